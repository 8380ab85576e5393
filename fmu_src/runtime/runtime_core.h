/* The version-neutral core of the FMUs' runtime (runtime_core.c): what every FMI version's
 * entry points (fmi2_functions.c for FMI 2.0) stand on, in C over the Python C API.
 *
 * - Python: the CPython of the process found or loaded and started, one FMU at a time
 *   (`load`), the Python C API resolved from it (`py`), a Python thread state per host thread,
 *   the GIL taken around every call (`enter_python`, `leave_python`) and around a fork.
 * - The FMU: its resources folder from a resource location URI (`resource_folder`), its slave
 *   module (`slave_module`) and the GUID recorded at build time (`recorded_guid`).
 * - Instances: an `Instance` owns its slave, made from the class the slave module defines
 *   below the version's slave base (`create_slave`, through the Python helper that imports
 *   each FMU's own bundle), the slave's methods looked up once (`Method`,
 *   `ModelExchangeMethod`), and its messages (`Sink`), passed to the host's logger through the
 *   version's `Emit`; a Python exception is the status Error (Fatal for MemoryError and
 *   SystemExit) with one message (`python_failure`).
 * - Calling the slave: value reference lists, counts checked before an array is read, results
 *   converted (`reference_list`, `references_fit`, `take_numbers`, `truth`, `wrong_result`).
 *
 * An FMI version provides the exported functions of its standard: it allocates an Instance
 * (calloc), sets its tag, sink and what the version keeps in `type`, `state` and
 * `last_successful_time`, checks every call against its state machine and calls the slave's
 * methods between `enter_python` and `leave_python`. Statuses are those of every FMI version
 * (STATUS_OK ... STATUS_FATAL, the same numbers as fmi2Status and fmi3Status).
 *
 * Only the runtime's sources include this header; nothing here is exported from the binary
 * (each FMU's copy of the runtime keeps its own).
 */
#ifndef RUNTIME_CORE_H
#define RUNTIME_CORE_H

#include <stddef.h>
#include <sys/types.h>

#define CORE_INTERNAL __attribute__((visibility("hidden")))

#define MESSAGE_SIZE 8192

/* The statuses, numbered as every FMI version numbers them. */
enum { STATUS_OK, STATUS_WARNING, STATUS_DISCARD, STATUS_ERROR, STATUS_FATAL };

/* ---- the Python C API, resolved by name from the process (one binary for 3.8 and later) */
typedef struct _object PyObject;
typedef ssize_t Py_ssize_t;
typedef int PyGILState_STATE;
typedef struct { int type; const char *func; const char *err_msg; int exitcode; } PyStatus;

#define PYTHON_API(X) \
    X(int, Py_IsInitialized, (void)) \
    X(const char *, Py_GetVersion, (void)) \
    X(void, PyPreConfig_InitPythonConfig, (void *)) \
    X(PyStatus, Py_PreInitialize, (const void *)) \
    X(void, PyConfig_InitPythonConfig, (void *)) \
    X(PyStatus, Py_InitializeFromConfig, (const void *)) \
    X(PyStatus, PyConfig_SetBytesString, (void *, void *, const char *)) \
    X(void, PyConfig_Clear, (void *)) \
    X(int, PyStatus_Exception, (PyStatus)) \
    X(void *, PyEval_SaveThread, (void)) \
    X(void, PyEval_RestoreThread, (void *)) \
    X(void, PyThreadState_Clear, (void *)) \
    X(void, PyThreadState_DeleteCurrent, (void)) \
    X(PyGILState_STATE, PyGILState_Ensure, (void)) \
    X(void, PyGILState_Release, (PyGILState_STATE)) \
    X(void *, PyGILState_GetThisThreadState, (void)) \
    X(int, PyGILState_Check, (void)) \
    X(void, PyOS_BeforeFork, (void)) \
    X(void, PyOS_AfterFork_Parent, (void)) \
    X(void, PyOS_AfterFork_Child, (void)) \
    X(void, Py_DecRef, (PyObject *)) \
    X(PyObject *, PyImport_ImportModule, (const char *)) \
    X(PyObject *, PyImport_AddModule, (const char *)) \
    X(PyObject *, PyModule_GetDict, (PyObject *)) \
    X(void, Py_IncRef, (PyObject *)) \
    X(PyObject *, PyObject_GetAttrString, (PyObject *, const char *)) \
    X(PyObject *, PyObject_CallFunctionObjArgs, (PyObject *, ...)) \
    X(PyObject *, PyObject_Str, (PyObject *)) \
    X(int, PyObject_IsTrue, (PyObject *)) \
    X(PyObject *, PyUnicode_DecodeFSDefault, (const char *)) \
    X(PyObject *, PyUnicode_FromString, (const char *)) \
    X(const char *, PyUnicode_AsUTF8AndSize, (PyObject *, Py_ssize_t *)) \
    X(PyObject *, PyUnicode_AsUTF8String, (PyObject *)) \
    X(PyObject *, PyLong_FromLong, (long)) \
    X(PyObject *, PyLong_FromSize_t, (size_t)) \
    X(long, PyLong_AsLong, (PyObject *)) \
    X(PyObject *, PyFloat_FromDouble, (double)) \
    X(double, PyFloat_AsDouble, (PyObject *)) \
    X(PyObject *, PyBool_FromLong, (long)) \
    X(PyObject *, PyList_New, (Py_ssize_t)) \
    X(int, PyList_SetItem, (PyObject *, Py_ssize_t, PyObject *)) \
    X(Py_ssize_t, PySequence_Size, (PyObject *)) \
    X(Py_ssize_t, PyObject_Size, (PyObject *)) \
    X(PyObject *, PySequence_GetItem, (PyObject *, Py_ssize_t)) \
    X(int, PySequence_DelSlice, (PyObject *, Py_ssize_t, Py_ssize_t)) \
    X(PyObject *, PySequence_GetSlice, (PyObject *, Py_ssize_t, Py_ssize_t)) \
    X(PyObject *, PyBytes_FromStringAndSize, (const char *, Py_ssize_t)) \
    X(int, PyBytes_AsStringAndSize, (PyObject *, char **, Py_ssize_t *)) \
    X(PyObject *, PyErr_Occurred, (void)) \
    X(void, PyErr_Fetch, (PyObject **, PyObject **, PyObject **)) \
    X(void, PyErr_NormalizeException, (PyObject **, PyObject **, PyObject **)) \
    X(void, PyErr_Clear, (void)) \
    X(int, PyErr_GivenExceptionMatches, (PyObject *, PyObject *)) \
    X(void, PyErr_SetInterrupt, (void)) \
    X(PyObject *, PyDict_New, (void)) \
    X(int, PyDict_SetItemString, (PyObject *, const char *, PyObject *)) \
    X(PyObject *, PyDict_GetItemString, (PyObject *, const char *)) \
    X(PyObject *, PyRun_StringFlags, (const char *, int, PyObject *, PyObject *, void *))

#define DECLARE(result, name, arguments) result(*name) arguments;
typedef struct {
    PYTHON_API(DECLARE)
    int (*IsFinalizing)(void);  /* Py_IsFinalizing (3.13) or _Py_IsFinalizing; may be NULL */
    PyObject *None, *MemoryError, *SystemExit, *KeyboardInterrupt;
} PythonApi;
#undef DECLARE

/* The Python C API of the CPython this runtime uses (valid once `load` succeeded). */
extern CORE_INTERNAL PythonApi py;

/* ---- messages ------------------------------------------------------------------------ */
typedef struct {
    char text[MESSAGE_SIZE];
    size_t length;
} Message;

/* printf at the end of the message, which stays within its size. */
CORE_INTERNAL void append(Message *m, const char *format, ...)
    __attribute__((format(printf, 2, 3)));

/* Where messages go: the host's logger, with the instance's name and logging settings. */
typedef struct Sink Sink;
/* Pass one message (a printf format that prints it as it is) to the host's logger of the
 * sink, with its status and category (NULL: the version's default for the status). */
typedef void (*Emit)(const Sink *sink, int status, const char *category, const char *text);
struct Sink {
    Emit emit;          /* NULL: the host gave no logger */
    void (*logger)(void);  /* the host's logger, called by emit (cast to its own type) */
    void *environment;  /* and the environment the host passes it */
    char *name;
    int logging_on;
    char **categories;  /* NULL: every category */
    size_t category_count;
    int depth;          /* calls of the logger under way: a logger may call the FMU again */
};

/* Pass text to the host's logger, each % as %% and each line break as a space: Error and
 * Fatal messages always, the others when logging is on and their category enabled. */
CORE_INTERNAL void log_text(Sink *sink, int status, const char *category, const char *text);
CORE_INTERNAL void log_format(Sink *sink, int status, const char *format, ...)
    __attribute__((format(printf, 3, 4)));

/* ---- the FMU and its Python ------------------------------------------------------------ */
/* The GUID recorded in the FMU's resources/python.txt ("" if none). */
CORE_INTERNAL const char *recorded_guid(void);
/* Python found or loaded, started and its helper made (once per copy of the runtime); 0 with
 * why on failure. */
CORE_INTERNAL int load(Message *why);
/* The folder a resource location names, or NULL with why (malloc'ed). */
CORE_INTERNAL char *resource_folder(const char *uri, Message *why);
/* The slave module's name from <folder>/slavemodule.txt, or NULL with why (malloc'ed). */
CORE_INTERNAL char *slave_module(const char *folder, const char *uri, Message *why);

/* ---- instances ------------------------------------------------------------------------ */
/* The slave's methods the runtime calls (pythonfmu's names, which every version maps onto). */
enum Method {
    DO_STEP, GET_REAL, SET_REAL, GET_INTEGER, SET_INTEGER, GET_BOOLEAN, SET_BOOLEAN,
    GET_STRING, SET_STRING, SETUP_EXPERIMENT, ENTER_INITIALIZATION_MODE,
    EXIT_INITIALIZATION_MODE, TERMINATE, GET_FMU_STATE, SET_FMU_STATE, STATE_TO_BYTES,
    STATE_FROM_BYTES, METHOD_COUNT
};

/* Model Exchange's calls of the slave (fmu_src/fmi/model_exchange.py), looked up for a Model
 * Exchange instance only */
enum ModelExchangeMethod {
    ME_SET_TIME, ME_SET_CONTINUOUS_STATES, ME_GET_CONTINUOUS_STATES, ME_GET_NOMINALS,
    ME_GET_DERIVATIVES, ME_GET_EVENT_INDICATORS, ME_ENTER_EVENT_MODE, ME_NEW_DISCRETE_STATES,
    ME_ENTER_CONTINUOUS_TIME_MODE, ME_COMPLETED_INTEGRATOR_STEP, ME_METHOD_COUNT
};

typedef struct {
    unsigned tag;                 /* the version's: a live instance of its runtime */
    Sink sink;
    char *guid, *resources, *module;
    const char *slave_base;       /* the class the slave derives from, "pythonfmu.Fmi2Slave" */
    int visible;
    int model_exchange;           /* a Model Exchange instance: its me_ methods looked up */
    int type;                     /* the version's: its interface type */
    int state;                    /* the version's: its state machine state */
    double last_successful_time;  /* the FMU's time [s]: where the next step must start */
    PyObject *cls, *slave, *queue;
    PyObject *methods[METHOD_COUNT];
    PyObject *me_methods[ME_METHOD_COUNT];  /* a Model Exchange instance's */
    size_t state_count, indicator_count;     /* its nx and ni */
    PyObject **strings;  /* the UTF-8 bytes behind the last string get call's values */
    size_t string_count;
    size_t variable_count;  /* the slave's variables: no call names more value references */
    char *failure;       /* the message of the current call's Python exception */
} Instance;

/* Release a reference held, if any, and forget it. */
static inline void release(PyObject **object) {
    if (*object) py.Py_DecRef(*object);
    *object = NULL;
}

CORE_INTERNAL void release_strings(Instance *in);
/* Release the slave, its methods, its log queue and the strings last read (the GIL held). */
CORE_INTERNAL void release_slave(Instance *in);
/* Make the instance's slave (and look its methods up once), the GIL held: 1, or 0 after
 * logging why (function: the version's instantiate call, for the message), or 0 with
 * *missing naming a Model Exchange method or count a slave of Co-Simulation only lacks
 * (not logged, the slave kept: the version says so). */
CORE_INTERNAL int create_slave(Instance *in, const char *function, const char **missing);
/* Free the instance and all it owns. */
CORE_INTERNAL void free_instance(Instance *in);

/* ---- calling the slave ---------------------------------------------------------------- */
/* Enter Python for a call: a thread state for this thread, the GIL taken. */
CORE_INTERNAL PyGILState_STATE enter_python(void);
/* Leave Python after a call that returned status: the slave's messages passed on, then the
 * call's failure if the status is Error or Fatal, the GIL given back. */
CORE_INTERNAL void leave_python(Instance *in, int status, PyGILState_STATE gil);
/* The status of the pending Python exception, taken: Error (Fatal for MemoryError and
 * SystemExit), its message "<function>: <type>: <message>" kept for the caller to log. */
CORE_INTERNAL int python_failure(Instance *in, const char *function);
/* Pass the slave's queued log messages on (the GIL held). */
CORE_INTERNAL void drain_log(Instance *in);
/* Error with the call's failure message "<function>: the slave's <what>". */
CORE_INTERNAL int wrong_result(Instance *in, const char *function, const char *what);
/* nvr no larger than the FMU's number of variables, checked before any array is read;
 * otherwise 0 with the call's failure message set. */
CORE_INTERNAL int references_fit(Instance *in, size_t nvr, const char *function);
/* A Python list of the value references (new reference), or NULL. */
CORE_INTERNAL PyObject *reference_list(const unsigned int vr[], size_t nvr);
/* Error with the message "<function>: <nx or ni> = <given> is not this FMU's number of ...". */
CORE_INTERNAL int wrong_count(Instance *in, const char *function, int states, size_t given,
                              size_t count);
/* Copy a method's result, a sequence of n numbers, into values (n checked by the caller):
 * OK, or the status of its failure. */
CORE_INTERNAL int take_numbers(Instance *in, const char *function, PyObject *result,
                               double values[], size_t n);
/* The truth of item i of a result sequence (-1 with the exception pending). */
CORE_INTERNAL int truth(PyObject *result, Py_ssize_t i);

#endif
