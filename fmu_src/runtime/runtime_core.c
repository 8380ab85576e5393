/* The version-neutral core of the FMUs' runtime (runtime_core.h says what it offers):
 * Python found, loaded and started, the FMU's resources, instances and their slaves, messages
 * and the calls of the slave, for the entry points of an FMI version (fmi2_functions.c).
 *
 * Python:
 * - In a process that already holds a CPython 3.8 or later (the host program, as FMPy's, or a
 *   libpython loaded RTLD_GLOBAL or RTLD_LOCAL: every mapped object is looked at), it uses
 *   that interpreter (made global if it was local, started if it was not) and loads no second
 *   one; an older CPython there is refused. Otherwise, on the first instantiation, it loads
 *   (RTLD_GLOBAL) the libpython
 *   named by BALANCER_FMU_LIBPYTHON if set (and only that one), else the one the FMU was built
 *   with (resources/python.txt), else a libpython 3.8 or later the dynamic linker finds, and
 *   starts it with Py_InitializeFromConfig, which returns a status instead of ending the
 *   process. For the recorded library it passes the recorded prefix as the home (PyConfig, not
 *   the environment) when the host has no PYTHONHOME. A failure gives NULL and a message
 *   naming what was tried, PYTHONHOME included. It never changes the host's environment.
 * - An interpreter it started stays running: nothing calls Py_Finalize, so no library
 *   destructor touches Python. It installs no signal handlers and leaves the host's locale
 *   environment alone.
 * - Every call holds the GIL through PyGILState_Ensure/Release. A host thread that arrives
 *   without a Python thread state gets one for its lifetime, released when the thread ends.
 * - Around a fork of the process the forking thread takes the GIL (PyOS_BeforeFork,
 *   PyOS_AfterFork_Parent/_Child), so that the child has a GIL it can take.
 * - Each FMU imports the Python code of its own bundle (HELPER_SOURCE).
 *
 * References: every new reference is held by one owner and released once (Py_DecRef);
 * borrowed ones are never released. The instance owns its slave, the slave's bound methods
 * (looked up once) and its log queue.
 *
 * Status: a Python exception gives Error and one log line "<function>: <type>: <message>";
 * MemoryError and SystemExit give Fatal.
 *
 * Logging: the slave's log queue is passed on after every call, and the runtime's own
 * messages with it; each literal % reaches the host's logger as %% (its message is a printf
 * format). Error and Fatal messages always reach it, the others when logging is on (and, with
 * categories set, only those categories). A logger may call the FMU again: each message
 * reaches it once.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <link.h>
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
#include "runtime_core.h"

#define OVERRIDE_VARIABLE "BALANCER_FMU_LIBPYTHON"
#define RECORD_FILE "python.txt"   /* in the FMU's resources: key=value lines */
#define SLAVE_MODULE_FILE "slavemodule.txt"
#define PATH_SIZE 4096
#define CONFIG_SIZE 16384  /* bytes reserved for a PyConfig: larger than any CPython's */
#define MAX_LOGGER_DEPTH 8  /* nested calls of the host's logger (through calls it makes) */

/* sonames the dynamic linker may find when the recorded library is absent, newest first */
static const char *const FALLBACK_SONAMES[] = {
    "libpython3.14.so.1.0", "libpython3.13.so.1.0", "libpython3.12.so.1.0",
    "libpython3.11.so.1.0", "libpython3.10.so.1.0", "libpython3.9.so.1.0",
    "libpython3.8.so.1.0"};

/* ---- the Python C API (runtime_core.h), resolved by name from the process */
#define PY_FILE_INPUT 257
#define PY_CONFIG_INIT_PYTHON 2  /* _PyConfig_INIT_PYTHON: PyConfig/PyPreConfig._config_init */

PythonApi py;

/* The Python side of the runtime: find the slave class, make a slave. Its module lives once
 * per process, in sys.modules under HELPER_MODULE (named by the digest of this text), shared
 * by every FMU and every load of this library.
 *
 * Each FMU's Python code is imported from its own resources folder as the package
 * _fmu_bundle_<digest of the bundle's Python files> (a meta path finder bound to that folder
 * runs those modules with an __import__ that maps the bundle's top-level names, fmu_src,
 * pythonfmu and the slave module, into that package). So an FMU runs the code it carries,
 * whatever else the process imported: another FMU, another version of the same one, or a
 * host's own fmu_src. FMUs of the same content share their modules. */
static const char HELPER_SOURCE[] =
    "import builtins\n"
    "import hashlib\n"
    "import importlib\n"
    "import importlib.abc\n"
    "import importlib.machinery\n"
    "import os\n"
    "import sys\n"
    "import types\n"
    "\n"
    "# Each bundle's code is imported as the package PREFIX + <digest of its Python files>:\n"
    "# FMUs of other content never share a module, FMUs of the same content share them all.\n"
    "PREFIX = '_fmu_bundle_'\n"
    "\n"
    "\n"
    "def _digest(resources):\n"
    "    '''SHA-256 (32 hex digits) of the Python files below the resources folder: their paths\n"
    "    and bytes, in sorted order (compiled caches left out).'''\n"
    "    sha = hashlib.sha256()\n"
    "    for folder, folders, files in os.walk(resources):\n"
    "        folders[:] = sorted(name for name in folders if name != '__pycache__')\n"
    "        for name in sorted(files):\n"
    "            if name.endswith('.py'):\n"
    "                path = os.path.join(folder, name)\n"
    "                with open(path, 'rb') as file:\n"
    "                    data = file.read()\n"
    "                for part in (os.fsencode(os.path.relpath(path, resources)), data):\n"
    "                    sha.update(len(part).to_bytes(8, 'big'))\n"
    "                    sha.update(part)\n"
    "    return sha.hexdigest()[:32]\n"
    "\n"
    "\n"
    "def _bundle_import(package, tops):\n"
    "    '''An __import__ for the modules of one bundle: an absolute import of one of its\n"
    "    top-level names (fmu_src, pythonfmu, the slave module) is one of the bundle's package.'''\n"
    "    real = builtins.__import__\n"
    "\n"
    "    def bundle_import(name, globals=None, locals=None, fromlist=(), level=0):\n"
    "        top = name.partition('.')[0]\n"
    "        if level == 0 and top in tops:\n"
    "            module = real(package + '.' + name, globals, locals, fromlist, 0)\n"
    "            return module if fromlist else sys.modules[package + '.' + top]\n"
    "        return real(name, globals, locals, fromlist, level)\n"
    "    return bundle_import\n"
    "\n"
    "\n"
    "class _BundleLoader(importlib.machinery.SourceFileLoader):\n"
    "    '''Runs a module of a bundle with the bundle's builtins (its __import__).'''\n"
    "\n"
    "    def exec_module(self, module):\n"
    "        package = sys.modules[module.__name__.partition('.')[0]]\n"
    "        module.__dict__['__builtins__'] = package._bundle_builtins\n"
    "        super().exec_module(module)\n"
    "\n"
    "\n"
    "class _BundleFinder(importlib.abc.MetaPathFinder):\n"
    "    '''Finds the modules of the bundles' packages in their resources folders.'''\n"
    "\n"
    "    def find_spec(self, name, path, target=None):\n"
    "        if not name.startswith(PREFIX) or '.' not in name:\n"
    "            return None\n"
    "        spec = importlib.machinery.PathFinder.find_spec(name, path)\n"
    "        if spec is not None and type(spec.loader) is importlib.machinery.SourceFileLoader:\n"
    "            spec.loader = _BundleLoader(spec.loader.name, spec.loader.path)\n"
    "        return spec\n"
    "\n"
    "\n"
    "def _package(resources):\n"
    "    '''The package of the bundle in the resources folder, made on first use.'''\n"
    "    name = PREFIX + _digest(resources)\n"
    "    package = sys.modules.get(name)\n"
    "    if package is not None:\n"
    "        package.__path__[:] = [resources]  # earlier copies of this content may be deleted\n"
    "        return package\n"
    "    package = types.ModuleType(name, 'The Python code of the FMUs whose resources hold '\n"
    "                                     'these files: ' + resources)\n"
    "    package.__path__ = [resources]\n"
    "    package.__spec__ = importlib.machinery.ModuleSpec(name, None, is_package=True)\n"
    "    package.__spec__.submodule_search_locations = package.__path__\n"
    "    tops = frozenset(entry[:-3] if entry.endswith('.py') else entry\n"
    "                     for entry in os.listdir(resources)\n"
    "                     if entry.endswith('.py') or (entry != '__pycache__' and os.path.isdir(\n"
    "                         os.path.join(resources, entry))))\n"
    "    package._bundle_builtins = dict(vars(builtins), __import__=_bundle_import(name, tops))\n"
    "    if not any(type(finder).__name__ == '_BundleFinder' for finder in sys.meta_path):\n"
    "        sys.meta_path.insert(0, _BundleFinder())\n"
    "    return sys.modules.setdefault(name, package)  # another thread may have made it\n"
    "\n"
    "\n"
    "def _depth(cls, base):\n"
    "    names = [klass.__name__ for klass in getattr(cls, '__mro__', ())]\n"
    "    return names.index(base) if base in names[1:] else -1\n"
    "\n"
    "\n"
    "def slave_class(resources, module_name, base):\n"
    "    '''The subclass of base (the dotted name of the FMI version's slave class) of the slave\n"
    "    module of the FMU whose resources folder this is, imported from it (pythonfmu's rule:\n"
    "    of the concrete classes the module defines, the one deepest below base).'''\n"
    "    module = importlib.import_module(_package(resources).__name__ + '.' + module_name)\n"
    "    name = base.rpartition('.')[2]\n"
    "    members = [m for m in vars(module).values() if isinstance(m, type)\n"
    "               and _depth(m, name) > 0 and not getattr(m, '__abstractmethods__', None)]\n"
    "    own = [m for m in members if m.__module__ == module.__name__] or members\n"
    "    if not own:\n"
    "        raise TypeError(f'module {module_name} ({module.__file__}) defines no concrete '\n"
    "                        f'subclass of {base}')\n"
    "    return max(own, key=lambda m: _depth(m, name))\n"
    "\n"
    "\n"
    "def new_slave(cls, instance_name, resources, visible):\n"
    "    return cls(instance_name=instance_name, resources=resources, visible=bool(visible))\n";

/* ---- messages ------------------------------------------------------------------------ */
void append(Message *m, const char *format, ...) {
    va_list args;
    if (m->length >= sizeof m->text - 1) return;
    va_start(args, format);
    int n = vsnprintf(m->text + m->length, sizeof m->text - m->length, format, args);
    va_end(args);
    if (n > 0) m->length += (size_t)n;
    if (m->length > sizeof m->text - 1) m->length = sizeof m->text - 1;
}

static int category_enabled(const Sink *sink, const char *category) {
    if (!sink->categories) return 1;
    for (size_t i = 0; i < sink->category_count; i++)
        if (category && strcmp(sink->categories[i], category) == 0) return 1;
    return 0;
}

/* Pass text to the host's logger as a printf format that prints it as it is: each % as %%,
 * each line break as a space (one message, one line). A logger that calls the FMU, whose
 * call logs, and so on, is cut off MAX_LOGGER_DEPTH calls deep (the deeper messages are
 * dropped) instead of running out of stack. */
void log_text(Sink *sink, int status, const char *category, const char *text) {
    if (!sink->emit || sink->depth >= MAX_LOGGER_DEPTH) return;
    if (status < STATUS_ERROR && !(sink->logging_on && category_enabled(sink, category)))
        return;
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
    sink->depth++;
    sink->emit(sink, status, category, escaped);
    sink->depth--;
    free(escaped);
}

void log_format(Sink *sink, int status, const char *format, ...) {
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

/* resources/python.txt beside this library, read once (load_lock held): libpython, prefix
 * and guid. */
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

/* ---- the Python of the process --------------------------------------------------------- */
static void *python_library;  /* the handle the Python C API is resolved from */
static int host_python;       /* that Python was running before this runtime looked */

/* The CPython major and minor version of a library's Py_GetVersion, or 0. */
static int python_version(void *library, int *minor) {
    const char *(*version)(void) = (const char *(*)(void))dlsym(library, "Py_GetVersion");
    int major = 0;
    *minor = 0;
    if (!version || sscanf(version(), "%d.%d", &major, minor) != 2) return 0;
    return major;
}

/* dlopen a libpython (RTLD_GLOBAL), a regular file or a soname, and check it is CPython 3.8
 * or later; its handle, or NULL after adding why to the message. */
static void *open_libpython(const char *path, Message *why) {
    if (strchr(path, '/') && !regular_file(path)) {
        struct stat info;
        append(why, "\n  %s: %s", path, stat(path, &info) != 0 ? "no such file"
                                          : "not a regular file (not opened)");
        return NULL;
    }
    void *handle = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    if (!handle) {
        const char *error = dlerror();
        size_t length = strlen(path); /* dlerror often starts with the path already */
        if (strncmp(error, path, length) == 0 && strncmp(error + length, ": ", 2) == 0)
            error += length + 2;
        append(why, "\n  %s: %s", path, error);
        return NULL;
    }
    int minor, major = python_version(handle, &minor);
    if (major != 3 || minor < 8) {
        const char *(*version)(void) = (const char *(*)(void))dlsym(handle, "Py_GetVersion");
        append(why, "\n  %s: not a CPython 3.8 or later library (%s)", path,
               version ? version() : "no Py_GetVersion");
        dlclose(handle);
        return NULL;
    }
    return handle;
}

/* The objects mapped in the process (dl_iterate_phdr), as found: a name (empty for the
 * program) and the address ranges of its loaded segments. */
#define MAX_OBJECTS 1024
#define MAX_SEGMENTS 8
typedef struct {
    char name[PATH_SIZE];
    size_t segments;
    uintptr_t start[MAX_SEGMENTS], end[MAX_SEGMENTS];
} MappedObject;

typedef struct {
    MappedObject *objects;
    size_t count;
} MappedObjects;

static int note_object(struct dl_phdr_info *info, size_t size, void *data) {
    (void)size;
    MappedObjects *found = data;
    if (found->count == MAX_OBJECTS) return 1;
    MappedObject *object = &found->objects[found->count++];
    snprintf(object->name, sizeof object->name, "%s", info->dlpi_name ? info->dlpi_name : "");
    object->segments = 0;
    for (int i = 0; i < info->dlpi_phnum && object->segments < MAX_SEGMENTS; i++) {
        if (info->dlpi_phdr[i].p_type != PT_LOAD) continue;
        uintptr_t start = (uintptr_t)info->dlpi_addr + (uintptr_t)info->dlpi_phdr[i].p_vaddr;
        object->start[object->segments] = start;
        object->end[object->segments++] = start + (uintptr_t)info->dlpi_phdr[i].p_memsz;
    }
    return 0;
}

static int holds(const MappedObject *object, const void *address) {
    for (size_t i = 0; i < object->segments; i++)
        if ((uintptr_t)address >= object->start[i] && (uintptr_t)address < object->end[i])
            return 1;
    return 0;
}

/* A CPython already in the process, however it came (the host's program, a libpython loaded
 * RTLD_GLOBAL or RTLD_LOCAL by the host or a plugin, or by another FMU): every mapped object
 * that defines Py_IsInitialized itself. The one to use: a running CPython 3.8 or later, else
 * one not started yet. Its handle (made global if it was loaded RTLD_LOCAL, so that its
 * extension modules find its symbols), or NULL: none there (*refused 0), or none usable
 * (*refused 1, why in the message). */
static void *mapped_python(Message *why, int *refused) {
    MappedObjects found = {calloc(MAX_OBJECTS, sizeof(MappedObject)), 0};
    void *chosen = NULL;
    int chosen_running = 0, chosen_program = 0, pythons = 0;
    char chosen_name[PATH_SIZE] = "", other[PATH_SIZE + 64] = "";
    *refused = 0;
    if (!found.objects) return NULL;
    dl_iterate_phdr(note_object, &found);  /* the objects noted first: no dlopen under its lock */
    for (size_t i = 0; i < found.count; i++) {
        const char *name = found.objects[i].name[0] ? found.objects[i].name : NULL;
        if (i > 0 && !name) continue;  /* the program is the first object; others have names */
        void *handle = dlopen(name, RTLD_LAZY | RTLD_NOLOAD);
        void *symbol = handle ? dlsym(handle, "Py_IsInitialized") : NULL;
        if (!symbol || !holds(&found.objects[i], symbol)) {
            if (handle) dlclose(handle);
            continue;
        }
        pythons++;
        int minor, major = python_version(handle, &minor);
        int running = ((int (*)(void))symbol)();
        const char *label = name ? name : "the host program";
        if (major != 3 || minor < 8) {
            snprintf(other, sizeof other, "%s (CPython %d.%d)", label, major, minor);
            dlclose(handle);
        } else if (!chosen || (running && !chosen_running)) {
            if (chosen) dlclose(chosen);
            chosen = handle;
            chosen_running = running;
            chosen_program = !name;
            snprintf(chosen_name, sizeof chosen_name, "%s", label);
        } else {
            snprintf(other, sizeof other, "%s", label);
            dlclose(handle);
        }
    }
    free(found.objects);
    if (!chosen && pythons) {
        append(why, "a CPython older than 3.8 is already in this process, %s: the FMU needs "
               "3.8 or later and loads no second interpreter beside it", other);
        *refused = 1;
        return NULL;
    }
    if (!chosen) return NULL;
    void *symbol = dlsym(chosen, "Py_IsInitialized");
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized") != symbol) {  /* loaded RTLD_LOCAL */
        if (pythons > 1) {
            append(why, "CPython %s is in this process but not visible to the libraries it "
                   "loads (RTLD_LOCAL), and another one is there too, %s: the FMU will not "
                   "make one of them visible beside the other", chosen_name, other);
            dlclose(chosen);
            *refused = 1;
            return NULL;
        }
        if (!chosen_program) dlopen(chosen_name, RTLD_LAZY | RTLD_NOLOAD | RTLD_GLOBAL);
    }
    host_python = chosen_running;
    return chosen;
}

/* What PYTHONHOME is for a Python this runtime starts, for messages; and the home it passes
 * to that Python (PyConfig.home), if any. */
static char home_note[PATH_SIZE + 128];
static const char *python_home;

/* Find or load the Python as the header comment says (python_library); 0 with the paths tried
 * in why on failure (*refused 1 when a Python in the process rules the others out). */
static int load_libpython(Message *why, int *refused) {
    if ((python_library = mapped_python(why, refused))) return 1;
    if (*refused) return 0;
    const char *override = getenv(OVERRIDE_VARIABLE);
    const char *home = getenv("PYTHONHOME");
    if (home) snprintf(home_note, sizeof home_note, "PYTHONHOME=%s (from the environment)", home);
    else snprintf(home_note, sizeof home_note, "PYTHONHOME unset");
    if (override && override[0]) {
        append(why, "no Python for this FMU; tried %s=%s:", OVERRIDE_VARIABLE, override);
        return (python_library = open_libpython(override, why)) != NULL;
    }
    append(why, "no Python for this FMU; tried (%s unset):", OVERRIDE_VARIABLE);
    if (record.libpython[0]) {
        if ((python_library = open_libpython(record.libpython, why))) {
            if (!home && record.prefix[0] && is_directory(record.prefix)) {
                python_home = record.prefix;  /* through PyConfig: the environment stays */
                snprintf(home_note, sizeof home_note,
                         "PYTHONHOME=%s (the prefix recorded at build time)", record.prefix);
            }
            return 1;
        }
    } else {
        append(why, "\n  resources/" RECORD_FILE ": no libpython recorded");
    }
    for (size_t i = 0; i < sizeof FALLBACK_SONAMES / sizeof *FALLBACK_SONAMES; i++)
        if ((python_library = open_libpython(FALLBACK_SONAMES[i], why))) return 1;
    return 0;
}

/* The Python C API from python_library: the CPython this runtime uses, whatever else is
 * mapped in the process. */
static int resolve_python_api(Message *why) {
    void *library = python_library;
#define RESOLVE(result, name, arguments) \
    if (!(*(void **)&py.name = dlsym(library, #name))) { \
        append(why, "the Python C API function " #name " is not in this process"); return 0; }
    PYTHON_API(RESOLVE)
#undef RESOLVE
    *(void **)&py.IsFinalizing = dlsym(library, "Py_IsFinalizing");
    if (!py.IsFinalizing) *(void **)&py.IsFinalizing = dlsym(library, "_Py_IsFinalizing");
    py.None = (PyObject *)dlsym(library, "_Py_NoneStruct");
    PyObject **memory = dlsym(library, "PyExc_MemoryError");
    PyObject **exit = dlsym(library, "PyExc_SystemExit");
    PyObject **interrupt = dlsym(library, "PyExc_KeyboardInterrupt");
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
/* offsetof(PyConfig, home) of each CPython 3.8 and later (x86_64) by minor version; 0 for
 * a version not listed. tests/test_native_host.py checks them against the headers of every
 * CPython installed. */
static size_t config_home_offset(void) {
    static const size_t OFFSETS[] = {[8] = 240, [9] = 240, [10] = 256, [11] = 280,
                                     [12] = 288, [13] = 296};
    int major = 0, minor = 0;
    if (sscanf(py.Py_GetVersion(), "%d.%d", &major, &minor) != 2 || major != 3 || minor < 0 ||
        (size_t)minor >= sizeof OFFSETS / sizeof *OFFSETS)
        return 0;
    return OFFSETS[minor];
}

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
    PyStatus status = {0, NULL, NULL, 0};
    size_t home = python_home ? config_home_offset() : 0;
    if (python_home && !home)  /* a CPython newer than this runtime: its built-in prefix */
        snprintf(home_note, sizeof home_note, "PYTHONHOME unset (the recorded prefix %s not "
                 "passed: the runtime does not know the PyConfig of CPython %.10s)",
                 python_home, py.Py_GetVersion());
    if (home)
        status = py.PyConfig_SetBytesString(config, (void *)((char *)config + home),
                                            python_home);
    if (!py.PyStatus_Exception(status)) status = py.Py_InitializeFromConfig(config);
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

/* The helper's module: HELPER_MODULE_PREFIX and the FNV-1a digest of HELPER_SOURCE, so that
 * runtimes of one source share it and others do not. */
static void helper_module_name(char *name, size_t size) {
    uint64_t hash = 14695981039346656037ull;
    for (const char *ch = HELPER_SOURCE; *ch; ch++)
        hash = (hash ^ (unsigned char)*ch) * 1099511628211ull;
    snprintf(name, size, "_fmu_runtime_helper_%016llx", (unsigned long long)hash);
}

/* Find the helper's functions in its module, running HELPER_SOURCE there first if this is
 * the first load in the process: one FMU at a time (HELPER_SOURCE releases the GIL while it
 * imports, and a second run of it would replace the functions a first took). This load keeps
 * a reference to each function (never released: see the header). */
static int make_helper_now(Message *why) {
    char name[64];
    helper_module_name(name, sizeof name);
    PyGILState_STATE gil = py.PyGILState_Ensure();
    PyObject *module = py.PyImport_AddModule(name);  /* borrowed: sys.modules holds it */
    PyObject *namespace = module ? py.PyModule_GetDict(module) : NULL;
    PyObject *builtins = NULL, *result = NULL;
    int ready = namespace && py.PyDict_GetItemString(namespace, "new_slave");
    if (namespace && !ready) {
        builtins = py.PyImport_ImportModule("builtins");
        if (builtins && py.PyDict_SetItemString(namespace, "__builtins__", builtins) == 0)
            result = py.PyRun_StringFlags(HELPER_SOURCE, PY_FILE_INPUT, namespace, namespace,
                                          NULL);
        ready = result != NULL;
    }
    if (ready) {
        helper_slave_class = py.PyDict_GetItemString(namespace, "slave_class");
        helper_new_slave = py.PyDict_GetItemString(namespace, "new_slave");
        if (helper_slave_class) py.Py_IncRef(helper_slave_class);
        if (helper_new_slave) py.Py_IncRef(helper_new_slave);
    }
    py.PyErr_Clear();
    if (result) py.Py_DecRef(result);
    if (builtins) py.Py_DecRef(builtins);
    py.PyGILState_Release(gil);
    if (!helper_slave_class || !helper_new_slave) {
        append(why, "the runtime's Python helper did not compile");
        return 0;
    }
    return 1;
}

static int make_helper(Message *why) {
    int lock = lock_process();
    int made = make_helper_now(why);
    if (lock >= 0) close(lock);
    return made;
}

/* ---- fork ------------------------------------------------------------------------------- */
/* A host thread may fork while another is inside an FMU call, holding the GIL: the child would
 * wait for ever on a GIL no thread of its own holds. Around every fork of the process, the
 * forking thread takes the GIL first (waiting for the call under way to let go of it) and
 * readies Python for the fork (PyOS_BeforeFork); parent and child go on from a consistent
 * interpreter (PyOS_AfterFork_Parent/_Child) and release the GIL. A fork from Python code
 * (os.fork) holds the GIL already and does this itself. Each copy of the runtime (one per FMU)
 * registers the handlers; the first to run in a fork acts for all. */
static int fork_prepared;  /* this copy took the GIL for the fork under way */
/* Its address names this copy's fork handlers to glibc (__register_atfork), which forgets them
 * when the library is unloaded (__cxa_finalize, called from the library's destructor): a fork
 * after that must not call into unmapped code. (pthread_atfork, as linked for glibc 2.17, keeps
 * them for good.) */
static char fork_handlers;
static int fork_handlers_registered;
extern int __register_atfork(void (*)(void), void (*)(void), void (*)(void), void *);
extern void __cxa_finalize(void *);

static void before_fork(void) {
    fork_prepared = 0;
    if (!python_usable() || py.PyGILState_Check()) return;
    hold_thread_state();
    py.PyEval_RestoreThread(py.PyGILState_GetThisThreadState());
    py.PyOS_BeforeFork();
    fork_prepared = 1;
}

static void after_fork_in_parent(void) {
    if (!fork_prepared) return;
    fork_prepared = 0;
    py.PyOS_AfterFork_Parent();
    py.PyEval_SaveThread();
}

static void after_fork_in_child(void) {
    if (!fork_prepared) return;
    fork_prepared = 0;
    py.PyOS_AfterFork_Child();
    py.PyEval_SaveThread();
}

/* Make loaded true, or write why not. */
int load(Message *why) {
    pthread_mutex_lock(&load_lock);
    if (!loaded && !load_failure.length) {
        Message attempt = {{0}, 0};
        int refused = 0;
        if (!load_libpython(&attempt, &refused)) {
            if (!refused)
                append(&attempt, "\nThis FMU runs its model in CPython 3.8 or later: set %s to "
                       "the path of a libpython3.X.so.1.0 shared library.", OVERRIDE_VARIABLE);
        } else if (resolve_python_api(&attempt) && start_python(&attempt)) {
            loaded = 1;
            if (!make_helper(&attempt)) loaded = 0;
            else {
                thread_key_made = pthread_key_create(&thread_key, release_thread_state) == 0;
                fork_handlers_registered = __register_atfork(
                    before_fork, after_fork_in_parent, after_fork_in_child, &fork_handlers) == 0;
            }
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

/* A thread-exit destructor or a fork handler must not run once this library is unloaded. */
__attribute__((destructor)) static void unload(void) {
    if (thread_key_made) pthread_key_delete(thread_key);
    if (fork_handlers_registered) __cxa_finalize(&fork_handlers);
}

const char *recorded_guid(void) {
    pthread_mutex_lock(&load_lock);
    read_record();
    pthread_mutex_unlock(&load_lock);
    return record.guid;
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
char *resource_folder(const char *uri, Message *why) {
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
char *slave_module(const char *folder, const char *uri, Message *why) {
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
static const char *const METHOD_NAMES[METHOD_COUNT] = {
    "do_step", "get_real", "set_real", "get_integer", "set_integer", "get_boolean",
    "set_boolean", "get_string", "set_string", "setup_experiment", "enter_initialization_mode",
    "exit_initialization_mode", "terminate", "_get_fmu_state", "_set_fmu_state",
    "_fmu_state_to_bytes", "_fmu_state_from_bytes"};

static const char *const ME_METHOD_NAMES[ME_METHOD_COUNT] = {
    "me_set_time", "me_set_continuous_states", "me_get_continuous_states", "me_get_nominals",
    "me_get_derivatives", "me_get_event_indicators", "me_enter_event_mode",
    "me_new_discrete_states", "me_enter_continuous_time_mode", "me_completed_integrator_step"};

void release_strings(Instance *in) {
    for (size_t i = 0; i < in->string_count; i++) release(&in->strings[i]);
    free(in->strings);
    in->strings = NULL;
    in->string_count = 0;
}

void release_slave(Instance *in) {
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

int python_failure(Instance *in, const char *function) {
    PyObject *type = NULL, *value = NULL, *trace = NULL;
    py.PyErr_Fetch(&type, &value, &trace);
    int status = STATUS_ERROR;
    char name[256] = "unknown error", text[MESSAGE_SIZE / 2] = "";
    if (type) {
        py.PyErr_NormalizeException(&type, &value, &trace);
        if (py.PyErr_GivenExceptionMatches(type, py.MemoryError) ||
            py.PyErr_GivenExceptionMatches(type, py.SystemExit)) status = STATUS_FATAL;
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

/* The messages are taken out of the queue first, so that a call the host's logger makes back
 * into the FMU passes on only its own messages. */
void drain_log(Instance *in) {
    Py_ssize_t count = in->queue ? py.PySequence_Size(in->queue) : 0;
    PyObject *messages = count > 0 ? py.PySequence_GetSlice(in->queue, 0, count) : NULL;
    if (messages && py.PySequence_DelSlice(in->queue, 0, count) != 0) release(&messages);
    if (!messages) {
        py.PyErr_Clear();
        return;
    }
    for (Py_ssize_t i = 0; i < count; i++) {
        PyObject *message = py.PySequence_GetItem(messages, i);
        PyObject *status = message ? py.PyObject_GetAttrString(message, "status") : NULL;
        PyObject *category = message ? py.PyObject_GetAttrString(message, "category") : NULL;
        PyObject *msg = message ? py.PyObject_GetAttrString(message, "msg") : NULL;
        long level = status ? py.PyLong_AsLong(status) : STATUS_OK;
        if (level < STATUS_OK || level > STATUS_FATAL) level = STATUS_OK;
        py.PyErr_Clear();
        char category_text[256], text[MESSAGE_SIZE];
        int has_category = category && category != py.None;
        if (has_category) text_of(category, category_text, sizeof category_text);
        text_of(msg, text, sizeof text);
        log_text(&in->sink, (int)level, has_category ? category_text : NULL, text);
        release(&msg);
        release(&category);
        release(&status);
        release(&message);
    }
    release(&messages);
}

/* Look the slave's Model Exchange methods and its numbers of continuous states and event
 * indicators up (me_state_count, me_indicator_count); the name of the first missing (a slave
 * of Co-Simulation only), or NULL. */
static const char *model_exchange_methods(Instance *in) {
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
    if (missing) py.PyErr_Clear();
    return missing;
}

int create_slave(Instance *in, const char *function, const char **missing) {
    PyObject *name = py.PyUnicode_FromString(in->sink.name);
    PyObject *resources = py.PyUnicode_DecodeFSDefault(in->resources);
    PyObject *module = py.PyUnicode_FromString(in->module);
    PyObject *visible = py.PyBool_FromLong(in->visible);
    PyObject *base = in->cls ? NULL : py.PyUnicode_FromString(in->slave_base);
    if (!in->cls && name && resources && module && base)
        in->cls = py.PyObject_CallFunctionObjArgs(helper_slave_class, resources, module, base,
                                                  NULL);
    if (in->cls && visible)
        in->slave = py.PyObject_CallFunctionObjArgs(helper_new_slave, in->cls, name, resources,
                                                    visible, NULL);
    for (int i = 0; in->slave && i < METHOD_COUNT; i++)
        if (!(in->methods[i] = py.PyObject_GetAttrString(in->slave, METHOD_NAMES[i]))) break;
    PyObject *queue_getter = in->slave && in->methods[METHOD_COUNT - 1]
                                 ? py.PyObject_GetAttrString(in->slave, "_get_log_queue") : NULL;
    if (queue_getter) in->queue = py.PyObject_CallFunctionObjArgs(queue_getter, NULL);
    release(&queue_getter);
    if (in->queue) {  /* the failure of a step before is kept for its message */
        PyObject *variables = py.PyObject_GetAttrString(in->slave, "vars");
        Py_ssize_t count = variables ? py.PyObject_Size(variables) : -1;
        in->variable_count = count >= 0 ? (size_t)count : SIZE_MAX;  /* not pythonfmu's */
        py.PyErr_Clear();
        release(&variables);
    }
    release(&name);
    release(&resources);
    release(&module);
    release(&visible);
    release(&base);
    *missing = in->queue && in->model_exchange ? model_exchange_methods(in) : NULL;
    if (in->queue) return !*missing;
    char call[128];
    snprintf(call, sizeof call, "%s (%s)", function,
             in->slave ? "the slave's methods" : "the slave class");
    int status = python_failure(in, call);
    drain_log(in);
    log_text(&in->sink, status > STATUS_ERROR ? status : STATUS_FATAL, NULL, in->failure);
    free(in->failure);  /* logged */
    in->failure = NULL;
    release_slave(in);
    return 0;
}

void free_instance(Instance *in) {
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

/* ---- calling the slave ---------------------------------------------------------------- */
PyGILState_STATE enter_python(void) {
    hold_thread_state();
    return py.PyGILState_Ensure();
}

void leave_python(Instance *in, int status, PyGILState_STATE gil) {
    drain_log(in);
    char *failure = in->failure;
    in->failure = NULL;
    if (status >= STATUS_ERROR && failure) log_text(&in->sink, status, NULL, failure);
    free(failure);
    py.PyGILState_Release(gil);
}

int wrong_result(Instance *in, const char *function, const char *what) {
    free(in->failure);
    Message m = {{0}, 0};
    append(&m, "%s: the slave's %s", function, what);
    in->failure = strdup(m.text);
    return STATUS_ERROR;
}

/* A larger nvr can only be a host's mistake: the length of another array, a negative number
 * cast. */
int references_fit(Instance *in, size_t nvr, const char *function) {
    if (nvr <= in->variable_count) return 1;
    Message m = {{0}, 0};
    append(&m, "%s: nvr = %zu value references, more than the %zu variables of this FMU",
           function, nvr, in->variable_count);
    free(in->failure);
    in->failure = strdup(m.text);
    return 0;
}

PyObject *reference_list(const unsigned int vr[], size_t nvr) {
    PyObject *list = py.PyList_New((Py_ssize_t)nvr);
    for (size_t i = 0; list && i < nvr; i++) {
        PyObject *item = py.PyLong_FromLong((long)vr[i]);
        if (!item || py.PyList_SetItem(list, (Py_ssize_t)i, item) != 0) release(&list);
    }
    return list;
}

int wrong_count(Instance *in, const char *function, int states, size_t given, size_t count) {
    Message m = {{0}, 0};
    append(&m, "%s: %s = %zu is not this FMU's number of %s, %zu", function,
           states ? "nx" : "ni", given, states ? "continuous states" : "event indicators",
           count);
    free(in->failure);
    in->failure = strdup(m.text);
    return STATUS_ERROR;
}

int take_numbers(Instance *in, const char *function, PyObject *result, double values[],
                 size_t n) {
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
    return STATUS_OK;
}

int truth(PyObject *result, Py_ssize_t i) {
    PyObject *item = py.PySequence_GetItem(result, i);
    int value = item ? py.PyObject_IsTrue(item) : -1;
    release(&item);
    return value;
}
