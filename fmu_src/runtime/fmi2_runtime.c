/* The FMU's linux64 binary: an FMI 2.0 Co-Simulation and Model Exchange runtime, in C, over
 * pythonfmu's Python API (the Fmi2Slave instance and its methods; for Model Exchange the
 * slave's me_ methods, fmu_src/fmi/model_exchange.py). pythonfmu's own binary is not used.
 *
 * Python:
 * - In a process that already has Python (Py_IsInitialized visible, e.g. FMPy), it uses that
 *   interpreter. Otherwise, on the first fmi2Instantiate, it loads (RTLD_GLOBAL) the libpython
 *   named by BALANCER_FMU_LIBPYTHON if set (and only that one), else the one the FMU was built
 *   with (resources/python.txt), else a libpython 3.8 or later the dynamic linker finds, and
 *   starts it with Py_InitializeFromConfig, which returns a status instead of ending the
 *   process. For the recorded library it sets PYTHONHOME to the recorded prefix when the host
 *   has none. A failure gives NULL and a message naming what was tried, PYTHONHOME included.
 * - An interpreter it started stays running: nothing calls Py_Finalize, so no library
 *   destructor touches Python. It installs no signal handlers and leaves the host's locale
 *   environment alone.
 * - Every call holds the GIL through PyGILState_Ensure/Release. A host thread that arrives
 *   without a Python thread state gets one for its lifetime, released when the thread ends.
 *
 * References: every new reference is held by one owner and released once (Py_DecRef);
 * borrowed ones are never released. The instance owns its slave, the slave's bound methods
 * (looked up once) and its log queue; an FMU state owns its Python state.
 *
 * Status:
 * - a Python exception gives fmi2Error and one log line "<function>: <type>: <message>";
 *   MemoryError and SystemExit give fmi2Fatal; do_step returning False gives fmi2Discard;
 * - after fmi2Fatal every call returns fmi2Fatal without entering Python (fmi2FreeInstance
 *   still releases the instance);
 * - refused without entering Python, with a message: Model Exchange for a slave without it,
 *   a GUID other than the FMU's, a NULL name, GUID or resource location, an unusable
 *   resource location, a call in a phase that does not allow it (stepping, setting or
 *   initialising after fmi2Terminate) and a
 *   call of the other interface than the instance's (fmi2DoStep on a Model Exchange
 *   instance, fmi2GetDerivatives on a Co-Simulation one).
 *
 * Logging: the slave's log queue is passed on after every call, and the runtime's own
 * messages with it; each literal % reaches the host's logger as %% (its message is a printf
 * format). Error and Fatal messages always reach it, the others when logging is on (and, after
 * fmi2SetDebugLogging with categories, only those categories).
 *
 * build: python -m ziglang cc -target x86_64-linux-gnu.2.17 -shared -fPIC -O2
 *        -I<fmpy>/c-code fmi2_runtime.c -o <Model>.so   (harness/fmu/build.py does this)
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <stddef.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>
#include "fmi2Functions.h"

#define OVERRIDE_VARIABLE "BALANCER_FMU_LIBPYTHON"
#define RECORD_FILE "python.txt"   /* in the FMU's resources: key=value lines */
#define SLAVE_MODULE_FILE "slavemodule.txt"
#define STATE_HEADER "pythonfmu state of FMU "  /* + GUID + "\n", before the slave's bytes */
#define MESSAGE_SIZE 8192
#define PATH_SIZE 4096
#define CONFIG_SIZE 16384  /* bytes reserved for a PyConfig: larger than any CPython's */

/* sonames the dynamic linker may find when the recorded library is absent, newest first */
static const char *const FALLBACK_SONAMES[] = {
    "libpython3.14.so.1.0", "libpython3.13.so.1.0", "libpython3.12.so.1.0",
    "libpython3.11.so.1.0", "libpython3.10.so.1.0", "libpython3.9.so.1.0",
    "libpython3.8.so.1.0"};

/* ---- the Python C API, resolved by name from the process (one binary for 3.8 and later) */
typedef struct _object PyObject;
typedef ssize_t Py_ssize_t;
typedef int PyGILState_STATE;
enum { GIL_LOCKED = 0, GIL_UNLOCKED = 1 };  /* PyGILState_STATE's values */
typedef struct { int type; const char *func; const char *err_msg; int exitcode; } PyStatus;
#define PY_FILE_INPUT 257
#define PY_CONFIG_INIT_PYTHON 2  /* _PyConfig_INIT_PYTHON: PyConfig/PyPreConfig._config_init */

#define PYTHON_API(X) \
    X(int, Py_IsInitialized, (void)) \
    X(const char *, Py_GetVersion, (void)) \
    X(void, PyPreConfig_InitPythonConfig, (void *)) \
    X(PyStatus, Py_PreInitialize, (const void *)) \
    X(void, PyConfig_InitPythonConfig, (void *)) \
    X(PyStatus, Py_InitializeFromConfig, (const void *)) \
    X(void, PyConfig_Clear, (void *)) \
    X(int, PyStatus_Exception, (PyStatus)) \
    X(void *, PyEval_SaveThread, (void)) \
    X(void, PyEval_RestoreThread, (void *)) \
    X(void, PyThreadState_Clear, (void *)) \
    X(void, PyThreadState_DeleteCurrent, (void)) \
    X(PyGILState_STATE, PyGILState_Ensure, (void)) \
    X(void, PyGILState_Release, (PyGILState_STATE)) \
    X(void *, PyGILState_GetThisThreadState, (void)) \
    X(void, Py_DecRef, (PyObject *)) \
    X(PyObject *, PyImport_ImportModule, (const char *)) \
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
    X(PyObject *, PySequence_GetItem, (PyObject *, Py_ssize_t)) \
    X(int, PySequence_DelSlice, (PyObject *, Py_ssize_t, Py_ssize_t)) \
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
static struct {
    PYTHON_API(DECLARE)
    int (*IsFinalizing)(void);  /* Py_IsFinalizing (3.13) or _Py_IsFinalizing; may be NULL */
    PyObject *None, *MemoryError, *SystemExit, *KeyboardInterrupt;
} py;
#undef DECLARE

/* The Python side of the runtime: find the slave class, make a slave. Run once per load of
 * this library into a private namespace. */
static const char HELPER_SOURCE[] =
    "import importlib, sys\n"
    "def _depth(cls):\n"
    "    names = [base.__name__ for base in getattr(cls, '__mro__', ())]\n"
    "    return names.index('Fmi2Slave') if 'Fmi2Slave' in names[1:] else -1\n"
    "def slave_class(resources, module_name):\n"
    "    '''The Fmi2Slave subclass of the slave module (pythonfmu's rule: of the concrete\n"
    "    classes the module defines, the one deepest below Fmi2Slave).'''\n"
    "    if module_name not in sys.modules and resources not in sys.path:\n"
    "        sys.path.insert(0, resources)\n"
    "    module = importlib.import_module(module_name)\n"
    "    members = [m for m in vars(module).values() if isinstance(m, type) and _depth(m) > 0\n"
    "               and not getattr(m, '__abstractmethods__', None)]\n"
    "    own = [m for m in members if m.__module__ == module.__name__] or members\n"
    "    if not own:\n"
    "        raise TypeError(f'module {module_name} ({module.__file__}) defines no concrete '\n"
    "                        'subclass of pythonfmu.Fmi2Slave')\n"
    "    return max(own, key=_depth)\n"
    "def new_slave(cls, instance_name, resources, visible):\n"
    "    return cls(instance_name=instance_name, resources=resources, visible=bool(visible))\n";

/* ---- messages ------------------------------------------------------------------------ */
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

/* Where messages go: the host's logger, with the instance's name and logging settings. */
typedef struct {
    fmi2CallbackFunctions callbacks;
    char *name;
    int logging_on;
    char **categories;  /* NULL: every category */
    size_t category_count;
} Sink;

static int category_enabled(const Sink *sink, const char *category) {
    if (!sink->categories) return 1;
    for (size_t i = 0; i < sink->category_count; i++)
        if (category && strcmp(sink->categories[i], category) == 0) return 1;
    return 0;
}

static const char *const STATUS_CATEGORIES[] = {"logAll", "logStatusWarning",
                                               "logStatusDiscard", "logStatusError",
                                               "logStatusFatal", "logAll"};

/* Pass text to the host's logger as a printf format that prints it as it is: each % as %%,
 * each line break as a space (one message, one line). */
static void log_text(const Sink *sink, fmi2Status status, const char *category,
                     const char *text) {
    if (!sink->callbacks.logger) return;
    if (status < fmi2Error && !(sink->logging_on && category_enabled(sink, category))) return;
    size_t length = strlen(text), percents = 0;
    for (size_t i = 0; i < length; i++) percents += text[i] == '%';
    char *escaped = malloc(length + percents + 1);
    if (!escaped) return;
    char *out = escaped;
    for (size_t i = 0; i < length; i++) {
        char ch = text[i];
        if (ch == '%') *out++ = '%';
        *out++ = (ch == '\n' || ch == '\r') ? ' ' : ch;
    }
    *out = '\0';
    sink->callbacks.logger(sink->callbacks.componentEnvironment, sink->name, status,
                           category ? category : STATUS_CATEGORIES[status], escaped);
    free(escaped);
}

static void log_format(const Sink *sink, fmi2Status status, const char *format, ...) {
    Message m = {{0}, 0};
    va_list args;
    va_start(args, format);
    vsnprintf(m.text, sizeof m.text, format, args);
    va_end(args);
    log_text(sink, status, NULL, m.text);
}

/* ---- loading ------------------------------------------------------------------------- */
static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int loaded;                   /* py resolved, Python running, helper made */
static Message load_failure;         /* why loading failed for good (Python did not start) */
static PyObject *helper_slave_class, *helper_new_slave;
static pthread_key_t thread_key;     /* the Python thread state this runtime gave a thread */
static int thread_key_made;
static __thread int thread_state_held;

static struct {
    int read;
    char libpython[PATH_SIZE], prefix[PATH_SIZE], guid[256];
} record;

static int regular_file(const char *path) {
    struct stat info;
    return stat(path, &info) == 0 && S_ISREG(info.st_mode);
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

/* resources/python.txt beside this library, read once: libpython, prefix and guid. */
static void read_record(void) {
    if (record.read) return;
    record.read = 1;
    char folder[PATH_SIZE], path[PATH_SIZE + 64], line[PATH_SIZE];
    if (!own_folder(folder, sizeof folder)) return;
    snprintf(path, sizeof path, "%s/../../resources/" RECORD_FILE, folder);
    if (!regular_file(path)) return;
    FILE *file = fopen(path, "r");
    if (!file) return;
    while (fgets(line, sizeof line, file)) {
        line[strcspn(line, "\r\n")] = '\0';
        char *value = strchr(line, '=');
        if (!value) continue;
        *value++ = '\0';
        if (strcmp(line, "libpython") == 0)
            snprintf(record.libpython, sizeof record.libpython, "%s", value);
        else if (strcmp(line, "prefix") == 0)
            snprintf(record.prefix, sizeof record.prefix, "%s", value);
        else if (strcmp(line, "guid") == 0)
            snprintf(record.guid, sizeof record.guid, "%s", value);
    }
    fclose(file);
}

/* A Python host, or a libpython loaded before (by this FMU or another). */
static int python_in_process(void) { return dlsym(RTLD_DEFAULT, "Py_IsInitialized") != NULL; }

/* dlopen a libpython (RTLD_GLOBAL), a regular file or a soname, and check it is CPython 3.8
 * or later; on failure add why to the message and return 0. */
static int open_libpython(const char *path, Message *why) {
    if (strchr(path, '/') && !regular_file(path)) {
        struct stat info;
        append(why, "\n  %s: %s", path, stat(path, &info) != 0 ? "no such file"
                                          : "not a regular file (not opened)");
        return 0;
    }
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

/* What PYTHONHOME is for a Python this runtime starts, for messages. */
static char home_note[PATH_SIZE + 128];
static int host_python;  /* Python was in the process before this runtime looked */

/* Load libpython as the header comment says; 0 with the paths tried in why on failure. */
static int load_libpython(Message *why) {
    if (python_in_process()) {
        host_python = 1;
        return 1;
    }
    const char *override = getenv(OVERRIDE_VARIABLE);
    const char *home = getenv("PYTHONHOME");
    if (home) snprintf(home_note, sizeof home_note, "PYTHONHOME=%s (from the environment)", home);
    else snprintf(home_note, sizeof home_note, "PYTHONHOME unset");
    if (override && override[0]) {
        append(why, "no Python for this FMU; tried %s=%s:", OVERRIDE_VARIABLE, override);
        return open_libpython(override, why);
    }
    append(why, "no Python for this FMU; tried (%s unset):", OVERRIDE_VARIABLE);
    if (record.libpython[0]) {
        if (open_libpython(record.libpython, why)) {
            if (!home && record.prefix[0] && is_directory(record.prefix)) {
                setenv("PYTHONHOME", record.prefix, 0);
                snprintf(home_note, sizeof home_note,
                         "PYTHONHOME=%s (the prefix recorded at build time)", record.prefix);
            }
            return 1;
        }
    } else {
        append(why, "\n  resources/" RECORD_FILE ": no libpython recorded");
    }
    for (size_t i = 0; i < sizeof FALLBACK_SONAMES / sizeof *FALLBACK_SONAMES; i++)
        if (open_libpython(FALLBACK_SONAMES[i], why)) return 1;
    return 0;
}

static int resolve_python_api(Message *why) {
#define RESOLVE(result, name, arguments) \
    if (!(*(void **)&py.name = dlsym(RTLD_DEFAULT, #name))) { \
        append(why, "the Python C API function " #name " is not in this process"); return 0; }
    PYTHON_API(RESOLVE)
#undef RESOLVE
    *(void **)&py.IsFinalizing = dlsym(RTLD_DEFAULT, "Py_IsFinalizing");
    if (!py.IsFinalizing) *(void **)&py.IsFinalizing = dlsym(RTLD_DEFAULT, "_Py_IsFinalizing");
    py.None = (PyObject *)dlsym(RTLD_DEFAULT, "_Py_NoneStruct");
    PyObject **memory = dlsym(RTLD_DEFAULT, "PyExc_MemoryError");
    PyObject **exit = dlsym(RTLD_DEFAULT, "PyExc_SystemExit");
    PyObject **interrupt = dlsym(RTLD_DEFAULT, "PyExc_KeyboardInterrupt");
    if (!py.None || !memory || !exit || !interrupt) {
        append(why, "the Python C API's None and exception types are not in this process");
        return 0;
    }
    py.MemoryError = *memory;
    py.SystemExit = *exit;
    py.KeyboardInterrupt = *interrupt;
    return 1;
}

/* Python can be entered: running and not shutting down. */
static int python_usable(void) {
    return loaded && py.Py_IsInitialized() && !(py.IsFinalizing && py.IsFinalizing());
}

static int failed_status(PyStatus status, const char *step, Message *why) {
    if (!py.PyStatus_Exception(status)) return 0;
    append(why, "Python %.20s did not start (%s%s%s) with %s. Point PYTHONHOME at the "
                "installation prefix of that Python (the folder that holds lib/python3.X), "
                "or unset it.", py.Py_GetVersion(), step,
           status.func ? ": " : "", status.err_msg ? status.err_msg : "", home_note);
    return 1;
}

/* Start an interpreter if there is none: the PyConfig API, which reports a failure instead of
 * ending the process. Its configuration is Python's usual one (PYTHONHOME, PYTHONPATH read
 * from the environment), less the C locale coercion (which would set LC_CTYPE in the host's
 * environment) and the signal handlers (the host keeps SIGINT). */
static int start_python_now(Message *why) {
    if (py.Py_IsInitialized()) return 1;
    int pre[64] = {0};  /* a PyPreConfig: ints only, fewer than 16 in any CPython */
    py.PyPreConfig_InitPythonConfig(pre);
    if (pre[0] == PY_CONFIG_INIT_PYTHON) pre[5] = pre[6] = 0;  /* coerce_c_locale(_warn) */
    if (failed_status(py.Py_PreInitialize(pre), "pre-initialisation", why)) return 0;
    int *config = calloc(1, CONFIG_SIZE);
    if (!config) {
        append(why, "out of memory");
        return 0;
    }
    py.PyConfig_InitPythonConfig(config);
    if (config[0] == PY_CONFIG_INIT_PYTHON && config[4] == 1)
        config[4] = 0;  /* install_signal_handlers, the fifth int in every CPython 3.8+ */
    PyStatus status = py.Py_InitializeFromConfig(config);
    py.PyConfig_Clear(config);
    free(config);
    if (failed_status(status, "initialisation", why)) return 0;
    py.PyEval_SaveThread();  /* the GIL is taken per call */
    return 1;
}

/* A lock held by one thread of this process at a time, whichever copy of this runtime takes
 * it: an abstract Unix socket named after the process id, which only one socket can be bound
 * to. (Each FMU has its own copy of the runtime, so no static of it is common ground; a file
 * lock would be common to every process on the machine.) -1 if there is none to be had. */
static int lock_process(void) {
    struct sockaddr_un address;
    memset(&address, 0, sizeof address);
    address.sun_family = AF_UNIX;  /* sun_path[0] = '\0': the abstract namespace */
    int n = snprintf(address.sun_path + 1, sizeof address.sun_path - 1,
                     "gravity-balancer-fmu-python-start-%ld", (long)getpid());
    socklen_t length = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + 1 + (size_t)n);
    const struct timespec pause = {0, 1000000};  /* 1 ms */
    for (;;) {
        int lock = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (lock < 0) return -1;
        if (bind(lock, (struct sockaddr *)&address, length) == 0) return lock;
        int error = errno;
        close(lock);
        if (error != EADDRINUSE) return -1;
        nanosleep(&pause, NULL);  /* another FMU of this process is starting Python */
    }
}

/* start_python_now, one FMU at a time: two host threads may instantiate two FMUs at once. */
static int start_python(Message *why) {
    if (py.Py_IsInitialized()) return 1;
    int lock = lock_process();
    int started = start_python_now(why);
    if (lock >= 0) close(lock);  /* and the lock with it */
    return started;
}

/* At the end of a host thread given a Python thread state by this runtime: delete it. By
 * now the thread's PyGILState entry may be gone (thread-specific values are cleared in key
 * order), so the state is the key's own value. */
static void release_thread_state(void *thread_state) {
    if (!python_usable()) return;
    py.PyEval_RestoreThread(thread_state);  /* the GIL taken, the state current */
    py.PyThreadState_Clear(thread_state);
    py.PyThreadState_DeleteCurrent();       /* and the GIL released */
}

/* Give the calling thread a Python thread state for its lifetime if it has none, so that the
 * PyGILState_Ensure/Release of each call only take and give back the GIL. */
static void hold_thread_state(void) {
    if (thread_state_held) return;
    thread_state_held = 1;
    if (py.PyGILState_GetThisThreadState() == NULL) {
        py.PyGILState_Ensure();
        void *thread_state = py.PyEval_SaveThread();
        if (thread_key_made) pthread_setspecific(thread_key, thread_state);
    }
}

static int make_helper(Message *why) {
    PyGILState_STATE gil = py.PyGILState_Ensure();
    PyObject *namespace = py.PyDict_New(), *builtins = py.PyImport_ImportModule("builtins");
    PyObject *result = NULL;
    if (namespace && builtins && py.PyDict_SetItemString(namespace, "__builtins__", builtins) == 0)
        result = py.PyRun_StringFlags(HELPER_SOURCE, PY_FILE_INPUT, namespace, namespace, NULL);
    if (result) {
        /* borrowed from the namespace, which is kept (never released: see the header) */
        helper_slave_class = py.PyDict_GetItemString(namespace, "slave_class");
        helper_new_slave = py.PyDict_GetItemString(namespace, "new_slave");
        py.Py_DecRef(result);
    } else {
        py.PyErr_Clear();
        if (namespace) py.Py_DecRef(namespace);
        namespace = NULL;
    }
    if (builtins) py.Py_DecRef(builtins);
    py.PyGILState_Release(gil);
    if (!namespace || !helper_slave_class || !helper_new_slave) {
        append(why, "the runtime's Python helper did not compile");
        return 0;
    }
    return 1;
}

/* Make loaded true, or write why not. */
static int load(Message *why) {
    pthread_mutex_lock(&load_lock);
    if (!loaded && !load_failure.length) {
        Message attempt = {{0}, 0};
        if (!load_libpython(&attempt))
            append(&attempt, "\nThis FMU runs its model in CPython 3.8 or later: set %s to the "
                             "path of a libpython3.X.so.1.0 shared library.", OVERRIDE_VARIABLE);
        else if (resolve_python_api(&attempt) && start_python(&attempt)) {
            loaded = 1;
            if (!make_helper(&attempt)) loaded = 0;
            else thread_key_made = pthread_key_create(&thread_key, release_thread_state) == 0;
        }
        /* a Python that did not start cannot be started again in this process */
        if (!loaded && py.Py_IsInitialized) load_failure = attempt;
        if (!loaded) *why = attempt;
    } else if (!loaded) {
        *why = load_failure;
    }
    int ok = loaded;
    pthread_mutex_unlock(&load_lock);
    return ok;
}

/* A thread-exit destructor must not run once this library is unloaded. */
__attribute__((destructor)) static void unload(void) {
    if (thread_key_made) pthread_key_delete(thread_key);
}

/* ---- resource location ---------------------------------------------------------------- */
static int hex_digit(char ch) {
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

/* The folder a resource location names (RFC 8089 file URI: file:///p, file:/p,
 * file://localhost/p, percent-encoded UTF-8; a plain absolute path is taken as it is), without
 * a trailing slash, or NULL with why. */
static char *resource_folder(const char *uri, Message *why) {
    const char *path = uri;
    if (strncasecmp(uri, "file:", 5) == 0) {
        path = uri + 5;
        if (path[0] == '/' && path[1] == '/') {
            const char *host = path + 2, *end = strchr(host, '/');
            size_t length = end ? (size_t)(end - host) : strlen(host);
            if (length && !(length == 9 && strncasecmp(host, "localhost", 9) == 0)) {
                append(why, "resource location %s names the host %.*s: only local files can be "
                            "read", uri, (int)length, host);
                return NULL;
            }
            path = end ? end : "";
        }
    }
    if (path[0] != '/') {
        append(why, "resource location \"%s\" is not a file URI of an absolute path "
                    "(file:///path/to/resources)", uri);
        return NULL;
    }
    size_t end = strcspn(path, "?#");  /* a query or fragment is no part of the path */
    char *folder = malloc(end + 1);
    if (!folder) {
        append(why, "out of memory");
        return NULL;
    }
    size_t n = 0;
    for (size_t i = 0; i < end; i++) {
        int high, low;
        if (path[i] == '%' && i + 2 < end + 1 && (high = hex_digit(path[i + 1])) >= 0 &&
            (low = hex_digit(path[i + 2])) >= 0) {
            folder[n++] = (char)(high * 16 + low);
            i += 2;
        } else {
            folder[n++] = path[i];  /* a % not followed by two hex digits is a plain % */
        }
    }
    folder[n] = '\0';
    if (strlen(folder) != n) {
        append(why, "resource location %s encodes a NUL byte", uri);
        free(folder);
        return NULL;
    }
    while (n > 1 && folder[n - 1] == '/') folder[--n] = '\0';
    return folder;
}

/* The slave module's name from <folder>/slavemodule.txt, or NULL with why. */
static char *slave_module(const char *folder, const char *uri, Message *why) {
    char path[PATH_SIZE + 32], line[256];
    if (!is_directory(folder)) {
        append(why, "resource location %s: %s is not a folder", uri, folder);
        return NULL;
    }
    snprintf(path, sizeof path, "%s/" SLAVE_MODULE_FILE, folder);
    FILE *file = regular_file(path) ? fopen(path, "r") : NULL;
    if (!file) {
        append(why, "resource location %s: %s has no " SLAVE_MODULE_FILE " (it is not the "
                    "resources folder of this FMU)", uri, folder);
        return NULL;
    }
    char *name = fgets(line, sizeof line, file) ? line : NULL;
    fclose(file);
    if (name) name[strcspn(name, " \t\r\n")] = '\0';
    if (!name || !name[0] || strchr(name, '/')) {
        append(why, "%s names no Python module", path);
        return NULL;
    }
    return strdup(name);
}

/* ---- instances ------------------------------------------------------------------------ */
enum Method {
    DO_STEP, GET_REAL, SET_REAL, GET_INTEGER, SET_INTEGER, GET_BOOLEAN, SET_BOOLEAN,
    GET_STRING, SET_STRING, SETUP_EXPERIMENT, ENTER_INITIALIZATION_MODE,
    EXIT_INITIALIZATION_MODE, TERMINATE, GET_FMU_STATE, SET_FMU_STATE, STATE_TO_BYTES,
    STATE_FROM_BYTES, METHOD_COUNT
};
static const char *const METHOD_NAMES[METHOD_COUNT] = {
    "do_step", "get_real", "set_real", "get_integer", "set_integer", "get_boolean",
    "set_boolean", "get_string", "set_string", "setup_experiment", "enter_initialization_mode",
    "exit_initialization_mode", "terminate", "_get_fmu_state", "_set_fmu_state",
    "_fmu_state_to_bytes", "_fmu_state_from_bytes"};

/* Model Exchange's calls of the slave, looked up for a Model Exchange instance only */
enum ModelExchangeMethod {
    ME_SET_TIME, ME_SET_CONTINUOUS_STATES, ME_GET_CONTINUOUS_STATES, ME_GET_NOMINALS,
    ME_GET_DERIVATIVES, ME_GET_EVENT_INDICATORS, ME_ENTER_EVENT_MODE, ME_NEW_DISCRETE_STATES,
    ME_ENTER_CONTINUOUS_TIME_MODE, ME_COMPLETED_INTEGRATOR_STEP, ME_METHOD_COUNT
};
static const char *const ME_METHOD_NAMES[ME_METHOD_COUNT] = {
    "me_set_time", "me_set_continuous_states", "me_get_continuous_states", "me_get_nominals",
    "me_get_derivatives", "me_get_event_indicators", "me_enter_event_mode",
    "me_new_discrete_states", "me_enter_continuous_time_mode", "me_completed_integrator_step"};

/* STEPPING is Co-Simulation's slaveInitialized; EVENT_MODE and CONTINUOUS_TIME_MODE are
 * Model Exchange's */
enum Phase {
    INSTANTIATED, INITIALIZATION_MODE, STEPPING, TERMINATED, EVENT_MODE, CONTINUOUS_TIME_MODE,
    PHASE_COUNT
};
static const char *const PHASE_NAMES[PHASE_COUNT] = {
    "Instantiated", "Initialization Mode", "slaveInitialized", "Terminated", "Event Mode",
    "Continuous-Time Mode"};

#define INSTANCE_TAG 0x464d5532u  /* "FMU2" */
#define STATE_TAG 0x53544154u     /* "STAT" */

typedef struct {
    unsigned tag;
    Sink sink;
    char *guid, *resources, *module;
    int visible, fatal;
    fmi2Type type;     /* the interface it was instantiated for */
    enum Phase phase;
    double last_successful_time;
    PyObject *cls, *slave, *queue;
    PyObject *methods[METHOD_COUNT];
    PyObject *me_methods[ME_METHOD_COUNT];  /* a Model Exchange instance's */
    size_t state_count, indicator_count;     /* its nx and ni */
    PyObject **strings;  /* the UTF-8 bytes behind the last fmi2GetString's values */
    size_t string_count;
    char *failure;       /* the message of the current call's Python exception */
} Instance;

typedef struct {
    unsigned tag;
    char *guid;        /* of the FMU that made it */
    PyObject *state;   /* the slave's state object */
} State;

static void release(PyObject **object) {
    if (*object) py.Py_DecRef(*object);
    *object = NULL;
}

static void release_strings(Instance *in) {
    for (size_t i = 0; i < in->string_count; i++) release(&in->strings[i]);
    free(in->strings);
    in->strings = NULL;
    in->string_count = 0;
}

static void release_slave(Instance *in) {
    for (int i = 0; i < METHOD_COUNT; i++) release(&in->methods[i]);
    for (int i = 0; i < ME_METHOD_COUNT; i++) release(&in->me_methods[i]);
    release(&in->queue);
    release(&in->slave);
    release_strings(in);
}

/* UTF-8 of a Python object's str(), into buffer (never fails: "?" instead). */
static void text_of(PyObject *object, char *buffer, size_t size) {
    PyObject *text = object ? py.PyObject_Str(object) : NULL;
    const char *utf8 = text ? py.PyUnicode_AsUTF8AndSize(text, NULL) : NULL;
    snprintf(buffer, size, "%s", utf8 ? utf8 : "?");
    if (!utf8) py.PyErr_Clear();
    if (text) py.Py_DecRef(text);
}

/* The status of the pending Python exception, taken: fmi2Error (fmi2Fatal for MemoryError and
 * SystemExit), its message "<function>: <type>: <message>" kept for the caller to log. */
static fmi2Status python_failure(Instance *in, const char *function) {
    PyObject *type = NULL, *value = NULL, *trace = NULL;
    py.PyErr_Fetch(&type, &value, &trace);
    fmi2Status status = fmi2Error;
    char name[256] = "unknown error", text[MESSAGE_SIZE / 2] = "";
    if (type) {
        py.PyErr_NormalizeException(&type, &value, &trace);
        if (py.PyErr_GivenExceptionMatches(type, py.MemoryError) ||
            py.PyErr_GivenExceptionMatches(type, py.SystemExit)) status = fmi2Fatal;
        PyObject *type_name = py.PyObject_GetAttrString(type, "__name__");
        if (!type_name) py.PyErr_Clear();
        text_of(type_name, name, sizeof name);
        if (type_name) py.Py_DecRef(type_name);
        text_of(value, text, sizeof text);
        /* a Ctrl-C in a Python host: its interpreter gets it back after this call */
        if (host_python && py.PyErr_GivenExceptionMatches(type, py.KeyboardInterrupt))
            py.PyErr_SetInterrupt();
    }
    release(&type);
    release(&value);
    release(&trace);
    Message m = {{0}, 0};
    append(&m, "%s: %s%s%s", function, name, text[0] ? ": " : "", text);
    free(in->failure);
    in->failure = strdup(m.text);
    return status;
}

/* Pass the slave's queued log messages on and empty its queue (the GIL held). */
static void drain_log(Instance *in) {
    Py_ssize_t count = in->queue ? py.PySequence_Size(in->queue) : 0;
    if (count <= 0) {
        if (count < 0) py.PyErr_Clear();
        return;
    }
    for (Py_ssize_t i = 0; i < count; i++) {
        PyObject *message = py.PySequence_GetItem(in->queue, i);
        PyObject *status = message ? py.PyObject_GetAttrString(message, "status") : NULL;
        PyObject *category = message ? py.PyObject_GetAttrString(message, "category") : NULL;
        PyObject *msg = message ? py.PyObject_GetAttrString(message, "msg") : NULL;
        long level = status ? py.PyLong_AsLong(status) : fmi2OK;
        if (level < fmi2OK || level > fmi2Fatal) level = fmi2OK;
        py.PyErr_Clear();
        char category_text[256], text[MESSAGE_SIZE];
        int has_category = category && category != py.None;
        if (has_category) text_of(category, category_text, sizeof category_text);
        text_of(msg, text, sizeof text);
        log_text(&in->sink, (fmi2Status)level, has_category ? category_text : NULL, text);
        release(&msg);
        release(&category);
        release(&status);
        release(&message);
    }
    if (py.PySequence_DelSlice(in->queue, 0, count) != 0) py.PyErr_Clear();
}

/* Look the slave's Model Exchange methods and its numbers of continuous states and event
 * indicators up (me_state_count, me_indicator_count); 0 after logging why not (a slave of
 * Co-Simulation only). */
static int model_exchange_methods(Instance *in) {
    const char *missing = NULL;
    for (int i = 0; !missing && i < ME_METHOD_COUNT; i++)
        if (!(in->me_methods[i] = py.PyObject_GetAttrString(in->slave, ME_METHOD_NAMES[i])))
            missing = ME_METHOD_NAMES[i];
    const char *const counts[2] = {"me_state_count", "me_indicator_count"};
    size_t *const values[2] = {&in->state_count, &in->indicator_count};
    for (int i = 0; !missing && i < 2; i++) {
        PyObject *count = py.PyObject_GetAttrString(in->slave, counts[i]);
        long value = count ? py.PyLong_AsLong(count) : -1;
        release(&count);
        if (value < 0) missing = counts[i];
        else *values[i] = (size_t)value;
    }
    if (!missing) return 1;
    py.PyErr_Clear();
    log_format(&in->sink, fmi2Error, "fmi2Instantiate: this FMU's slave implements FMI 2.0 "
               "Co-Simulation only (it has no %s); fmuType fmi2ModelExchange refused", missing);
    drain_log(in);
    return 0;
}

/* Make the instance's slave (and look its methods up once); 0 after logging why. */
static int create_slave(Instance *in) {
    PyObject *name = py.PyUnicode_FromString(in->sink.name);
    PyObject *resources = py.PyUnicode_DecodeFSDefault(in->resources);
    PyObject *module = py.PyUnicode_FromString(in->module);
    PyObject *visible = py.PyBool_FromLong(in->visible);
    if (!in->cls && name && resources && module)
        in->cls = py.PyObject_CallFunctionObjArgs(helper_slave_class, resources, module, NULL);
    if (in->cls && visible)
        in->slave = py.PyObject_CallFunctionObjArgs(helper_new_slave, in->cls, name, resources,
                                                    visible, NULL);
    for (int i = 0; in->slave && i < METHOD_COUNT; i++)
        if (!(in->methods[i] = py.PyObject_GetAttrString(in->slave, METHOD_NAMES[i]))) break;
    PyObject *queue_getter = in->slave && in->methods[METHOD_COUNT - 1]
                                 ? py.PyObject_GetAttrString(in->slave, "_get_log_queue") : NULL;
    if (queue_getter) in->queue = py.PyObject_CallFunctionObjArgs(queue_getter, NULL);
    release(&queue_getter);
    if (in->queue && in->type == fmi2ModelExchange && !model_exchange_methods(in)) {
        release_slave(in);
        release(&name);
        release(&resources);
        release(&module);
        release(&visible);
        return 0;
    }
    release(&name);
    release(&resources);
    release(&module);
    release(&visible);
    if (in->queue) return 1;
    fmi2Status status = python_failure(in, in->slave ? "fmi2Instantiate (the slave's methods)"
                                                     : "fmi2Instantiate (the slave class)");
    drain_log(in);
    log_text(&in->sink, status > fmi2Error ? status : fmi2Fatal, NULL, in->failure);
    free(in->failure);  /* logged */
    in->failure = NULL;
    release_slave(in);
    return 0;
}

static void free_instance(Instance *in) {
    if (python_usable() && (in->slave || in->cls || in->strings)) {
        PyGILState_STATE gil = py.PyGILState_Ensure();
        release_slave(in);
        release(&in->cls);
        py.PyGILState_Release(gil);
    }
    for (size_t i = 0; i < in->sink.category_count; i++) free(in->sink.categories[i]);
    free(in->sink.categories);
    free(in->sink.name);
    free(in->guid);
    free(in->resources);
    free(in->module);
    free(in->failure);
    in->tag = 0;
    free(in);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    if (!functions) return NULL;  /* no logger to say why */
    Sink sink = {*functions, (char *)(instanceName ? instanceName : ""), 1, NULL, 0};
    Message why = {{0}, 0};
    pthread_mutex_lock(&load_lock);
    read_record();
    pthread_mutex_unlock(&load_lock);
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
    if (record.guid[0] && strcmp(fmuGUID, record.guid) != 0) {
        log_format(&sink, fmi2Error, "fmi2Instantiate: fmuGUID %s is not this FMU's GUID %s "
                   "(its modelDescription.xml): the binary belongs to another FMU", fmuGUID,
                   record.guid);
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
        in->visible = visible != fmi2False;
        in->type = fmuType;
        in->phase = INSTANTIATED;
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
    hold_thread_state();
    PyGILState_STATE gil = py.PyGILState_Ensure();
    int made = create_slave(in);
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

/* ---- calls ---------------------------------------------------------------------------- */
#define ANY_PHASE ((1u << PHASE_COUNT) - 1u)
#define NOT_TERMINATED (ANY_PHASE & ~(1u << TERMINATED))

/* Check an instance may take the call: not after fmi2Fatal, in a phase that allows it. */
static fmi2Status admit(Instance *in, const char *function, unsigned phases) {
    if (!in || in->tag != INSTANCE_TAG) return fmi2Error;
    if (in->fatal) {
        log_format(&in->sink, fmi2Fatal, "%s refused: an earlier call on this instance "
                   "returned fmi2Fatal", function);
        return fmi2Fatal;
    }
    if (!(phases & (1u << in->phase))) {
        if (in->phase == TERMINATED)
            log_format(&in->sink, fmi2Error, "%s refused: not allowed after fmi2Terminate "
                       "(only fmi2Reset, fmi2FreeInstance and the getters are)", function);
        else
            log_format(&in->sink, fmi2Error, "%s refused: not allowed in %s (FMI 2.0 state "
                       "machine)", function, PHASE_NAMES[in->phase]);
        return fmi2Error;
    }
    return fmi2OK;
}

/* Check an instance may take a call of one interface (fmi2CoSimulation or
 * fmi2ModelExchange) in the phases given: as admit, and refused for an instance of the
 * other interface. */
static fmi2Status admit_type(Instance *in, const char *function, fmi2Type type,
                             unsigned phases) {
    fmi2Status refused = admit(in, function, phases);
    if (refused != fmi2OK) return refused;
    if (in->type != type) {
        log_format(&in->sink, fmi2Error, "%s refused: it is a %s call, and this instance was "
                   "instantiated for %s", function, type == fmi2ModelExchange
                   ? "Model Exchange" : "Co-Simulation", in->type == fmi2ModelExchange
                   ? "Model Exchange" : "Co-Simulation");
        return fmi2Error;
    }
    return fmi2OK;
}

/* Enter Python for a call: the GIL taken (and the failure message of the call cleared). */
#define BEGIN(function, phases) \
    Instance *in = (Instance *)c; \
    const char *const function_name = function; \
    { fmi2Status refused = admit(in, function_name, phases); \
      if (refused != fmi2OK) return refused; } \
    hold_thread_state(); \
    PyGILState_STATE gil = py.PyGILState_Ensure(); \
    fmi2Status status = fmi2OK

/* Leave Python: the slave's messages, then the failure's, passed on; the GIL given back. */
#define END() \
    drain_log(in); \
    if (status >= fmi2Error && in->failure) log_text(&in->sink, status, NULL, in->failure); \
    free(in->failure); \
    in->failure = NULL; \
    py.PyGILState_Release(gil); \
    if (status == fmi2Fatal) in->fatal = 1; \
    return status

/* Call a method; the result (new reference) or NULL with status set from the exception. */
#define CALL(method, ...) \
    py.PyObject_CallFunctionObjArgs(in->methods[method], __VA_ARGS__, NULL)

/* A result that is not the one expected: fmi2Error with a message. */
static fmi2Status wrong_result(Instance *in, const char *function, const char *what) {
    free(in->failure);
    Message m = {{0}, 0};
    append(&m, "%s: the slave's %s", function, what);
    in->failure = strdup(m.text);
    return fmi2Error;
}

static PyObject *reference_list(const fmi2ValueReference vr[], size_t nvr) {
    PyObject *list = py.PyList_New((Py_ssize_t)nvr);
    for (size_t i = 0; list && i < nvr; i++) {
        PyObject *item = py.PyLong_FromLong((long)vr[i]);
        if (!item || py.PyList_SetItem(list, (Py_ssize_t)i, item) != 0) release(&list);
    }
    return list;
}

static fmi2Status no_call(Instance *in, const char *function) {
    log_format(&in->sink, fmi2Error, "%s: not supported by this FMU", function);
    return fmi2Error;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *in = (Instance *)c;
    fmi2Status refused = admit(in, "fmi2SetDebugLogging", ANY_PHASE);
    if (refused != fmi2OK) return refused;
    if (nCategories && !categories) {
        log_format(&in->sink, fmi2Error, "fmi2SetDebugLogging: categories is NULL");
        return fmi2Error;
    }
    for (size_t i = 0; i < in->sink.category_count; i++) free(in->sink.categories[i]);
    free(in->sink.categories);
    in->sink.categories = NULL;
    in->sink.category_count = 0;
    in->sink.logging_on = loggingOn != fmi2False;
    if (nCategories) {
        in->sink.categories = calloc(nCategories, sizeof *in->sink.categories);
        if (!in->sink.categories) return fmi2Error;
        for (size_t i = 0; i < nCategories; i++)
            in->sink.categories[i] = strdup(categories[i] ? categories[i] : "");
        in->sink.category_count = nCategories;
    }
    return fmi2OK;
}

/* Call a method without arguments but self (the life-cycle calls). */
static fmi2Status life_cycle(fmi2Component c, const char *function, enum Method method,
                             unsigned phases, enum Phase next) {
    BEGIN(function, phases);
    PyObject *result = py.PyObject_CallFunctionObjArgs(in->methods[method], NULL);
    if (!result) status = python_failure(in, function_name);
    else {
        release(&result);
        in->phase = next;
    }
    END();
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN("fmi2SetupExperiment", NOT_TERMINATED);
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
    return life_cycle(c, "fmi2EnterInitializationMode", ENTER_INITIALIZATION_MODE,
                      NOT_TERMINATED, INITIALIZATION_MODE);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *in = (Instance *)c;  /* Model Exchange goes on in Event Mode */
    enum Phase next = in && in->tag == INSTANCE_TAG && in->type == fmi2ModelExchange
                          ? EVENT_MODE : STEPPING;
    return life_cycle(c, "fmi2ExitInitializationMode", EXIT_INITIALIZATION_MODE,
                      NOT_TERMINATED, next);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    return life_cycle(c, "fmi2Terminate", TERMINATE, NOT_TERMINATED, TERMINATED);
}

fmi2Status fmi2Reset(fmi2Component c) {
    BEGIN("fmi2Reset", ANY_PHASE);
    release_slave(in);
    if (!create_slave(in)) status = fmi2Fatal;  /* no slave left: logged by create_slave */
    else {
        in->phase = INSTANTIATED;
        in->last_successful_time = 0.0;
    }
    END();
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    { fmi2Status refused = admit_type((Instance *)c, "fmi2DoStep", fmi2CoSimulation,
                                      NOT_TERMINATED);
      if (refused != fmi2OK) return refused; }
    BEGIN("fmi2DoStep", NOT_TERMINATED);
    PyObject *now = py.PyFloat_FromDouble(currentCommunicationPoint);
    PyObject *step = py.PyFloat_FromDouble(communicationStepSize);
    PyObject *result = now && step ? CALL(DO_STEP, now, step) : NULL;
    int taken = result ? py.PyObject_IsTrue(result) : -1;
    if (taken < 0) status = python_failure(in, function_name);
    else if (taken) in->last_successful_time = currentCommunicationPoint + communicationStepSize;
    else status = fmi2Discard;  /* refused by the slave, which logged why */
    release(&result);
    release(&now);
    release(&step);
    END();
}

/* The getters: call the method with the value references, convert each item of its result. */
#define GETTER(Type, fmiType, method, convert) \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                             fmiType value[]) { \
        if (nvr == 0) return admit((Instance *)c, "fmi2Get" #Type, ANY_PHASE); \
        BEGIN("fmi2Get" #Type, ANY_PHASE); \
        if (!vr || !value) { \
            status = wrong_result(in, function_name, "arguments: NULL arrays"); \
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

GETTER(Real, fmi2Real, GET_REAL, value[i] = py.PyFloat_AsDouble(item))
GETTER(Boolean, fmi2Boolean, GET_BOOLEAN,
       { int truth = py.PyObject_IsTrue(item); value[i] = truth > 0 ? fmi2True : fmi2False; })
GETTER(Integer, fmi2Integer, GET_INTEGER, {
    long number = py.PyLong_AsLong(item);
    if (number < INT32_MIN || number > INT32_MAX) {
        status = wrong_result(in, function_name, "get_integer value is beyond 32 bits");
    } else value[i] = (fmi2Integer)number;
})

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    if (nvr == 0) return admit((Instance *)c, "fmi2GetString", ANY_PHASE);
    BEGIN("fmi2GetString", ANY_PHASE);
    PyObject *refs = vr && value ? reference_list(vr, nvr) : NULL;
    PyObject *result = refs ? CALL(GET_STRING, refs) : NULL;
    release(&refs);
    release_strings(in);
    if (!vr || !value) status = wrong_result(in, function_name, "arguments: NULL arrays");
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
#define SETTER(Type, fmiType, method, phases, convert) \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                             const fmiType value[]) { \
        if (nvr == 0) return admit((Instance *)c, "fmi2Set" #Type, phases); \
        BEGIN("fmi2Set" #Type, phases); \
        PyObject *refs = vr && value ? reference_list(vr, nvr) : NULL; \
        PyObject *values = refs ? py.PyList_New((Py_ssize_t)nvr) : NULL; \
        for (size_t i = 0; values && i < nvr; i++) { \
            PyObject *item = convert; \
            if (!item || py.PyList_SetItem(values, (Py_ssize_t)i, item) != 0) release(&values); \
        } \
        PyObject *result = values ? CALL(method, refs, values) : NULL; \
        if (!vr || !value) status = wrong_result(in, function_name, "arguments: NULL arrays"); \
        else if (!result) status = python_failure(in, function_name); \
        release(&result); \
        release(&values); \
        release(&refs); \
        END(); \
    }

/* In Continuous-Time Mode the slave refuses a discrete input set to another value (FMI 2.0
 * allows no discrete variable to be set there; FMPy's CVode sets every input again, to the
 * same value, in its root function, so the same value is let through) */
SETTER(Real, fmi2Real, SET_REAL, NOT_TERMINATED, py.PyFloat_FromDouble(value[i]))
SETTER(Integer, fmi2Integer, SET_INTEGER, NOT_TERMINATED, py.PyLong_FromLong(value[i]))
SETTER(Boolean, fmi2Boolean, SET_BOOLEAN, NOT_TERMINATED,
       py.PyBool_FromLong(value[i] != fmi2False))
SETTER(String, fmi2String, SET_STRING, NOT_TERMINATED,
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
    BEGIN("fmi2GetFMUstate", ANY_PHASE);
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
        release(&s->state);
        s->state = result;  /* owned by the state now */
        result = NULL;
        *state = s;
    }
    release(&result);
    END();
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    BEGIN("fmi2SetFMUstate", ANY_PHASE);
    State *s = state_of(in, state, function_name);
    PyObject *result = s ? CALL(SET_FMU_STATE, s->state) : NULL;
    if (!s) status = fmi2Error;
    else if (!result) status = python_failure(in, function_name);
    release(&result);
    END();
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    if (!state || !*state) return admit((Instance *)c, "fmi2FreeFMUstate", ANY_PHASE);
    BEGIN("fmi2FreeFMUstate", ANY_PHASE);
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

/* The serialised state: STATE_HEADER, the GUID, a line break, then the slave's bytes. A new
 * reference to the slave's bytes, or NULL with status set. */
static PyObject *state_bytes(Instance *in, fmi2FMUstate state, const char *function,
                             fmi2Status *status) {
    State *s = state_of(in, state, function);
    PyObject *bytes = s ? CALL(STATE_TO_BYTES, s->state) : NULL;
    char *data;
    if (!s) *status = fmi2Error;
    else if (!bytes || py.PyBytes_AsStringAndSize(bytes, &data, NULL) != 0) {
        *status = python_failure(in, function);
        release(&bytes);
    }
    return bytes;
}

static size_t header_size(const Instance *in) {
    return strlen(STATE_HEADER) + strlen(in->guid) + 1;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    BEGIN("fmi2SerializedFMUstateSize", ANY_PHASE);
    PyObject *bytes = size ? state_bytes(in, state, function_name, &status) : NULL;
    char *data;
    Py_ssize_t length;
    if (!size) status = wrong_result(in, function_name, "argument: size is NULL");
    else if (bytes && py.PyBytes_AsStringAndSize(bytes, &data, &length) == 0)
        *size = header_size(in) + (size_t)length;
    release(&bytes);
    END();
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serialized[],
                                 size_t size) {
    BEGIN("fmi2SerializeFMUstate", ANY_PHASE);
    PyObject *bytes = serialized ? state_bytes(in, state, function_name, &status) : NULL;
    char *data;
    Py_ssize_t length;
    if (!serialized) status = wrong_result(in, function_name, "argument: the array is NULL");
    else if (bytes && py.PyBytes_AsStringAndSize(bytes, &data, &length) == 0) {
        size_t header = header_size(in);
        if (size < header + (size_t)length) {
            status = wrong_result(in, function_name,
                                  "state needs more bytes than given (fmi2SerializedFMUstateSize)");
        } else {
            snprintf(serialized, header + 1, STATE_HEADER "%s\n", in->guid);
            memcpy(serialized + header, data, (size_t)length);
        }
    }
    release(&bytes);
    END();
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serialized[], size_t size,
                                   fmi2FMUstate *state) {
    BEGIN("fmi2DeSerializeFMUstate", ANY_PHASE);
    size_t header = header_size(in), prefix = strlen(STATE_HEADER);
    State *s = NULL;
    if (!serialized || !state) {
        status = wrong_result(in, function_name, "arguments: NULL");
    } else if (size < header || memcmp(serialized, STATE_HEADER, prefix) != 0 ||
               serialized[header - 1] != '\n' ||
               memcmp(serialized + prefix, in->guid, header - prefix - 1) != 0) {
        const char *end = size >= prefix ? memchr(serialized + prefix, '\n', size - prefix)
                                         : NULL;
        Message m = {{0}, 0};
        if (size >= prefix && memcmp(serialized, STATE_HEADER, prefix) == 0 && end)
            append(&m, "%s: the bytes are a state of another FMU (GUID %.*s, this one %s)",
                   function_name, (int)(end - serialized - prefix), serialized + prefix,
                   in->guid);
        else
            append(&m, "%s: the bytes are not a serialised FMU state of this runtime",
                   function_name);
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
    fmi2Status refused = admit((Instance *)c, "fmi2GetDirectionalDerivative", ANY_PHASE);
    return refused != fmi2OK ? refused : no_call((Instance *)c, "fmi2GetDirectionalDerivative");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    fmi2Status refused = admit_type((Instance *)c, "fmi2SetRealInputDerivatives",
                                    fmi2CoSimulation, ANY_PHASE);
    return refused != fmi2OK ? refused : no_call((Instance *)c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    fmi2Status refused = admit_type((Instance *)c, "fmi2GetRealOutputDerivatives",
                                    fmi2CoSimulation, ANY_PHASE);
    return refused != fmi2OK ? refused
                             : no_call((Instance *)c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    fmi2Status refused = admit_type((Instance *)c, "fmi2CancelStep", fmi2CoSimulation,
                                    ANY_PHASE);
    return refused != fmi2OK ? refused : no_call((Instance *)c, "fmi2CancelStep");
}

/* Steps are synchronous: no step is ever pending. */
static fmi2Status no_status(Instance *in, const char *function, fmi2StatusKind kind) {
    log_format(&in->sink, fmi2Discard, "%s: status kind %d is not provided (steps are "
               "synchronous)", function, (int)kind);
    return fmi2Discard;
}

/* The inquiries this FMU does not answer: every kind of a type. */
#define NO_STATUS(Type, fmiType) \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2StatusKind s, fmiType *value) { \
        (void)value; \
        fmi2Status refused = admit_type((Instance *)c, "fmi2Get" #Type, fmi2CoSimulation, \
                                        ANY_PHASE); \
        return refused != fmi2OK ? refused : no_status((Instance *)c, "fmi2Get" #Type, s); \
    }

NO_STATUS(Status, fmi2Status)
NO_STATUS(IntegerStatus, fmi2Integer)
NO_STATUS(StringStatus, fmi2String)

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    fmi2Status refused = admit_type((Instance *)c, "fmi2GetRealStatus", fmi2CoSimulation,
                                    ANY_PHASE);
    if (refused != fmi2OK) return refused;
    if (s != fmi2LastSuccessfulTime || !value)
        return no_status((Instance *)c, "fmi2GetRealStatus", s);
    *value = ((Instance *)c)->last_successful_time;
    return fmi2OK;
}

/* fmi2Terminated is false: a refused step (fmi2Discard) leaves the slave as it was, ready for
 * a shorter step or another input. */
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    fmi2Status refused = admit_type((Instance *)c, "fmi2GetBooleanStatus", fmi2CoSimulation,
                                    ANY_PHASE);
    if (refused != fmi2OK) return refused;
    if (s != fmi2Terminated || !value)
        return no_status((Instance *)c, "fmi2GetBooleanStatus", s);
    *value = fmi2False;
    return fmi2OK;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

/* ==== Model Exchange ========================================================================
 * The FMI 2.0 Model Exchange calls over the slave's me_ methods (fmu_src/fmi/model_exchange.py),
 * for an instance made with fmuType fmi2ModelExchange. The phases they are allowed in follow
 * the standard's state machine (FMI 2.0.4, section 3.2.3); fmi2ExitInitializationMode leads to
 * Event Mode, fmi2EnterEventMode from Event or Continuous-Time Mode to Event Mode, and
 * fmi2EnterContinuousTimeMode from Event Mode to Continuous-Time Mode. This section keeps its
 * own phase checks (admit_type) until the runtime's state-machine table covers Model Exchange.
 * The runtime never reads or writes past the model's nx or ni (me_state_count,
 * me_indicator_count): a host's other count is refused before its array is touched. */

#define EVENT_OR_CONTINUOUS ((1u << EVENT_MODE) | (1u << CONTINUOUS_TIME_MODE))
/* fmi2GetContinuousStates, fmi2GetDerivatives, fmi2GetEventIndicators */
#define MODEL_INQUIRY ((1u << INITIALIZATION_MODE) | EVENT_OR_CONTINUOUS | (1u << TERMINATED))

/* Enter Python for a Model Exchange call (BEGIN, refused for a Co-Simulation instance). */
#define BEGIN_ME(function, phases) \
    { fmi2Status refused = admit_type((Instance *)c, function, fmi2ModelExchange, phases); \
      if (refused != fmi2OK) return refused; } \
    BEGIN(function, phases)

/* Call a Model Exchange method with the arguments given (or none: CALL_ME(method, NULL)). */
#define CALL_ME(method, ...) \
    py.PyObject_CallFunctionObjArgs(in->me_methods[method], __VA_ARGS__, NULL)

/* fmi2Error with the message "<function>: <what> = <given> is not <the model's count>". */
static fmi2Status wrong_count(Instance *in, const char *function, const char *what,
                              size_t given, size_t count) {
    Message m = {{0}, 0};
    append(&m, "%s: %s = %zu is not this FMU's number of %s, %zu", function, what, given,
           what[0] == 'n' && what[1] == 'x' ? "continuous states" : "event indicators", count);
    free(in->failure);
    in->failure = strdup(m.text);
    return fmi2Error;
}

/* Copy a method's result, a sequence of n numbers, into values (n checked by the caller). */
static fmi2Status take_numbers(Instance *in, const char *function, PyObject *result,
                               fmi2Real values[], size_t n) {
    if (!result) return python_failure(in, function);
    if (py.PySequence_Size(result) != (Py_ssize_t)n) {
        py.PyErr_Clear();
        return wrong_result(in, function, "result: a wrong number of values");
    }
    for (size_t i = 0; i < n; i++) {
        PyObject *item = py.PySequence_GetItem(result, (Py_ssize_t)i);
        values[i] = item ? py.PyFloat_AsDouble(item) : 0.0;
        release(&item);
        if (py.PyErr_Occurred()) return python_failure(in, function);
    }
    return fmi2OK;
}

/* One of the inquiries that fill an array of the model's nx or ni numbers. */
static fmi2Status inquire(fmi2Component c, const char *function, unsigned phases,
                          enum ModelExchangeMethod method, const char *what, fmi2Real values[],
                          size_t n) {
    BEGIN_ME(function, phases);
    size_t count = what[1] == 'x' ? in->state_count : in->indicator_count;
    if (n != count) status = wrong_count(in, function_name, what, n, count);
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
    return inquire(c, "fmi2GetContinuousStates", MODEL_INQUIRY, ME_GET_CONTINUOUS_STATES, "nx",
                   x, nx);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    return inquire(c, "fmi2GetDerivatives", MODEL_INQUIRY, ME_GET_DERIVATIVES, "nx",
                   derivatives, nx);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    return inquire(c, "fmi2GetEventIndicators", MODEL_INQUIRY, ME_GET_EVENT_INDICATORS, "ni",
                   eventIndicators, ni);
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[],
                                             size_t nx) {
    return inquire(c, "fmi2GetNominalsOfContinuousStates", ANY_PHASE, ME_GET_NOMINALS, "nx",
                   x_nominal, nx);
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    BEGIN_ME("fmi2SetTime", EVENT_OR_CONTINUOUS);
    PyObject *value = py.PyFloat_FromDouble(time);
    PyObject *result = value ? CALL_ME(ME_SET_TIME, value) : NULL;
    if (!result) status = python_failure(in, function_name);
    release(&result);
    release(&value);
    END();
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    BEGIN_ME("fmi2SetContinuousStates", 1u << CONTINUOUS_TIME_MODE);
    PyObject *values = NULL;
    if (nx != in->state_count) status = wrong_count(in, function_name, "nx", nx,
                                                    in->state_count);
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

/* A Model Exchange call that takes no argument and changes the phase to next on success. */
static fmi2Status change_mode(fmi2Component c, const char *function, unsigned phases,
                              enum ModelExchangeMethod method, enum Phase next) {
    BEGIN_ME(function, phases);
    PyObject *result = CALL_ME(method, NULL);
    if (!result) status = python_failure(in, function_name);
    else in->phase = next;
    release(&result);
    END();
}

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    return change_mode(c, "fmi2EnterEventMode", EVENT_OR_CONTINUOUS, ME_ENTER_EVENT_MODE,
                       EVENT_MODE);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    return change_mode(c, "fmi2EnterContinuousTimeMode", 1u << EVENT_MODE,
                       ME_ENTER_CONTINUOUS_TIME_MODE, CONTINUOUS_TIME_MODE);
}

/* The truth of item i of a result sequence (-1 with the exception pending). */
static int truth(PyObject *result, Py_ssize_t i) {
    PyObject *item = py.PySequence_GetItem(result, i);
    int value = item ? py.PyObject_IsTrue(item) : -1;
    release(&item);
    return value;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    BEGIN_ME("fmi2NewDiscreteStates", 1u << EVENT_MODE);
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
    BEGIN_ME("fmi2CompletedIntegratorStep", 1u << CONTINUOUS_TIME_MODE);
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
