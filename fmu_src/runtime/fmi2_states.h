/* The FMI 2.0 state machine of an FMU instance: which call is allowed in which state, and the
 * state a call leaves the instance in. FMI 2.0.x, section 4.2.4 (Co-Simulation) and section
 * 3.2.3 (Model Exchange): one table for both interface types (fmi2_states.c).
 *
 * The runtime asks `fmi2_allowed` before every call on an instance and refuses a call the
 * table does not allow with fmi2Error and a message (`fmi2_refusal`); after the call it moves
 * the instance on with `fmi2_next_state`. A numbered cell of the standard's tables (a call
 * allowed only for some variables, or with values for debugging only) counts as allowed here:
 * the variables' own rules are the slave's to check.
 *
 * Only the runtime's sources include this header; nothing here is exported from the binary.
 */
#ifndef FMI2_STATES_H
#define FMI2_STATES_H

#include <stddef.h>
#include "fmi2Functions.h"

#define FMI2_INTERNAL __attribute__((visibility("hidden")))

/* The states of both interface types, as the standard names them. An instance of one type
 * never enters the states only the other type has. */
typedef enum {
    FMI2_START_END,             /* no instance: only fmi2Instantiate */
    FMI2_INSTANTIATED,
    FMI2_INITIALIZATION_MODE,
    FMI2_EVENT_MODE,            /* Model Exchange */
    FMI2_CONTINUOUS_TIME_MODE,  /* Model Exchange */
    FMI2_STEP_COMPLETE,         /* Co-Simulation: slaveInitialized, no step pending or failed */
    FMI2_STEP_IN_PROGRESS,      /* Co-Simulation: fmi2DoStep returned fmi2Pending */
    FMI2_STEP_FAILED,           /* Co-Simulation: fmi2DoStep returned fmi2Discard */
    FMI2_STEP_CANCELED,         /* Co-Simulation: after fmi2CancelStep */
    FMI2_TERMINATED,
    FMI2_ERROR,                 /* a call returned fmi2Error */
    FMI2_FATAL,                 /* a call returned fmi2Fatal */
    FMI2_STATE_COUNT
} Fmi2State;

/* Every FMI 2.0 function, in the order of the standard's tables. */
typedef enum {
    FMI2_GET_TYPES_PLATFORM,
    FMI2_GET_VERSION,
    FMI2_SET_DEBUG_LOGGING,
    FMI2_INSTANTIATE,
    FMI2_FREE_INSTANCE,
    FMI2_SETUP_EXPERIMENT,
    FMI2_ENTER_INITIALIZATION_MODE,
    FMI2_EXIT_INITIALIZATION_MODE,
    FMI2_TERMINATE,
    FMI2_RESET,
    FMI2_GET_REAL,
    FMI2_GET_INTEGER,
    FMI2_GET_BOOLEAN,
    FMI2_GET_STRING,
    FMI2_SET_REAL,
    FMI2_SET_INTEGER,
    FMI2_SET_BOOLEAN,
    FMI2_SET_STRING,
    FMI2_GET_FMU_STATE,
    FMI2_SET_FMU_STATE,
    FMI2_FREE_FMU_STATE,
    FMI2_SERIALIZED_FMU_STATE_SIZE,
    FMI2_SERIALIZE_FMU_STATE,
    FMI2_DESERIALIZE_FMU_STATE,
    FMI2_GET_DIRECTIONAL_DERIVATIVE,
    /* Model Exchange only */
    FMI2_ENTER_EVENT_MODE,
    FMI2_NEW_DISCRETE_STATES,
    FMI2_ENTER_CONTINUOUS_TIME_MODE,
    FMI2_COMPLETED_INTEGRATOR_STEP,
    FMI2_SET_TIME,
    FMI2_SET_CONTINUOUS_STATES,
    FMI2_GET_EVENT_INDICATORS,
    FMI2_GET_CONTINUOUS_STATES,
    FMI2_GET_DERIVATIVES,
    FMI2_GET_NOMINALS_OF_CONTINUOUS_STATES,
    /* Co-Simulation only */
    FMI2_SET_REAL_INPUT_DERIVATIVES,
    FMI2_GET_REAL_OUTPUT_DERIVATIVES,
    FMI2_DO_STEP,
    FMI2_CANCEL_STEP,
    FMI2_GET_STATUS,
    FMI2_GET_REAL_STATUS,
    FMI2_GET_INTEGER_STATUS,
    FMI2_GET_BOOLEAN_STATUS,
    FMI2_GET_STRING_STATUS,
    FMI2_CALL_COUNT
} Fmi2Call;

/* Whether the standard allows the call in the state, for an instance of this type. */
FMI2_INTERNAL int fmi2_allowed(fmi2Type type, Fmi2State state, Fmi2Call call);

/* The state after the call returned status in state (the call was allowed there):
 * - fmi2Fatal: fatal; fmi2Error: error (FMI 2.0, section 2.1.3: the simulation cannot go on
 *   but from a stored FMU state, fmi2SetFMUstate, or after fmi2Reset);
 * - fmi2Discard of fmi2DoStep: stepFailed; fmi2Pending of fmi2DoStep: stepInProgress;
 * - fmi2OK or fmi2Warning: the transition of the standard's state machine (fmi2Reset:
 *   instantiated, fmi2ExitInitializationMode: stepComplete or Event Mode, ...);
 * - anything else: the state as it was.
 * fmi2SetFMUstate leaves the state as it was here: the runtime restores the state the FMU
 * state was taken in. */
FMI2_INTERNAL Fmi2State fmi2_next_state(fmi2Type type, Fmi2State state, Fmi2Call call,
                                        fmi2Status status);

/* The name of the call ("fmi2DoStep") and of the state ("Initialization Mode"). */
FMI2_INTERNAL const char *fmi2_call_name(Fmi2Call call);
FMI2_INTERNAL const char *fmi2_state_name(Fmi2State state);

/* The message of a refused call: "<call> is not allowed in <state> (FMI 2.0 <type>: only in
 * <the states that allow it>)", into text (at most size bytes, NUL-terminated). */
FMI2_INTERNAL void fmi2_refusal(fmi2Type type, Fmi2State state, Fmi2Call call, char *text,
                                size_t size);

#endif
