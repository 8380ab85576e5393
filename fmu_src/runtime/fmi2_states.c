/* The FMI 2.0 state machine's tables (fmi2_states.h): for every call, the states it is allowed
 * in, for Co-Simulation (FMI 2.0.x, section 4.2.4) and for Model Exchange (section 3.2.3),
 * copied cell by cell from the standard; tests/test_fmi2_states.py checks every pair. */
#include <stdio.h>
#include <string.h>
#include "fmi2_states.h"

#define IN(state) (1u << FMI2_##state)
/* the Co-Simulation states of slaveInitialized that the standard's rows mostly share */
#define DONE_OR_FAILED (IN(STEP_COMPLETE) | IN(STEP_FAILED) | IN(STEP_CANCELED))

typedef struct {
    const char *name;
    unsigned co_simulation, model_exchange;  /* the states the call is allowed in */
} Row;

/* Numbered cells of the standard count as allowed (see the header). */
static const Row TABLE[FMI2_CALL_COUNT] = {
    [FMI2_GET_TYPES_PLATFORM] = {"fmi2GetTypesPlatform",
        IN(START_END) | IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED |
            IN(STEP_IN_PROGRESS) | IN(TERMINATED) | IN(ERROR),
        IN(START_END) | IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
    [FMI2_GET_VERSION] = {"fmi2GetVersion",
        IN(START_END) | IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED |
            IN(STEP_IN_PROGRESS) | IN(TERMINATED) | IN(ERROR),
        IN(START_END) | IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
    [FMI2_SET_DEBUG_LOGGING] = {"fmi2SetDebugLogging",
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED | IN(STEP_IN_PROGRESS) |
            IN(TERMINATED) | IN(ERROR),
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
    [FMI2_INSTANTIATE] = {"fmi2Instantiate", IN(START_END), IN(START_END)},
    [FMI2_FREE_INSTANCE] = {"fmi2FreeInstance",
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED | IN(TERMINATED) |
            IN(ERROR),
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
    [FMI2_SETUP_EXPERIMENT] = {"fmi2SetupExperiment", IN(INSTANTIATED), IN(INSTANTIATED)},
    [FMI2_ENTER_INITIALIZATION_MODE] = {"fmi2EnterInitializationMode", IN(INSTANTIATED),
        IN(INSTANTIATED)},
    [FMI2_EXIT_INITIALIZATION_MODE] = {"fmi2ExitInitializationMode", IN(INITIALIZATION_MODE),
        IN(INITIALIZATION_MODE)},
    [FMI2_TERMINATE] = {"fmi2Terminate", IN(STEP_COMPLETE) | IN(STEP_FAILED),
        IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE)},
    [FMI2_RESET] = {"fmi2Reset",
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED | IN(TERMINATED) |
            IN(ERROR),
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
#define GETTER(CALL, name) \
    [CALL] = {name, IN(INITIALIZATION_MODE) | DONE_OR_FAILED | IN(TERMINATED) | IN(ERROR), \
              IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE) | \
                  IN(TERMINATED) | IN(ERROR)}
    GETTER(FMI2_GET_REAL, "fmi2GetReal"),
    GETTER(FMI2_GET_INTEGER, "fmi2GetInteger"),
    GETTER(FMI2_GET_BOOLEAN, "fmi2GetBoolean"),
    GETTER(FMI2_GET_STRING, "fmi2GetString"),
#undef GETTER
    [FMI2_SET_REAL] = {"fmi2SetReal",
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(STEP_COMPLETE),
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE)},
#define SETTER(CALL, name) \
    [CALL] = {name, IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(STEP_COMPLETE), \
              IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE)}
    SETTER(FMI2_SET_INTEGER, "fmi2SetInteger"),
    SETTER(FMI2_SET_BOOLEAN, "fmi2SetBoolean"),
    SETTER(FMI2_SET_STRING, "fmi2SetString"),
#undef SETTER
    [FMI2_GET_FMU_STATE] = {"fmi2GetFMUstate",
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED | IN(TERMINATED) |
            IN(ERROR),
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
#define STATE_CALL(CALL, name) \
    [CALL] = {name, IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | DONE_OR_FAILED | \
                        IN(TERMINATED) | IN(ERROR), \
              IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | \
                  IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)}
    STATE_CALL(FMI2_SET_FMU_STATE, "fmi2SetFMUstate"),
    STATE_CALL(FMI2_FREE_FMU_STATE, "fmi2FreeFMUstate"),
    STATE_CALL(FMI2_SERIALIZED_FMU_STATE_SIZE, "fmi2SerializedFMUstateSize"),
    STATE_CALL(FMI2_SERIALIZE_FMU_STATE, "fmi2SerializeFMUstate"),
    STATE_CALL(FMI2_DESERIALIZE_FMU_STATE, "fmi2DeSerializeFMUstate"),
#undef STATE_CALL
    [FMI2_GET_DIRECTIONAL_DERIVATIVE] = {"fmi2GetDirectionalDerivative",
        IN(INITIALIZATION_MODE) | DONE_OR_FAILED | IN(TERMINATED) | IN(ERROR),
        IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE) |
            IN(TERMINATED) | IN(ERROR)},
    /* Model Exchange only */
    [FMI2_ENTER_EVENT_MODE] = {"fmi2EnterEventMode", 0,
        IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE)},
    [FMI2_NEW_DISCRETE_STATES] = {"fmi2NewDiscreteStates", 0, IN(EVENT_MODE)},
    [FMI2_ENTER_CONTINUOUS_TIME_MODE] = {"fmi2EnterContinuousTimeMode", 0, IN(EVENT_MODE)},
    [FMI2_COMPLETED_INTEGRATOR_STEP] = {"fmi2CompletedIntegratorStep", 0,
        IN(CONTINUOUS_TIME_MODE)},
    [FMI2_SET_TIME] = {"fmi2SetTime", 0, IN(EVENT_MODE) | IN(CONTINUOUS_TIME_MODE)},
    [FMI2_SET_CONTINUOUS_STATES] = {"fmi2SetContinuousStates", 0, IN(CONTINUOUS_TIME_MODE)},
#define MODEL_GETTER(CALL, name) \
    [CALL] = {name, 0, IN(INITIALIZATION_MODE) | IN(EVENT_MODE) | \
                           IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)}
    MODEL_GETTER(FMI2_GET_EVENT_INDICATORS, "fmi2GetEventIndicators"),
    MODEL_GETTER(FMI2_GET_CONTINUOUS_STATES, "fmi2GetContinuousStates"),
    MODEL_GETTER(FMI2_GET_DERIVATIVES, "fmi2GetDerivatives"),
#undef MODEL_GETTER
    [FMI2_GET_NOMINALS_OF_CONTINUOUS_STATES] = {"fmi2GetNominalsOfContinuousStates", 0,
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(EVENT_MODE) |
            IN(CONTINUOUS_TIME_MODE) | IN(TERMINATED) | IN(ERROR)},
    /* Co-Simulation only */
    [FMI2_SET_REAL_INPUT_DERIVATIVES] = {"fmi2SetRealInputDerivatives",
        IN(INSTANTIATED) | IN(INITIALIZATION_MODE) | IN(STEP_COMPLETE), 0},
    [FMI2_GET_REAL_OUTPUT_DERIVATIVES] = {"fmi2GetRealOutputDerivatives",
        DONE_OR_FAILED | IN(TERMINATED) | IN(ERROR), 0},
    [FMI2_DO_STEP] = {"fmi2DoStep", IN(STEP_COMPLETE), 0},
    [FMI2_CANCEL_STEP] = {"fmi2CancelStep", IN(STEP_IN_PROGRESS), 0},
#define STATUS_CALL(CALL, name) \
    [CALL] = {name, IN(STEP_COMPLETE) | IN(STEP_IN_PROGRESS) | IN(STEP_FAILED) | \
                        IN(TERMINATED), 0}
    STATUS_CALL(FMI2_GET_STATUS, "fmi2GetStatus"),
    STATUS_CALL(FMI2_GET_REAL_STATUS, "fmi2GetRealStatus"),
    STATUS_CALL(FMI2_GET_INTEGER_STATUS, "fmi2GetIntegerStatus"),
    STATUS_CALL(FMI2_GET_BOOLEAN_STATUS, "fmi2GetBooleanStatus"),
    STATUS_CALL(FMI2_GET_STRING_STATUS, "fmi2GetStringStatus"),
#undef STATUS_CALL
};

static const char *const STATE_NAMES[FMI2_STATE_COUNT] = {
    [FMI2_START_END] = "start/end", [FMI2_INSTANTIATED] = "instantiated",
    [FMI2_INITIALIZATION_MODE] = "Initialization Mode", [FMI2_EVENT_MODE] = "Event Mode",
    [FMI2_CONTINUOUS_TIME_MODE] = "Continuous-Time Mode",
    [FMI2_STEP_COMPLETE] = "stepComplete", [FMI2_STEP_IN_PROGRESS] = "stepInProgress",
    [FMI2_STEP_FAILED] = "stepFailed", [FMI2_STEP_CANCELED] = "stepCanceled",
    [FMI2_TERMINATED] = "terminated", [FMI2_ERROR] = "error", [FMI2_FATAL] = "fatal"};

static unsigned allowed_states(fmi2Type type, Fmi2Call call) {
    if ((unsigned)call >= FMI2_CALL_COUNT) return 0;
    return type == fmi2ModelExchange ? TABLE[call].model_exchange : TABLE[call].co_simulation;
}

int fmi2_allowed(fmi2Type type, Fmi2State state, Fmi2Call call) {
    return (unsigned)state < FMI2_STATE_COUNT && (allowed_states(type, call) & (1u << state));
}

Fmi2State fmi2_next_state(fmi2Type type, Fmi2State state, Fmi2Call call, fmi2Status status) {
    if (status == fmi2Fatal) return FMI2_FATAL;
    if (status == fmi2Error) return state == FMI2_FATAL ? FMI2_FATAL : FMI2_ERROR;
    if (call == FMI2_DO_STEP && status == fmi2Discard) return FMI2_STEP_FAILED;
    if (call == FMI2_DO_STEP && status == fmi2Pending) return FMI2_STEP_IN_PROGRESS;
    if (status != fmi2OK && status != fmi2Warning) return state;
    switch (call) {
    case FMI2_INSTANTIATE: return FMI2_INSTANTIATED;
    case FMI2_FREE_INSTANCE: return FMI2_START_END;
    case FMI2_ENTER_INITIALIZATION_MODE: return FMI2_INITIALIZATION_MODE;
    case FMI2_EXIT_INITIALIZATION_MODE:
        return type == fmi2ModelExchange ? FMI2_EVENT_MODE : FMI2_STEP_COMPLETE;
    case FMI2_TERMINATE: return FMI2_TERMINATED;
    case FMI2_RESET: return FMI2_INSTANTIATED;
    case FMI2_DO_STEP: return FMI2_STEP_COMPLETE;
    case FMI2_CANCEL_STEP: return FMI2_STEP_CANCELED;
    case FMI2_ENTER_EVENT_MODE: return FMI2_EVENT_MODE;
    case FMI2_ENTER_CONTINUOUS_TIME_MODE: return FMI2_CONTINUOUS_TIME_MODE;
    default: return state;
    }
}

const char *fmi2_call_name(Fmi2Call call) {
    return (unsigned)call < FMI2_CALL_COUNT ? TABLE[call].name : "an unknown FMI 2.0 call";
}

const char *fmi2_state_name(Fmi2State state) {
    return (unsigned)state < FMI2_STATE_COUNT ? STATE_NAMES[state] : "an unknown state";
}

/* snprintf at text + *length, keeping *length within size */
static void add(char *text, size_t size, size_t *length, const char *format, const char *value) {
    if (*length >= size) return;
    int n = snprintf(text + *length, size - *length, format, value);
    if (n > 0) *length += (size_t)n;
    if (*length >= size) *length = size - 1;
}

void fmi2_refusal(fmi2Type type, Fmi2State state, Fmi2Call call, char *text, size_t size) {
    const char *kind = type == fmi2ModelExchange ? "Model Exchange" : "Co-Simulation";
    unsigned states = allowed_states(type, call);
    size_t length = 0;
    if (!size) return;
    text[0] = '\0';
    add(text, size, &length, "%s is not allowed in ", fmi2_call_name(call));
    add(text, size, &length, "%s (FMI 2.0 ", fmi2_state_name(state));
    add(text, size, &length, "%s", kind);
    if (!states) {
        add(text, size, &length, "%s has no such call)", "");
        return;
    }
    const char *separator = ": only in ";
    for (int s = 0; s < FMI2_STATE_COUNT; s++) {
        if (!(states & (1u << s))) continue;
        add(text, size, &length, "%s", separator);
        add(text, size, &length, "%s", STATE_NAMES[s]);
        separator = ", ";
    }
    add(text, size, &length, "%s)", "");
}
