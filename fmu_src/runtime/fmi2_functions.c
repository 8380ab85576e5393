/* The FMU's linux64 binary as FMI 2.0 sees it: every FMI 2.0 Co-Simulation and Model Exchange
 * function, over the version-neutral core of the runtime (runtime_core.h: Python, the FMU's
 * resources, instances, messages, the calls of the slave) and pythonfmu's Python API (the
 * Fmi2Slave instance and its methods; for Model Exchange the slave's me_ methods,
 * fmu_src/fmi/model_exchange.py). pythonfmu's own binary is not used.
 *
 * Status:
 * - a Python exception gives fmi2Error and one log line "<function>: <type>: <message>";
 *   MemoryError and SystemExit give fmi2Fatal; do_step returning False gives fmi2Discard;
 * - the FMI 2.0 state machine (fmi2_states.h, the standard's tables) decides which calls an
 *   instance takes: any other is refused with fmi2Error and a message, and after fmi2Error
 *   the instance is in the error state (reads, FMU states, fmi2Reset and fmi2FreeInstance
 *   only), after fmi2Discard of a step in stepFailed; fmi2SetFMUstate takes it back to the
 *   state machine state and time its FMU state was taken in;
 * - fmi2DoStep's currentCommunicationPoint must be the FMU's time (the start time, or where
 *   the last step ended) within TIME_TOLERANCE: otherwise fmi2Error;
 * - after fmi2Fatal every call returns fmi2Fatal without entering Python (fmi2FreeInstance
 *   still releases the instance);
 * - refused without entering Python, with a message: Model Exchange of a slave without it, a
 *   GUID other than the FMU's, a NULL name, GUID or resource location, an unusable resource
 *   location.
 *
 * An FMU state owns its Python state; it carries the GUID of the FMU that made it, and the
 * state machine state and time it was taken in.
 *
 * build: python -m ziglang cc -target x86_64-linux-gnu.2.17 -shared -fPIC -O2
 *        -I<fmpy>/c-code fmi2_functions.c runtime_core.c fmi2_states.c -o <Model>.so
 *        (harness/fmu/build.py does this)
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
#include "fmi2_states.h"
#include "runtime_core.h"

#define STATE_HEADER "pythonfmu state of FMU "  /* + GUID + "\n": a serialised state's start */
/* after the state machine state: the time's bits, written and read */
#define TIME_BITS " at time 0x%016llx (IEEE 754 bits)"
#define READ_TIME_BITS " at time 0x%16llx (IEEE 754 bits)%n"
/* fmi2DoStep's currentCommunicationPoint may differ from the FMU's time by this much, relative
 * to the larger of that time and the step size */
#define TIME_TOLERANCE 1e-9
#define SLAVE_BASE "pythonfmu.Fmi2Slave"  /* the class the slave module's slave derives from */

#define INSTANCE_TAG 0x464d5532u  /* "FMU2" */
#define STATE_TAG 0x53544154u     /* "STAT" */

_Static_assert(fmi2OK == STATUS_OK && fmi2Warning == STATUS_WARNING &&
               fmi2Discard == STATUS_DISCARD && fmi2Error == STATUS_ERROR &&
               fmi2Fatal == STATUS_FATAL, "fmi2Status numbers the statuses as the core does");

typedef struct {
    unsigned tag;
    char *guid;        /* of the FMU that made it */
    Fmi2State taken_in;  /* the instance's state machine state and time when it was taken */
    double time;
    PyObject *state;   /* the slave's state object */
} State;

/* ---- messages ------------------------------------------------------------------------- */
static const char *const STATUS_CATEGORIES[] = {"logAll", "logStatusWarning",
                                               "logStatusDiscard", "logStatusError",
                                               "logStatusFatal", "logAll"};

/* A message to the host's fmi2CallbackLogger, in the category of its status if it has none. */
static void emit(const Sink *sink, int status, const char *category, const char *text) {
    ((fmi2CallbackLogger)sink->logger)(sink->environment, sink->name, (fmi2Status)status,
                                       category ? category : STATUS_CATEGORIES[status], text);
}

/* The sink of the host's callbacks, for an instance of this name. */
static Sink host_sink(const fmi2CallbackFunctions *functions, const char *name) {
    Sink sink = {functions->logger ? emit : NULL, (void (*)(void))functions->logger,
                 functions->componentEnvironment, (char *)name, 1, NULL, 0, 0};
    return sink;
}

/* ---- instances ------------------------------------------------------------------------ */
/* Make the instance's slave (create_slave); 0 after logging why, the Model Exchange of a
 * slave of Co-Simulation only included. */
static int make_slave(Instance *in) {
    const char *missing = NULL;
    int made = create_slave(in, "fmi2Instantiate", &missing);
    if (missing) {
        log_format(&in->sink, fmi2Error, "fmi2Instantiate: this FMU's slave implements FMI 2.0 "
                   "Co-Simulation only (it has no %s); fmuType fmi2ModelExchange refused",
                   missing);
        drain_log(in);
        release_slave(in);
    }
    return made;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    if (!functions) return NULL;  /* no logger to say why */
    Sink sink = host_sink(functions, instanceName ? instanceName : "");
    Message why = {{0}, 0};
    const char *guid = recorded_guid();
    if (!instanceName || !fmuGUID || !fmuResourceLocation) {
        log_format(&sink, fmi2Error, "fmi2Instantiate: %s is NULL", !instanceName ? "instanceName"
                   : !fmuGUID ? "fmuGUID" : "fmuResourceLocation");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation && fmuType != fmi2ModelExchange) {
        log_format(&sink, fmi2Error, "fmi2Instantiate: fmuType %d is neither "
                   "fmi2ModelExchange (%d) nor fmi2CoSimulation (%d)", (int)fmuType,
                   (int)fmi2ModelExchange, (int)fmi2CoSimulation);
        return NULL;
    }
    if (guid[0] && strcmp(fmuGUID, guid) != 0) {
        log_format(&sink, fmi2Error, "fmi2Instantiate: fmuGUID %s is not this FMU's GUID %s "
                   "(its modelDescription.xml): the binary belongs to another FMU", fmuGUID,
                   guid);
        return NULL;
    }
    char *folder = resource_folder(fmuResourceLocation, &why);
    char *module = folder ? slave_module(folder, fmuResourceLocation, &why) : NULL;
    Instance *in = NULL;
    if (module && load(&why)) in = calloc(1, sizeof *in);
    if (in) {
        in->tag = INSTANCE_TAG;
        in->sink = sink;
        in->sink.name = strdup(sink.name);
        in->sink.logging_on = loggingOn != fmi2False;
        in->guid = strdup(fmuGUID);
        in->resources = folder;
        in->module = module;
        in->slave_base = SLAVE_BASE;
        in->visible = visible != fmi2False;
        in->model_exchange = fmuType == fmi2ModelExchange;
        in->type = fmuType;
        in->state = FMI2_INSTANTIATED;
        folder = module = NULL;
    } else if (!why.length) {
        append(&why, "out of memory");
    }
    free(folder);
    free(module);
    if (!in || !in->sink.name || !in->guid) {
        log_format(&sink, fmi2Fatal, "fmi2Instantiate: %s", why.length ? why.text
                                                                      : "out of memory");
        if (in) free_instance(in);
        return NULL;
    }
    PyGILState_STATE gil = enter_python();
    int made = make_slave(in);
    if (made) drain_log(in);
    py.PyGILState_Release(gil);
    if (!made) {
        free_instance(in);
        return NULL;
    }
    return in;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *in = (Instance *)c;
    if (!in || in->tag != INSTANCE_TAG) return;
    free_instance(in);
}

/* ---- the state machine: every call checked against the FMI 2.0 tables (fmi2_states.h) -- */
/* Whether a call may go ahead: fmi2OK, or fmi2Error for a call the instance's state does not
 * allow (with a message, and the instance in the error state, as after any fmi2Error), or
 * fmi2Fatal for any call after fmi2Fatal (the standard allows none then). */
/* fmi2SetInteger, fmi2SetBoolean and fmi2SetString in Continuous-Time Mode, which the
 * standard does not allow: FMPy's CVode sets every input again in its root function, there
 * and past an input event it has not reached yet. They go to the slave, which takes a
 * discrete input's new value at the next event only (fmu_src/fmi/model_exchange.py). */
static int discrete_set_again(const Instance *in, Fmi2Call call) {
    return in->type == fmi2ModelExchange && in->state == FMI2_CONTINUOUS_TIME_MODE &&
           (call == FMI2_SET_INTEGER || call == FMI2_SET_BOOLEAN || call == FMI2_SET_STRING);
}

static fmi2Status check_call(Instance *in, Fmi2Call call) {
    if (!in || in->tag != INSTANCE_TAG) return fmi2Error;
    if (in->state == FMI2_FATAL) {
        log_format(&in->sink, fmi2Fatal, "%s refused: an earlier call on this instance "
                   "returned fmi2Fatal", fmi2_call_name(call));
        return fmi2Fatal;
    }
    if (!fmi2_allowed(in->type, in->state, call) && !discrete_set_again(in, call)) {
        char refusal[1024];
        fmi2_refusal(in->type, in->state, call, refusal, sizeof refusal);
        in->state = FMI2_ERROR;
        log_format(&in->sink, fmi2Error, "%s", refusal);
        return fmi2Error;
    }
    return fmi2OK;
}

/* Move the instance on after a call that returned status. */
static void finish_call(Instance *in, Fmi2Call call, fmi2Status status) {
    in->state = fmi2_next_state(in->type, in->state, call, status);
}

/* A call answered without Python: checked, the answer's status taken, the instance moved on. */
static fmi2Status answer(fmi2Component c, Fmi2Call call, fmi2Status status) {
    Instance *in = (Instance *)c;
    fmi2Status refused = check_call(in, call);
    if (refused != fmi2OK) return refused;
    finish_call(in, call, status);
    return status;
}

/* ---- calls ---------------------------------------------------------------------------- */
/* Enter Python for a call: the GIL taken (and the failure message of the call cleared). */
#define BEGIN(call) \
    Instance *in = (Instance *)c; \
    const Fmi2Call this_call = call; \
    const char *const function_name = fmi2_call_name(this_call); \
    (void)function_name; \
    { fmi2Status refused = check_call(in, this_call); \
      if (refused != fmi2OK) return refused; } \
    PyGILState_STATE gil = enter_python(); \
    fmi2Status status = fmi2OK

/* Leave Python: the instance moved on, then the slave's messages and the failure's passed on
 * (a call the host's logger makes back into the FMU sees the instance as this call left it),
 * the GIL given back. */
#define END() \
    finish_call(in, this_call, status); \
    leave_python(in, status, gil); \
    return status

/* Call a method; the result (new reference) or NULL with status set from the exception. */
#define CALL(method, ...) \
    py.PyObject_CallFunctionObjArgs(in->methods[method], __VA_ARGS__, NULL)

/* A call this FMU does not implement (its model description says so): fmi2Error. */
static fmi2Status no_call(fmi2Component c, Fmi2Call call) {
    fmi2Status refused = check_call((Instance *)c, call);
    if (refused != fmi2OK) return refused;
    log_format(&((Instance *)c)->sink, fmi2Error, "%s: not supported by this FMU",
               fmi2_call_name(call));
    finish_call((Instance *)c, call, fmi2Error);
    return fmi2Error;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *in = (Instance *)c;
    fmi2Status refused = check_call(in, FMI2_SET_DEBUG_LOGGING);
    if (refused != fmi2OK) return refused;
    if (nCategories && !categories) {
        log_format(&in->sink, fmi2Error, "fmi2SetDebugLogging: categories is NULL");
        finish_call(in, FMI2_SET_DEBUG_LOGGING, fmi2Error);
        return fmi2Error;
    }
    for (size_t i = 0; i < in->sink.category_count; i++) free(in->sink.categories[i]);
    free(in->sink.categories);
    in->sink.categories = NULL;
    in->sink.category_count = 0;
    in->sink.logging_on = loggingOn != fmi2False;
    if (nCategories) {
        in->sink.categories = calloc(nCategories, sizeof *in->sink.categories);
        if (!in->sink.categories) {
            finish_call(in, FMI2_SET_DEBUG_LOGGING, fmi2Error);
            return fmi2Error;
        }
        for (size_t i = 0; i < nCategories; i++)
            in->sink.categories[i] = strdup(categories[i] ? categories[i] : "");
        in->sink.category_count = nCategories;
    }
    return fmi2OK;
}

/* Call a method without arguments but self: a life-cycle call (an enum Method) or, with
 * model_exchange, a change of Model Exchange's mode (an enum ModelExchangeMethod); the state
 * machine moves the instance on. */
static fmi2Status without_arguments(fmi2Component c, Fmi2Call call, int model_exchange,
                                    int method) {
    BEGIN(call);
    PyObject *const *methods = model_exchange ? in->me_methods : in->methods;
    PyObject *result = py.PyObject_CallFunctionObjArgs(methods[method], NULL);
    if (!result) status = python_failure(in, function_name);
    release(&result);
    END();
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN(FMI2_SETUP_EXPERIMENT);
    PyObject *start = py.PyFloat_FromDouble(startTime);
    PyObject *stop = stopTimeDefined ? py.PyFloat_FromDouble(stopTime) : NULL;
    PyObject *tol = toleranceDefined ? py.PyFloat_FromDouble(tolerance) : NULL;
    PyObject *result = NULL;
    if (start && (stop || !stopTimeDefined) && (tol || !toleranceDefined))
        result = CALL(SETUP_EXPERIMENT, start, stop ? stop : py.None, tol ? tol : py.None);
    if (!result) status = python_failure(in, function_name);
    else in->last_successful_time = startTime;
    release(&result);
    release(&start);
    release(&stop);
    release(&tol);
    END();
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    return without_arguments(c, FMI2_ENTER_INITIALIZATION_MODE, 0, ENTER_INITIALIZATION_MODE);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return without_arguments(c, FMI2_EXIT_INITIALIZATION_MODE, 0, EXIT_INITIALIZATION_MODE);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return without_arguments(c, FMI2_TERMINATE, 0, TERMINATE);
}

fmi2Status fmi2Reset(fmi2Component c) {
    BEGIN(FMI2_RESET);
    release_slave(in);
    if (!make_slave(in)) status = fmi2Fatal;  /* no slave left: logged by make_slave */
    else in->last_successful_time = 0.0;
    END();
}

/* Whether a step starts at the FMU's time (the previous step's end, or the start time):
 * within TIME_TOLERANCE of it relative to the larger of that time and the step size, which
 * covers a host's rounding (t0 + k h against a running sum) and refuses a skipped or
 * repeated step. Otherwise 0 with the call's failure message set. */
static int at_fmu_time(Instance *in, double point, double step_size) {
    double tolerance = TIME_TOLERANCE * fmax(fabs(in->last_successful_time), step_size);
    if (fabs(point - in->last_successful_time) <= tolerance) return 1;  /* false for NaN */
    Message m = {{0}, 0};
    append(&m, "fmi2DoStep: currentCommunicationPoint = %.17g s is not the FMU's time "
           "%.17g s (where its last step ended, or the start time of fmi2SetupExperiment; "
           "allowed deviation %.3g s)", point, in->last_successful_time, tolerance);
    free(in->failure);
    in->failure = strdup(m.text);
    return 0;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    BEGIN(FMI2_DO_STEP);
    int on_time = at_fmu_time(in, currentCommunicationPoint, communicationStepSize);
    PyObject *now = on_time ? py.PyFloat_FromDouble(currentCommunicationPoint) : NULL;
    PyObject *step = now ? py.PyFloat_FromDouble(communicationStepSize) : NULL;
    PyObject *result = now && step ? CALL(DO_STEP, now, step) : NULL;
    int taken = result ? py.PyObject_IsTrue(result) : -1;
    if (!on_time) status = fmi2Error;  /* at_fmu_time said why */
    else if (taken < 0) status = python_failure(in, function_name);
    else if (taken) in->last_successful_time = currentCommunicationPoint + communicationStepSize;
    else status = fmi2Discard;  /* refused by the slave, which logged why */
    release(&result);
    release(&now);
    release(&step);
    END();
}

/* The getters: call the method with the value references, convert each item of its result. */
#define GETTER(Type, fmiType, call, method, convert) \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                             fmiType value[]) { \
        if (nvr == 0) return answer(c, call, fmi2OK); \
        BEGIN(call); \
        if (!vr || !value) { \
            status = wrong_result(in, function_name, "arguments: NULL arrays"); \
            END(); \
        } \
        if (!references_fit(in, nvr, function_name)) { \
            status = fmi2Error; \
            END(); \
        } \
        PyObject *refs = reference_list(vr, nvr); \
        PyObject *result = refs ? CALL(method, refs) : NULL; \
        release(&refs); \
        if (!result) status = python_failure(in, function_name); \
        else if (py.PySequence_Size(result) != (Py_ssize_t)nvr) { \
            py.PyErr_Clear(); \
            status = wrong_result(in, function_name, "result: a wrong number of values"); \
        } else { \
            for (size_t i = 0; i < nvr && status == fmi2OK; i++) { \
                PyObject *item = py.PySequence_GetItem(result, (Py_ssize_t)i); \
                if (item) { convert; } \
                if (status == fmi2OK && (!item || py.PyErr_Occurred())) \
                    status = python_failure(in, function_name); \
                release(&item); \
            } \
        } \
        release(&result); \
        END(); \
    }

GETTER(Real, fmi2Real, FMI2_GET_REAL, GET_REAL, value[i] = py.PyFloat_AsDouble(item))
GETTER(Boolean, fmi2Boolean, FMI2_GET_BOOLEAN, GET_BOOLEAN,
       { int truth = py.PyObject_IsTrue(item); value[i] = truth > 0 ? fmi2True : fmi2False; })
GETTER(Integer, fmi2Integer, FMI2_GET_INTEGER, GET_INTEGER, {
    long number = py.PyLong_AsLong(item);
    if (number < INT32_MIN || number > INT32_MAX) {
        status = wrong_result(in, function_name, "get_integer value is beyond 32 bits");
    } else value[i] = (fmi2Integer)number;
})

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    if (nvr == 0) return answer(c, FMI2_GET_STRING, fmi2OK);
    BEGIN(FMI2_GET_STRING);
    int fit = references_fit(in, nvr, function_name);
    PyObject *refs = vr && value && fit ? reference_list(vr, nvr) : NULL;
    PyObject *result = refs ? CALL(GET_STRING, refs) : NULL;
    release(&refs);
    release_strings(in);
    if (!fit) status = fmi2Error;
    else if (!vr || !value) status = wrong_result(in, function_name, "arguments: NULL arrays");
    else if (!result) status = python_failure(in, function_name);
    else if (py.PySequence_Size(result) != (Py_ssize_t)nvr) {
        py.PyErr_Clear();
        status = wrong_result(in, function_name, "get_string returned a wrong number of values");
    } else if (!(in->strings = calloc(nvr, sizeof *in->strings))) {
        status = wrong_result(in, function_name, "strings: out of memory");
    } else {
        in->string_count = nvr;
        for (size_t i = 0; i < nvr && status == fmi2OK; i++) {
            PyObject *item = py.PySequence_GetItem(result, (Py_ssize_t)i);
            in->strings[i] = item ? py.PyUnicode_AsUTF8String(item) : NULL;
            char *text;
            if (!in->strings[i] || py.PyBytes_AsStringAndSize(in->strings[i], &text, NULL) != 0)
                status = python_failure(in, function_name);
            else value[i] = text;
            release(&item);
        }
    }
    release(&result);
    END();
}

/* The setters: call the method with the value references and a list of converted values. */
#define SETTER(Type, fmiType, call, method, convert) \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                             const fmiType value[]) { \
        if (nvr == 0) return answer(c, call, fmi2OK); \
        BEGIN(call); \
        int fit = references_fit(in, nvr, function_name); \
        PyObject *refs = vr && value && fit ? reference_list(vr, nvr) : NULL; \
        PyObject *values = refs ? py.PyList_New((Py_ssize_t)nvr) : NULL; \
        for (size_t i = 0; values && i < nvr; i++) { \
            PyObject *item = convert; \
            if (!item || py.PyList_SetItem(values, (Py_ssize_t)i, item) != 0) release(&values); \
        } \
        PyObject *result = values ? CALL(method, refs, values) : NULL; \
        if (!fit) status = fmi2Error; \
        else if (!vr || !value) \
            status = wrong_result(in, function_name, "arguments: NULL arrays"); \
        else if (!result) status = python_failure(in, function_name); \
        release(&result); \
        release(&values); \
        release(&refs); \
        END(); \
    }

SETTER(Real, fmi2Real, FMI2_SET_REAL, SET_REAL, py.PyFloat_FromDouble(value[i]))
SETTER(Integer, fmi2Integer, FMI2_SET_INTEGER, SET_INTEGER, py.PyLong_FromLong(value[i]))
SETTER(Boolean, fmi2Boolean, FMI2_SET_BOOLEAN, SET_BOOLEAN,
       py.PyBool_FromLong(value[i] != fmi2False))
SETTER(String, fmi2String, FMI2_SET_STRING, SET_STRING,
       value[i] ? py.PyUnicode_FromString(value[i]) : py.PyUnicode_FromString(""))

/* ---- FMU states ----------------------------------------------------------------------- */
static State *state_of(Instance *in, fmi2FMUstate state, const char *function) {
    State *s = (State *)state;
    if (!s || s->tag != STATE_TAG) {
        wrong_result(in, function, "argument: not an FMU state");
        return NULL;
    }
    if (strcmp(s->guid, in->guid) != 0) {
        Message m = {{0}, 0};
        append(&m, "%s: the FMU state was made by another FMU (GUID %s, this one %s)", function,
               s->guid, in->guid);
        free(in->failure);
        in->failure = strdup(m.text);
        return NULL;
    }
    return s;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    BEGIN(FMI2_GET_FMU_STATE);
    State *s = NULL;
    PyObject *result = state ? py.PyObject_CallFunctionObjArgs(in->methods[GET_FMU_STATE],
                                                               NULL) : NULL;
    if (!state) status = wrong_result(in, function_name, "argument: state is NULL");
    else if (!result) status = python_failure(in, function_name);
    else if (*state && !(s = state_of(in, *state, function_name))) status = fmi2Error;
    else if (!s && !(s = calloc(1, sizeof *s))) status = fmi2Error;
    if (status == fmi2OK && !s->guid && !(s->guid = strdup(in->guid))) {
        if (!*state) free(s);
        status = wrong_result(in, function_name, "state: out of memory");
    }
    if (status == fmi2OK) {
        s->tag = STATE_TAG;
        s->taken_in = in->state;
        s->time = in->last_successful_time;
        release(&s->state);
        s->state = result;  /* owned by the state now */
        result = NULL;
        *state = s;
    }
    release(&result);
    END();
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    BEGIN(FMI2_SET_FMU_STATE);
    State *s = state_of(in, state, function_name);
    PyObject *result = s ? CALL(SET_FMU_STATE, s->state) : NULL;
    if (!s) status = fmi2Error;
    else if (!result) status = python_failure(in, function_name);
    else {  /* back where the state was taken: its state machine state and time */
        in->state = s->taken_in;
        in->last_successful_time = s->time;
    }
    release(&result);
    END();
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    if (!state || !*state) return answer(c, FMI2_FREE_FMU_STATE, fmi2OK);
    BEGIN(FMI2_FREE_FMU_STATE);
    State *s = (State *)*state;
    if (s->tag != STATE_TAG) status = wrong_result(in, function_name, "argument: not a state");
    else {
        release(&s->state);
        free(s->guid);
        s->tag = 0;
        free(s);
        *state = NULL;
    }
    END();
}

/* The serialised state: two lines of text, then the slave's bytes. The first line is
 * STATE_HEADER and the GUID, the second the state machine state and the time [s] the state
 * was taken in, "<state> at time 0x<the double's 64 bits in hex> (IEEE 754 bits)": exact, and
 * read the same whatever the host's locale. A new reference to the slave's bytes (and in
 * *taken the state they belong to), or NULL with status set. */
static PyObject *state_bytes(Instance *in, fmi2FMUstate state, const char *function,
                             fmi2Status *status, State **taken) {
    State *s = *taken = state_of(in, state, function);
    PyObject *bytes = s ? CALL(STATE_TO_BYTES, s->state) : NULL;
    char *data;
    if (!s) *status = fmi2Error;
    else if (!bytes || py.PyBytes_AsStringAndSize(bytes, &data, NULL) != 0) {
        *status = python_failure(in, function);
        release(&bytes);
    }
    return bytes;
}

/* The two lines before the slave's bytes into text (at most size bytes with the NUL, which
 * is not part of them); their length. */
static size_t state_lines(const Instance *in, const State *s, char *text, size_t size) {
    uint64_t bits;
    memcpy(&bits, &s->time, sizeof bits);
    int n = snprintf(text, size, STATE_HEADER "%s\n%s" TIME_BITS "\n", in->guid,
                     fmi2_state_name(s->taken_in), (unsigned long long)bits);
    return n > 0 ? (size_t)n : 0;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    BEGIN(FMI2_SERIALIZED_FMU_STATE_SIZE);
    State *s = NULL;
    PyObject *bytes = size ? state_bytes(in, state, function_name, &status, &s) : NULL;
    char *data;
    Py_ssize_t length;
    if (!size) status = wrong_result(in, function_name, "argument: size is NULL");
    else if (bytes && py.PyBytes_AsStringAndSize(bytes, &data, &length) == 0)
        *size = state_lines(in, s, NULL, 0) + (size_t)length;
    release(&bytes);
    END();
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serialized[],
                                 size_t size) {
    BEGIN(FMI2_SERIALIZE_FMU_STATE);
    State *s = NULL;
    PyObject *bytes = serialized ? state_bytes(in, state, function_name, &status, &s) : NULL;
    char *data, *lines = NULL;
    Py_ssize_t length;
    if (!serialized) status = wrong_result(in, function_name, "argument: the array is NULL");
    else if (bytes && py.PyBytes_AsStringAndSize(bytes, &data, &length) == 0) {
        size_t header = state_lines(in, s, NULL, 0);
        if (size < header + (size_t)length) {
            status = wrong_result(in, function_name,
                                  "state needs more bytes than given (fmi2SerializedFMUstateSize)");
        } else if (!(lines = malloc(header + 1))) {
            status = wrong_result(in, function_name, "state: out of memory");
        } else {
            state_lines(in, s, lines, header + 1);
            memcpy(serialized, lines, header);
            memcpy(serialized + header, data, (size_t)length);
        }
    }
    free(lines);
    release(&bytes);
    END();
}

/* The length of the two lines that begin a serialised state of this instance's FMU, with
 * the state machine state and time they name; 0 if they are not such lines (why in m). */
static size_t parse_state_lines(const Instance *in, const char *bytes, size_t size,
                                Fmi2State *taken_in, double *time, Message *m,
                                const char *function) {
    size_t prefix = strlen(STATE_HEADER), guid = strlen(in->guid);
    const char *end = size > prefix ? memchr(bytes + prefix, '\n', size - prefix) : NULL;
    if (!end || memcmp(bytes, STATE_HEADER, prefix) != 0) {
        append(m, "%s: the bytes are not a serialised FMU state of this runtime", function);
        return 0;
    }
    if ((size_t)(end - bytes) != prefix + guid || memcmp(bytes + prefix, in->guid, guid) != 0) {
        append(m, "%s: the bytes are a state of another FMU (GUID %.*s, this one %s)",
               function, (int)(end - bytes - (ptrdiff_t)prefix), bytes + prefix, in->guid);
        return 0;
    }
    const char *record = end + 1;
    const char *record_end = memchr(record, '\n', size - (size_t)(record - bytes));
    char line[128];
    size_t length = record_end ? (size_t)(record_end - record) : 0;
    if (record_end && length < sizeof line) {
        memcpy(line, record, length);
        line[length] = '\0';
        for (int state = 0; state < FMI2_STATE_COUNT; state++) {
            const char *name = fmi2_state_name((Fmi2State)state);
            size_t n = strlen(name);
            unsigned long long bits;
            int read = 0;
            if (strncmp(line, name, n) != 0 ||
                sscanf(line + n, READ_TIME_BITS, &bits, &read) != 1 ||
                line[n + (size_t)read] != '\0') continue;
            uint64_t exact = bits;
            memcpy(time, &exact, sizeof *time);
            *taken_in = (Fmi2State)state;
            if (isfinite(*time) && fmi2_allowed(in->type, *taken_in, FMI2_GET_FMU_STATE))
                return (size_t)(record_end + 1 - bytes);
        }
    }
    append(m, "%s: the bytes are not a serialised FMU state of this runtime (no state "
           "machine state and time on their second line)", function);
    return 0;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serialized[], size_t size,
                                   fmi2FMUstate *state) {
    BEGIN(FMI2_DESERIALIZE_FMU_STATE);
    State *s = NULL;
    Fmi2State taken_in = FMI2_START_END;
    double time = 0.0;
    Message m = {{0}, 0};
    size_t header = serialized && state ? parse_state_lines(in, serialized, size, &taken_in,
                                                            &time, &m, function_name) : 0;
    if (!serialized || !state) {
        status = wrong_result(in, function_name, "arguments: NULL");
    } else if (!header) {
        free(in->failure);
        in->failure = strdup(m.text);
        status = fmi2Error;
    } else {
        PyObject *bytes = py.PyBytes_FromStringAndSize(serialized + header,
                                                       (Py_ssize_t)(size - header));
        PyObject *result = bytes ? CALL(STATE_FROM_BYTES, bytes) : NULL;
        release(&bytes);
        if (!result) status = python_failure(in, function_name);
        else if (!(s = calloc(1, sizeof *s)) || !(s->guid = strdup(in->guid))) {
            free(s);
            release(&result);
            status = wrong_result(in, function_name, "state: out of memory");
        } else {
            s->tag = STATE_TAG;
            s->taken_in = taken_in;
            s->time = time;
            s->state = result;
            *state = s;
        }
    }
    END();
}

/* ---- what this FMU does not do, and the status inquiries ------------------------------ */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[],
                                        size_t nUnknown, const fmi2ValueReference known[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)unknown, (void)nUnknown, (void)known, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return no_call(c, FMI2_GET_DIRECTIONAL_DERIVATIVE);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return no_call(c, FMI2_SET_REAL_INPUT_DERIVATIVES);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return no_call(c, FMI2_GET_REAL_OUTPUT_DERIVATIVES);
}

fmi2Status fmi2CancelStep(fmi2Component c) { return no_call(c, FMI2_CANCEL_STEP); }

/* Steps are synchronous: no step is ever pending. An inquiry not answered is fmi2Discard
 * (FMI 2.0, section 4.2.3), which leaves the state as it was. */
static fmi2Status no_status(fmi2Component c, Fmi2Call call, fmi2StatusKind kind) {
    fmi2Status refused = check_call((Instance *)c, call);
    if (refused != fmi2OK) return refused;
    log_format(&((Instance *)c)->sink, fmi2Discard, "%s: status kind %d is not provided "
               "(steps are synchronous)", fmi2_call_name(call), (int)kind);
    finish_call((Instance *)c, call, fmi2Discard);
    return fmi2Discard;
}

/* The inquiries this FMU does not answer: every kind of a type. */
#define NO_STATUS(Type, fmiType, call) \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2StatusKind s, fmiType *value) { \
        (void)value; \
        return no_status(c, call, s); \
    }

NO_STATUS(Status, fmi2Status, FMI2_GET_STATUS)
NO_STATUS(IntegerStatus, fmi2Integer, FMI2_GET_INTEGER_STATUS)
NO_STATUS(StringStatus, fmi2String, FMI2_GET_STRING_STATUS)

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (s != fmi2LastSuccessfulTime || !value) return no_status(c, FMI2_GET_REAL_STATUS, s);
    fmi2Status status = answer(c, FMI2_GET_REAL_STATUS, fmi2OK);
    if (status == fmi2OK) *value = ((Instance *)c)->last_successful_time;
    return status;
}

/* fmi2Terminated is false: a refused step (fmi2Discard) leaves the slave as it was, ready for
 * a shorter step or another input. */
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (s != fmi2Terminated || !value) return no_status(c, FMI2_GET_BOOLEAN_STATUS, s);
    fmi2Status status = answer(c, FMI2_GET_BOOLEAN_STATUS, fmi2OK);
    if (status == fmi2OK) *value = fmi2False;
    return status;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

/* ==== Model Exchange ========================================================================
 * The FMI 2.0 Model Exchange calls over the slave's me_ methods (fmu_src/fmi/model_exchange.py),
 * for an instance made with fmuType fmi2ModelExchange; the state machine (fmi2_states.c)
 * admits them, and refuses them on a Co-Simulation instance (and fmi2DoStep on a Model
 * Exchange one). The runtime never reads or writes past the model's nx or ni
 * (me_state_count, me_indicator_count): a host's other count is refused before its array is
 * touched. */

/* Call a Model Exchange method with the arguments given (none: CALL_ME(method, NULL)). */
#define CALL_ME(method, ...) \
    py.PyObject_CallFunctionObjArgs(in->me_methods[method], __VA_ARGS__, NULL)

/* One of the inquiries that fill an array of the model's nx (states) or ni numbers. */
static fmi2Status inquire(fmi2Component c, Fmi2Call call, enum ModelExchangeMethod method,
                          int states, fmi2Real values[], size_t n) {
    BEGIN(call);
    size_t count = states ? in->state_count : in->indicator_count;
    if (n != count) status = wrong_count(in, function_name, states, n, count);
    else if (n && !values) status = wrong_result(in, function_name, "arguments: a NULL array");
    else {
        PyObject *size = py.PyLong_FromSize_t(n);
        PyObject *result = size ? CALL_ME(method, size) : NULL;
        status = take_numbers(in, function_name, result, values, n);
        release(&result);
        release(&size);
    }
    END();
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    return inquire(c, FMI2_GET_CONTINUOUS_STATES, ME_GET_CONTINUOUS_STATES, 1, x, nx);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    return inquire(c, FMI2_GET_DERIVATIVES, ME_GET_DERIVATIVES, 1, derivatives, nx);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    return inquire(c, FMI2_GET_EVENT_INDICATORS, ME_GET_EVENT_INDICATORS, 0, eventIndicators,
                   ni);
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[],
                                             size_t nx) {
    return inquire(c, FMI2_GET_NOMINALS_OF_CONTINUOUS_STATES, ME_GET_NOMINALS, 1, x_nominal,
                   nx);
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    BEGIN(FMI2_SET_TIME);
    PyObject *value = py.PyFloat_FromDouble(time);
    PyObject *result = value ? CALL_ME(ME_SET_TIME, value) : NULL;
    if (!result) status = python_failure(in, function_name);
    release(&result);
    release(&value);
    END();
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    BEGIN(FMI2_SET_CONTINUOUS_STATES);
    PyObject *values = NULL;
    if (nx != in->state_count)
        status = wrong_count(in, function_name, 1, nx, in->state_count);
    else if (nx && !x) status = wrong_result(in, function_name, "arguments: a NULL array");
    else if (!(values = py.PyList_New((Py_ssize_t)nx))) status = python_failure(in, function_name);
    for (size_t i = 0; values && status == fmi2OK && i < nx; i++) {
        PyObject *item = py.PyFloat_FromDouble(x[i]);
        if (!item || py.PyList_SetItem(values, (Py_ssize_t)i, item) != 0)
            status = python_failure(in, function_name);
    }
    if (status == fmi2OK) {
        PyObject *result = CALL_ME(ME_SET_CONTINUOUS_STATES, values);
        if (!result) status = python_failure(in, function_name);
        release(&result);
    }
    release(&values);
    END();
}

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    return without_arguments(c, FMI2_ENTER_EVENT_MODE, 1, ME_ENTER_EVENT_MODE);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    return without_arguments(c, FMI2_ENTER_CONTINUOUS_TIME_MODE, 1,
                             ME_ENTER_CONTINUOUS_TIME_MODE);
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    BEGIN(FMI2_NEW_DISCRETE_STATES);
    PyObject *result = eventInfo ? CALL_ME(ME_NEW_DISCRETE_STATES, NULL) : NULL;
    int flags[5] = {0};
    if (!eventInfo) status = wrong_result(in, function_name, "argument: eventInfo is NULL");
    else if (!result) status = python_failure(in, function_name);
    else if (py.PySequence_Size(result) != 6) {
        py.PyErr_Clear();
        status = wrong_result(in, function_name, "result: not the six fields of fmi2EventInfo");
    }
    for (int i = 0; status == fmi2OK && i < 5; i++)
        if ((flags[i] = truth(result, i)) < 0) status = python_failure(in, function_name);
    if (status == fmi2OK) {
        PyObject *next = py.PySequence_GetItem(result, 5);
        double next_time = next ? py.PyFloat_AsDouble(next) : 0.0;
        release(&next);
        if (py.PyErr_Occurred()) status = python_failure(in, function_name);
        else {
            eventInfo->newDiscreteStatesNeeded = flags[0] ? fmi2True : fmi2False;
            eventInfo->terminateSimulation = flags[1] ? fmi2True : fmi2False;
            eventInfo->nominalsOfContinuousStatesChanged = flags[2] ? fmi2True : fmi2False;
            eventInfo->valuesOfContinuousStatesChanged = flags[3] ? fmi2True : fmi2False;
            eventInfo->nextEventTimeDefined = flags[4] ? fmi2True : fmi2False;
            eventInfo->nextEventTime = next_time;
        }
    }
    release(&result);
    END();
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    BEGIN(FMI2_COMPLETED_INTEGRATOR_STEP);
    PyObject *result = enterEventMode && terminateSimulation
                           ? CALL_ME(ME_COMPLETED_INTEGRATOR_STEP, NULL) : NULL;
    int enter = 0, terminate = 0;
    if (!enterEventMode || !terminateSimulation)
        status = wrong_result(in, function_name, "arguments: a NULL pointer");
    else if (!result) status = python_failure(in, function_name);
    else if (py.PySequence_Size(result) != 2) {
        py.PyErr_Clear();
        status = wrong_result(in, function_name, "result: not (enterEventMode, terminate)");
    } else if ((enter = truth(result, 0)) < 0 || (terminate = truth(result, 1)) < 0) {
        status = python_failure(in, function_name);
    } else {
        *enterEventMode = enter ? fmi2True : fmi2False;
        *terminateSimulation = terminate ? fmi2True : fmi2False;
    }
    release(&result);
    END();
}
