/* The FMU's linux64 binary: loads Python by itself, then forwards every FMI 2.0 call to
 * pythonfmu's binary, installed beside it as <Model>.pythonfmu.so.
 *
 * pythonfmu's binary takes the Python C API from the process it is loaded into, so a host
 * that is not a Python process (fmuCheck, fmusim, OMSimulator, libcosim's CLI) fails to load
 * it. On the first fmi2Instantiate this loader:
 * - in a process that already has Python (Py_IsInitialized visible, e.g. FMPy), loads none;
 * - otherwise loads, with RTLD_GLOBAL, the libpython named by the environment variable
 *   BALANCER_FMU_LIBPYTHON if set (and only that one), else the one the FMU was built with
 *   (recorded in resources/python.txt), else the libpython 3.8 or later the dynamic linker
 *   finds; for the recorded library it sets PYTHONHOME to the recorded prefix when the host
 *   has none;
 * - then loads pythonfmu's binary. When nothing loads, fmi2Instantiate logs every path it
 *   tried and returns NULL.
 *
 * It also:
 * - keeps a Python thread state for each host thread that calls in without one, so that
 *   pythonfmu's PyGILState_Ensure/Release around every call only take the GIL instead of
 *   creating and destroying a thread state each time;
 * - refuses, with fmi2Fatal and without calling into Python, any call on an instance that
 *   has returned fmi2Fatal (pythonfmu's instance is unusable then and may crash the host);
 *   fmi2FreeInstance of such an instance frees only the loader's part.
 *
 * build: python -m ziglang cc -target x86_64-linux-gnu.2.17 -shared -fPIC -O2
 *        -I<fmpy>/c-code fmi2_loader.c -o <Model>.so   (harness/fmu_build.py does this)
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include "fmi2Functions.h"

#define OVERRIDE_VARIABLE "BALANCER_FMU_LIBPYTHON"
#define RECORD_FILE "python.txt"  /* in the FMU's resources: key=value lines */
#define PYTHONFMU_SUFFIX ".pythonfmu.so"
#define MESSAGE_SIZE 8192
#define PATH_SIZE 4096

/* sonames the dynamic linker may find when the recorded library is absent, newest first */
static const char *const FALLBACK_SONAMES[] = {
    "libpython3.14.so.1.0", "libpython3.13.so.1.0", "libpython3.12.so.1.0",
    "libpython3.11.so.1.0", "libpython3.10.so.1.0", "libpython3.9.so.1.0",
    "libpython3.8.so.1.0"};

/* pythonfmu's functions, resolved once */
static struct {
    fmi2InstantiateTYPE *Instantiate;
    fmi2FreeInstanceTYPE *FreeInstance;
    fmi2SetDebugLoggingTYPE *SetDebugLogging;
    fmi2SetupExperimentTYPE *SetupExperiment;
    fmi2EnterInitializationModeTYPE *EnterInitializationMode;
    fmi2ExitInitializationModeTYPE *ExitInitializationMode;
    fmi2TerminateTYPE *Terminate;
    fmi2ResetTYPE *Reset;
    fmi2GetRealTYPE *GetReal;
    fmi2GetIntegerTYPE *GetInteger;
    fmi2GetBooleanTYPE *GetBoolean;
    fmi2GetStringTYPE *GetString;
    fmi2SetRealTYPE *SetReal;
    fmi2SetIntegerTYPE *SetInteger;
    fmi2SetBooleanTYPE *SetBoolean;
    fmi2SetStringTYPE *SetString;
    fmi2GetFMUstateTYPE *GetFMUstate;
    fmi2SetFMUstateTYPE *SetFMUstate;
    fmi2FreeFMUstateTYPE *FreeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *SerializedFMUstateSize;
    fmi2SerializeFMUstateTYPE *SerializeFMUstate;
    fmi2DeSerializeFMUstateTYPE *DeSerializeFMUstate;
    fmi2GetDirectionalDerivativeTYPE *GetDirectionalDerivative;
    fmi2SetRealInputDerivativesTYPE *SetRealInputDerivatives;
    fmi2GetRealOutputDerivativesTYPE *GetRealOutputDerivatives;
    fmi2DoStepTYPE *DoStep;
    fmi2CancelStepTYPE *CancelStep;
    fmi2GetStatusTYPE *GetStatus;
    fmi2GetRealStatusTYPE *GetRealStatus;
    fmi2GetIntegerStatusTYPE *GetIntegerStatus;
    fmi2GetBooleanStatusTYPE *GetBooleanStatus;
    fmi2GetStringStatusTYPE *GetStringStatus;
} fmu;

/* the Python C API (stable ABI) the loader uses itself, resolved once Python is there */
typedef int PyGILStateType; /* PyGILState_STATE, an enum */
static struct {
    int (*IsInitialized)(void);
    void *(*GILStateGetThisThreadState)(void);
    PyGILStateType (*GILStateEnsure)(void);
    void *(*EvalSaveThread)(void);
} py;

static void *pythonfmu; /* pythonfmu's binary, unloaded with this library */
static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int loaded; /* fmu and py are resolved */
static __thread int thread_state_held;

/* One instance: pythonfmu's component, and whether a call on it returned fmi2Fatal. */
typedef struct {
    fmi2Component inner;
    int fatal;
    char *name;
    fmi2CallbackFunctions callbacks;
} Instance;

typedef struct {
    char text[MESSAGE_SIZE];
    size_t length;
} Message;

static void append(Message *m, const char *format, ...) {
    va_list args;
    if (m->length >= sizeof m->text - 1) return;
    va_start(args, format);
    int n = vsnprintf(m->text + m->length, sizeof m->text - m->length, format, args);
    va_end(args);
    if (n > 0) m->length += (size_t)n;
    if (m->length > sizeof m->text - 1) m->length = sizeof m->text - 1;
}

static int is_directory(const char *path) {
    struct stat info;
    return stat(path, &info) == 0 && S_ISDIR(info.st_mode);
}

/* The folder of this library (binaries/linux64), without a trailing slash. */
static int own_folder(char *folder, size_t size) {
    Dl_info info;
    if (!dladdr((void *)&own_folder, &info) || !info.dli_fname) return 0;
    snprintf(folder, size, "%s", info.dli_fname);
    char *slash = strrchr(folder, '/');
    if (!slash) return 0;
    *slash = '\0';
    return 1;
}

/* The value of key in the recorded file (key=value lines), or "" if absent. */
static void recorded(const char *record, const char *key, char *value, size_t size) {
    value[0] = '\0';
    FILE *file = fopen(record, "r");
    if (!file) return;
    char line[PATH_SIZE];
    size_t key_length = strlen(key);
    while (fgets(line, sizeof line, file)) {
        if (strncmp(line, key, key_length) == 0 && line[key_length] == '=') {
            line[strcspn(line, "\r\n")] = '\0';
            snprintf(value, size, "%s", line + key_length + 1);
            break;
        }
    }
    fclose(file);
}

/* A Python host, or a libpython loaded before (by this FMU or another): load none. */
static int python_in_process(void) { return dlsym(RTLD_DEFAULT, "Py_IsInitialized") != NULL; }

/* dlopen a libpython (RTLD_GLOBAL) and check it is CPython 3.8 or later; on failure add
 * why to the message and return 0. */
static int open_libpython(const char *path, Message *why) {
    void *handle = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    if (!handle) {
        const char *error = dlerror();
        size_t length = strlen(path); /* dlerror often starts with the path already */
        if (strncmp(error, path, length) == 0 && strncmp(error + length, ": ", 2) == 0)
            error += length + 2;
        append(why, "\n  %s: %s", path, error);
        return 0;
    }
    const char *(*version)(void) = (const char *(*)(void))dlsym(handle, "Py_GetVersion");
    int major = 0, minor = 0;
    if (!version || sscanf(version(), "%d.%d", &major, &minor) != 2 || major != 3 || minor < 8) {
        append(why, "\n  %s: not a CPython 3.8 or later library (%s)", path,
               version ? version() : "no Py_GetVersion");
        dlclose(handle);
        return 0;
    }
    return 1;
}

/* Load libpython as the header comment says; 0 with the paths tried in why on failure. */
static int load_python(const char *folder, Message *why) {
    if (python_in_process()) return 1;
    const char *override = getenv(OVERRIDE_VARIABLE);
    if (override && override[0]) {
        append(why, "no Python for this FMU; tried %s=%s:", OVERRIDE_VARIABLE, override);
        return open_libpython(override, why);
    }
    char record[PATH_SIZE], library[PATH_SIZE], prefix[PATH_SIZE];
    snprintf(record, sizeof record, "%s/../../resources/" RECORD_FILE, folder);
    recorded(record, "libpython", library, sizeof library);
    recorded(record, "prefix", prefix, sizeof prefix);
    append(why, "no Python for this FMU; tried (%s unset):", OVERRIDE_VARIABLE);
    if (library[0]) {
        if (open_libpython(library, why)) {
            if (!getenv("PYTHONHOME") && prefix[0] && is_directory(prefix))
                setenv("PYTHONHOME", prefix, 0);
            return 1;
        }
    } else {
        append(why, "\n  %s: no libpython recorded", record);
    }
    for (size_t i = 0; i < sizeof FALLBACK_SONAMES / sizeof *FALLBACK_SONAMES; i++)
        if (open_libpython(FALLBACK_SONAMES[i], why)) return 1;
    return 0;
}

#define RESOLVE(name) \
    if (!(fmu.name = (fmi2##name##TYPE *)dlsym(handle, "fmi2" #name))) { \
        append(why, "%s: no fmi2" #name, path); return 0; }

static int load_pythonfmu(const char *folder, Message *why) {
    Dl_info info;
    char path[PATH_SIZE];
    if (!dladdr((void *)&load_pythonfmu, &info) || !info.dli_fname) return 0;
    const char *name = strrchr(info.dli_fname, '/');
    name = name ? name + 1 : info.dli_fname;
    size_t stem = strlen(name) > 3 ? strlen(name) - 3 : strlen(name); /* drop ".so" */
    snprintf(path, sizeof path, "%s/%.*s" PYTHONFMU_SUFFIX, folder, (int)stem, name);
    void *handle = pythonfmu = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        append(why, "pythonfmu's binary %s: %s", path, dlerror());
        return 0;
    }
    RESOLVE(Instantiate) RESOLVE(FreeInstance) RESOLVE(SetDebugLogging)
    RESOLVE(SetupExperiment) RESOLVE(EnterInitializationMode) RESOLVE(ExitInitializationMode)
    RESOLVE(Terminate) RESOLVE(Reset)
    RESOLVE(GetReal) RESOLVE(GetInteger) RESOLVE(GetBoolean) RESOLVE(GetString)
    RESOLVE(SetReal) RESOLVE(SetInteger) RESOLVE(SetBoolean) RESOLVE(SetString)
    RESOLVE(GetFMUstate) RESOLVE(SetFMUstate) RESOLVE(FreeFMUstate)
    RESOLVE(SerializedFMUstateSize) RESOLVE(SerializeFMUstate) RESOLVE(DeSerializeFMUstate)
    RESOLVE(GetDirectionalDerivative) RESOLVE(SetRealInputDerivatives)
    RESOLVE(GetRealOutputDerivatives) RESOLVE(DoStep) RESOLVE(CancelStep)
    RESOLVE(GetStatus) RESOLVE(GetRealStatus) RESOLVE(GetIntegerStatus)
    RESOLVE(GetBooleanStatus) RESOLVE(GetStringStatus)
    return 1;
}

static int resolve_python_api(Message *why) {
    py.IsInitialized = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    py.GILStateGetThisThreadState = (void *(*)(void))dlsym(RTLD_DEFAULT,
                                                            "PyGILState_GetThisThreadState");
    py.GILStateEnsure = (PyGILStateType(*)(void))dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    py.EvalSaveThread = (void *(*)(void))dlsym(RTLD_DEFAULT, "PyEval_SaveThread");
    if (py.IsInitialized && py.GILStateGetThisThreadState && py.GILStateEnsure &&
        py.EvalSaveThread) return 1;
    append(why, "the Python C API is not visible after loading libpython");
    return 0;
}

/* Make loaded true, or write why not. */
static int load(Message *why) {
    pthread_mutex_lock(&load_lock);
    if (!loaded) {
        char folder[PATH_SIZE];
        if (!own_folder(folder, sizeof folder))
            append(why, "cannot locate this library's folder");
        else if (!load_python(folder, why))
            append(why, "\nThis FMU runs its model in CPython 3.8 or later: set %s to the "
                        "path of a libpython3.X.so.1.0 shared library.", OVERRIDE_VARIABLE);
        else {
            why->length = 0;
            why->text[0] = '\0';
            loaded = load_pythonfmu(folder, why) && resolve_python_api(why);
            if (!loaded && pythonfmu) { /* a binary that resolved only in part: the next */
                dlclose(pythonfmu);      /* instantiation opens it afresh, leaking none */
                pythonfmu = NULL;
            }
        }
    }
    int ok = loaded;
    pthread_mutex_unlock(&load_lock);
    return ok;
}

/* When the host unloads the FMU, unload pythonfmu's binary too, as a host loading it directly
 * would: otherwise every copy FMPy extracts stays loaded, and their destructors all run at
 * process exit, after the interpreter's finalisation. */
__attribute__((destructor)) static void unload_pythonfmu(void) {
    if (pythonfmu) dlclose(pythonfmu);
}

/* Give the calling thread a Python thread state for its lifetime if it has none: taken
 * (PyGILState_Ensure) and released at once (PyEval_SaveThread), it stays registered for the
 * thread, so pythonfmu's PyGILState_Ensure/Release pairs reuse it. */
static void hold_thread_state(void) {
    if (thread_state_held || !py.IsInitialized()) return;
    thread_state_held = 1;
    if (py.GILStateGetThisThreadState() == NULL) {
        py.GILStateEnsure();
        py.EvalSaveThread();
    }
}

static void refuse(Instance *instance, const char *function) {
    if (instance->callbacks.logger)
        instance->callbacks.logger(instance->callbacks.componentEnvironment, instance->name,
                                   fmi2Fatal, "logStatusFatal",
                                   "%s refused: an earlier call on this instance returned "
                                   "fmi2Fatal", function);
}

/* Forward a call on an instance, or refuse it after an earlier fmi2Fatal. */
#define FORWARD(function, ...) \
    do { \
        if (!c) return fmi2Error; \
        Instance *instance = (Instance *)c; \
        if (instance->fatal) { refuse(instance, "fmi2" #function); return fmi2Fatal; } \
        hold_thread_state(); \
        fmi2Status status = fmu.function(instance->inner, ##__VA_ARGS__); \
        if (status == fmi2Fatal) instance->fatal = 1; \
        return status; \
    } while (0)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Message why = {{0}, 0};
    if (!load(&why)) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Fatal,
                              "logStatusFatal", "%s", why.text);
        return NULL;
    }
    Instance *instance = calloc(1, sizeof *instance);
    if (!instance) return NULL;
    instance->name = strdup(instanceName ? instanceName : "");
    if (functions) instance->callbacks = *functions;
    instance->inner = fmu.Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation,
                                      functions, visible, loggingOn);
    hold_thread_state(); /* pythonfmu's first instance initialises the interpreter */
    if (!instance->inner || !instance->name) {
        if (instance->inner) fmu.FreeInstance(instance->inner);
        free(instance->name);
        free(instance);
        return NULL;
    }
    return instance;
}

void fmi2FreeInstance(fmi2Component c) {
    if (!c) return;
    Instance *instance = (Instance *)c;
    if (!instance->fatal) { /* a fatal pythonfmu instance may crash on any call */
        hold_thread_state();
        fmu.FreeInstance(instance->inner);
    }
    free(instance->name);
    free(instance);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    FORWARD(SetDebugLogging, loggingOn, nCategories, categories);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    FORWARD(SetupExperiment, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { FORWARD(EnterInitializationMode); }

fmi2Status fmi2ExitInitializationMode(fmi2Component c) { FORWARD(ExitInitializationMode); }

fmi2Status fmi2Terminate(fmi2Component c) { FORWARD(Terminate); }

fmi2Status fmi2Reset(fmi2Component c) { FORWARD(Reset); }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) { FORWARD(GetReal, vr, nvr, value); }

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) { FORWARD(GetInteger, vr, nvr, value); }

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) { FORWARD(GetBoolean, vr, nvr, value); }

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) { FORWARD(GetString, vr, nvr, value); }

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) { FORWARD(SetReal, vr, nvr, value); }

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) { FORWARD(SetInteger, vr, nvr, value); }

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) { FORWARD(SetBoolean, vr, nvr, value); }

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) { FORWARD(SetString, vr, nvr, value); }

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    FORWARD(GetFMUstate, state);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    FORWARD(SetFMUstate, state);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    FORWARD(FreeFMUstate, state);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    FORWARD(SerializedFMUstateSize, state, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                 size_t size) {
    FORWARD(SerializeFMUstate, state, bytes, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *state) {
    FORWARD(DeSerializeFMUstate, bytes, size, state);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[],
                                        size_t nUnknown, const fmi2ValueReference known[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    FORWARD(GetDirectionalDerivative, unknown, nUnknown, known, nKnown, dvKnown, dvUnknown);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    FORWARD(SetRealInputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    FORWARD(GetRealOutputDerivatives, vr, nvr, order, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    FORWARD(DoStep, currentCommunicationPoint, communicationStepSize,
            noSetFMUStatePriorToCurrentPoint);
}

fmi2Status fmi2CancelStep(fmi2Component c) { FORWARD(CancelStep); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    FORWARD(GetStatus, s, value);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    FORWARD(GetRealStatus, s, value);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Integer *value) {
    FORWARD(GetIntegerStatus, s, value);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    FORWARD(GetBooleanStatus, s, value);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    FORWARD(GetStringStatus, s, value);
}
