/* The FMI 2.0 state machine of the FMUs' runtime, call by call (tests/test_fmi2_states.py).
 *
 * Built with fmu_src/runtime/fmi2_states.c (the runtime's own table), it prints:
 *   fmi2_state_table table
 *       the table the runtime holds: one line "<type>\t<state>\t<call>\t<0|1>" for every
 *       interface type (cs, me), state and call;
 *   fmi2_state_table run DIR MODEL GUID U MODE TEXT FLAG
 *       what an unzipped probe FMU (tests/data/runtime_slaves/RuntimeProbe.py, its Real input
 *       U, Integer input MODE, String output TEXT and Boolean output FLAG given as value
 *       references) does with every call that takes an instance, made in every Co-Simulation
 *       state a synchronous slave can be in: one line "<state>\t<call>\t<status>\t<refused>",
 *       refused 1 when the runtime logged that the state does not allow the call. Each pair
 *       gets a fresh instance, driven into the state by calls the standard allows there.
 * exit status: 0 done, 1 a state not reached, 2 usage, 3 the binary or a function not loaded
 * build: cc -I<fmpy>/c-code -I<fmu_src/runtime> fmi2_state_table.c fmi2_states.c -ldl
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
#include "fmi2_states.h"

#define STEP 1e-3
#define PATH_SIZE 4096
/* the probe's `mode` values (RuntimeProbe.py) */
enum { NORMAL = 0, RAISE_VALUE_ERROR = 1, RAISE_MEMORY_ERROR = 2, DISCARD = 3 };

static int refused;  /* the runtime logged a state refusal since it was cleared */

static void log_message(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                        fmi2String category, fmi2String message, ...) {
    char text[8192];
    va_list args;
    (void)env, (void)instance, (void)category, (void)status;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    if (strstr(text, " is not allowed in ")) refused = 1;
}

static const fmi2CallbackFunctions callbacks = {log_message, calloc, free, NULL, NULL};

static void usage(const char *program) {
    fprintf(stderr, "usage: %s table | run DIR MODEL GUID U MODE TEXT FLAG\n", program);
    exit(2);
}

static int print_table(void) {
    const fmi2Type types[] = {fmi2CoSimulation, fmi2ModelExchange};
    for (int t = 0; t < 2; t++)
        for (int s = 0; s < FMI2_STATE_COUNT; s++)
            for (int c = 0; c < FMI2_CALL_COUNT; c++)
                printf("%s\t%s\t%s\t%d\n", types[t] == fmi2CoSimulation ? "cs" : "me",
                       fmi2_state_name((Fmi2State)s), fmi2_call_name((Fmi2Call)c),
                       fmi2_allowed(types[t], (Fmi2State)s, (Fmi2Call)c));
    return 0;
}

/* ---- run: the probe FMU through every call in every state ---------------------------- */
#define API(X) \
    X(fmi2Instantiate) X(fmi2FreeInstance) X(fmi2SetDebugLogging) X(fmi2SetupExperiment) \
    X(fmi2EnterInitializationMode) X(fmi2ExitInitializationMode) X(fmi2Terminate) \
    X(fmi2Reset) X(fmi2GetReal) X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString) \
    X(fmi2SetReal) X(fmi2SetInteger) X(fmi2SetBoolean) X(fmi2SetString) \
    X(fmi2GetFMUstate) X(fmi2SetFMUstate) X(fmi2FreeFMUstate) \
    X(fmi2SerializedFMUstateSize) X(fmi2SerializeFMUstate) X(fmi2DeSerializeFMUstate) \
    X(fmi2GetDirectionalDerivative) X(fmi2SetRealInputDerivatives) \
    X(fmi2GetRealOutputDerivatives) X(fmi2DoStep) X(fmi2CancelStep) X(fmi2GetStatus) \
    X(fmi2GetRealStatus) X(fmi2GetIntegerStatus) X(fmi2GetBooleanStatus) \
    X(fmi2GetStringStatus)

#define DECLARE(name) name##TYPE *name;
static struct { API(DECLARE) } fmu;  /* the FMU's functions */
#undef DECLARE

static fmi2ValueReference u_ref, mode_ref, text_ref, flag_ref;
static const char *model_guid;
static char resources[PATH_SIZE];

/* A fresh instance in the state, or NULL if the calls that lead there did not. */
static fmi2Component instance_in(Fmi2State state) {
    fmi2Component c = fmu.fmi2Instantiate("table", fmi2CoSimulation, model_guid, resources,
                                      &callbacks, fmi2False, fmi2True);
    if (!c || state == FMI2_INSTANTIATED) return c;
    int ok = fmu.fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) == fmi2OK &&
             fmu.fmi2EnterInitializationMode(c) == fmi2OK;
    if (ok && state == FMI2_INITIALIZATION_MODE) return c;
    ok = ok && fmu.fmi2ExitInitializationMode(c) == fmi2OK &&
         fmu.fmi2DoStep(c, 0.0, STEP, fmi2True) == fmi2OK;
    fmi2Integer mode = state == FMI2_STEP_FAILED ? DISCARD
                       : state == FMI2_ERROR ? RAISE_VALUE_ERROR
                       : state == FMI2_FATAL ? RAISE_MEMORY_ERROR : NORMAL;
    fmi2Status expected = state == FMI2_STEP_FAILED ? fmi2Discard
                          : state == FMI2_ERROR ? fmi2Error
                          : state == FMI2_FATAL ? fmi2Fatal : fmi2OK;
    ok = ok && fmu.fmi2SetInteger(c, &mode_ref, 1, &mode) == fmi2OK;
    if (ok && state != FMI2_STEP_COMPLETE && state != FMI2_TERMINATED)
        ok = fmu.fmi2DoStep(c, STEP, STEP, fmi2True) == expected;
    if (ok && state == FMI2_TERMINATED) ok = fmu.fmi2Terminate(c) == fmi2OK;
    if (ok) return c;
    fmu.fmi2FreeInstance(c);
    return NULL;
}

/* Make the call with arguments a host would pass; its status. state: an FMU state of the
 * FMU (freed by fmi2FreeFMUstate); bytes: a serialised one. */
static fmi2Status make(Fmi2Call call, fmi2Component c, fmi2FMUstate *state,
                       const fmi2Byte *bytes, size_t size) {
    fmi2Real real = 1.0;
    fmi2Integer integer = NORMAL;
    fmi2Boolean boolean = fmi2True;
    fmi2String string = "set";
    const fmi2String category = "logAll";
    fmi2FMUstate copy = NULL;
    fmi2Status status;
    fmi2Byte buffer[65536];
    size_t needed = 0;
    fmi2Integer order = 1;
    switch (call) {
    case FMI2_SET_DEBUG_LOGGING: return fmu.fmi2SetDebugLogging(c, fmi2True, 1, &category);
    case FMI2_SETUP_EXPERIMENT:
        return fmu.fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    case FMI2_ENTER_INITIALIZATION_MODE: return fmu.fmi2EnterInitializationMode(c);
    case FMI2_EXIT_INITIALIZATION_MODE: return fmu.fmi2ExitInitializationMode(c);
    case FMI2_TERMINATE: return fmu.fmi2Terminate(c);
    case FMI2_RESET: return fmu.fmi2Reset(c);
    case FMI2_GET_REAL: return fmu.fmi2GetReal(c, &u_ref, 1, &real);
    case FMI2_GET_INTEGER: return fmu.fmi2GetInteger(c, &mode_ref, 1, &integer);
    case FMI2_GET_BOOLEAN: return fmu.fmi2GetBoolean(c, &flag_ref, 1, &boolean);
    case FMI2_GET_STRING: return fmu.fmi2GetString(c, &text_ref, 1, &string);
    case FMI2_SET_REAL: return fmu.fmi2SetReal(c, &u_ref, 1, &real);
    case FMI2_SET_INTEGER: return fmu.fmi2SetInteger(c, &mode_ref, 1, &integer);
    case FMI2_SET_BOOLEAN: return fmu.fmi2SetBoolean(c, &flag_ref, 1, &boolean);
    case FMI2_SET_STRING: return fmu.fmi2SetString(c, &text_ref, 1, &string);
    case FMI2_GET_FMU_STATE:
        status = fmu.fmi2GetFMUstate(c, &copy);
        if (copy) fmu.fmi2FreeFMUstate(c, &copy);
        return status;
    case FMI2_SET_FMU_STATE: return fmu.fmi2SetFMUstate(c, *state);
    case FMI2_FREE_FMU_STATE: return fmu.fmi2FreeFMUstate(c, state);
    case FMI2_SERIALIZED_FMU_STATE_SIZE: return fmu.fmi2SerializedFMUstateSize(c, *state, &needed);
    case FMI2_SERIALIZE_FMU_STATE:
        return fmu.fmi2SerializeFMUstate(c, *state, buffer, sizeof buffer);
    case FMI2_DESERIALIZE_FMU_STATE:
        status = fmu.fmi2DeSerializeFMUstate(c, bytes, size, &copy);
        if (copy) fmu.fmi2FreeFMUstate(c, &copy);
        return status;
    case FMI2_GET_DIRECTIONAL_DERIVATIVE:
        return fmu.fmi2GetDirectionalDerivative(c, &u_ref, 1, &u_ref, 1, &real, &real);
    case FMI2_SET_REAL_INPUT_DERIVATIVES:
        return fmu.fmi2SetRealInputDerivatives(c, &u_ref, 1, &order, &real);
    case FMI2_GET_REAL_OUTPUT_DERIVATIVES:
        return fmu.fmi2GetRealOutputDerivatives(c, &u_ref, 1, &order, &real);
    case FMI2_DO_STEP: return fmu.fmi2DoStep(c, STEP, STEP, fmi2True);
    case FMI2_CANCEL_STEP: return fmu.fmi2CancelStep(c);
    case FMI2_GET_STATUS: {
        fmi2Status value;
        return fmu.fmi2GetStatus(c, fmi2DoStepStatus, &value);
    }
    case FMI2_GET_REAL_STATUS: return fmu.fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &real);
    case FMI2_GET_INTEGER_STATUS: return fmu.fmi2GetIntegerStatus(c, fmi2DoStepStatus, &integer);
    case FMI2_GET_BOOLEAN_STATUS: return fmu.fmi2GetBooleanStatus(c, fmi2Terminated, &boolean);
    case FMI2_GET_STRING_STATUS: return fmu.fmi2GetStringStatus(c, fmi2PendingStatus, &string);
    default: return fmi2Fatal;  /* not called: Model Exchange's, or without an instance */
    }
}

static int run(int argc, char **argv) {
    if (argc != 9) usage(argv[0]);
    char path[PATH_SIZE];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", argv[2], argv[3]);
    snprintf(resources, sizeof resources, "file://%s/resources", argv[2]);
    model_guid = argv[4];
    u_ref = (fmi2ValueReference)atoi(argv[5]);
    mode_ref = (fmi2ValueReference)atoi(argv[6]);
    text_ref = (fmi2ValueReference)atoi(argv[7]);
    flag_ref = (fmi2ValueReference)atoi(argv[8]);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        return 3;
    }
#define LOAD(name) \
    if (!(fmu.name = (name##TYPE *)dlsym(lib, #name))) { \
        fprintf(stderr, "missing %s\n", #name); \
        return 3; \
    }
    API(LOAD)
#undef LOAD
    /* an FMU state of an initialised instance, and its bytes */
    fmi2Component source = instance_in(FMI2_STEP_COMPLETE);
    fmi2FMUstate taken = NULL;
    static fmi2Byte bytes[65536];
    size_t size = 0;
    if (!source || fmu.fmi2GetFMUstate(source, &taken) != fmi2OK ||
        fmu.fmi2SerializedFMUstateSize(source, taken, &size) != fmi2OK || size > sizeof bytes ||
        fmu.fmi2SerializeFMUstate(source, taken, bytes, size) != fmi2OK) {
        fprintf(stderr, "no FMU state to pass\n");
        return 1;
    }
    const Fmi2State states[] = {FMI2_INSTANTIATED, FMI2_INITIALIZATION_MODE,
                                FMI2_STEP_COMPLETE, FMI2_STEP_FAILED, FMI2_TERMINATED,
                                FMI2_ERROR, FMI2_FATAL};
    for (size_t s = 0; s < sizeof states / sizeof *states; s++) {
        for (int call = 0; call < FMI2_CALL_COUNT; call++) {
            if (call == FMI2_GET_TYPES_PLATFORM || call == FMI2_GET_VERSION ||
                call == FMI2_INSTANTIATE || call == FMI2_FREE_INSTANCE ||
                (call >= FMI2_ENTER_EVENT_MODE && call < FMI2_SET_REAL_INPUT_DERIVATIVES))
                continue;  /* no instance to call them on, no status, or Model Exchange's */
            fmi2Component c = instance_in(states[s]);
            if (!c) {
                fprintf(stderr, "the probe did not reach %s\n", fmi2_state_name(states[s]));
                return 1;
            }
            fmi2FMUstate state = NULL;
            /* the state of another instance of this FMU: deserialised into this one */
            if (states[s] != FMI2_FATAL &&
                fmu.fmi2DeSerializeFMUstate(source, bytes, size, &state) != fmi2OK) state = NULL;
            refused = 0;
            fmi2Status status = make((Fmi2Call)call, c, &state, bytes, size);
            printf("%s\t%s\t%d\t%d\n", fmi2_state_name(states[s]),
                   fmi2_call_name((Fmi2Call)call), (int)status, refused);
            if (state) fmu.fmi2FreeFMUstate(source, &state);
            fmu.fmi2FreeInstance(c);
        }
    }
    fmu.fmi2FreeFMUstate(source, &taken);
    fmu.fmi2FreeInstance(source);
    fflush(stdout);
    return 0;
}

int main(int argc, char **argv) {
    if (argc >= 2 && strcmp(argv[1], "table") == 0 && argc == 2) return print_table();
    if (argc >= 2 && strcmp(argv[1], "run") == 0) return run(argc, argv);
    usage(argv[0]);
    return 2;
}
