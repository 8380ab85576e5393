/* Stress host for the FMUs' FMI 2.0 runtime, in C: no Python in the process.
 *
 * It drives unzipped FMUs through the paths a long-running importing tool takes (load and
 * unload, thousands of instances, host threads, failed instances, odd arguments) and prints
 * what tests/test_runtime.py measures. Every FMU is given as three arguments DIR MODEL GUID
 * (the binary DIR/binaries/linux64/MODEL.so, the resource URI "file://" DIR "/resources"),
 * optionally followed by options for that FMU:
 *   r:VR        read the Real VR (repeatable; default: VR 0 only)
 *   d:VR=VALUE  set the Real VR in initialisation mode
 *   i:VR=VALUE  set the Integer VR in initialisation mode
 * The logger formats the message like printf (vfprintf with the call's varargs) on stderr,
 * after "[category] instance status N: ". A failed call (status above fmi2Warning) is
 * reported on stderr as "<function> returned status N" and the host exits with status 1,
 * except in the modes that expect failures (fatal, instantiate).
 *
 * usage: fmi2_stress cycles N STEPS FMU...       N times: each FMU dlopen, instantiate,
 *                                                run, state round trip, free, dlclose
 *        fmi2_stress rss N FMU                   RSS growth per instance cycle
 *        fmi2_stress reload N FMU                RSS growth per cycle of dlopen,
 *                                                instantiate, 10 steps, free, dlclose
 *        fmi2_stress threads FMU_A FMU_B         two host threads, one instance each
 *        fmi2_stress serial FMU_A FMU_B          the same work in the main thread
 *        fmi2_stress short-threads N FMU         RSS growth per short-lived host thread
 *        fmi2_stress fatal N FMU                 N instances driven into fmi2Fatal
 *        fmi2_stress me-cycles N STEPS NX NZ FMU N times: dlopen, a Model Exchange
 *                                                instance (nx NX, ni NZ) integrated STEPS
 *                                                explicit Euler steps with its events, a
 *                                                state round trip, then hostile calls (each
 *                                                must return fmi2Error), free, dlclose
 *        fmi2_stress instantiate FMU [--uri URI] [--guid G] [--type me|cs] [--null-name]
 *                    [--null-guid] [--null-uri] [--after-terminate]
 *                                                one instance with these arguments
 *        fmi2_stress environment FMU [-- PROGRAM ARG...]
 *                                                run 10 steps, print whether the process
 *                                                environment changed (each change on a
 *                                                line), then run PROGRAM as a child and
 *                                                print its exit status
 *        fmi2_stress beside LIBPYTHON lazy|now start|idle FMU
 *                                                a host holding a CPython of its own, as a
 *                                                plugin loads one: LIBPYTHON opened
 *                                                RTLD_LOCAL (binding lazily or now), started
 *                                                by the host or not; then the FMU runs 100
 *                                                steps and its values are printed, and the
 *                                                host runs Python code ("host python OK")
 *        fmi2_stress fork N FMU [FMU_B]          fork N times while a second host thread
 *                                                steps an instance; each child steps and
 *                                                reads another instance (of FMU_B if given),
 *                                                10 s at the most; prints how many children
 *                                                finished, and forks once more after
 *                                                unloading the FMUs
 *        fmi2_stress huge-nvr FMU                one step, fmi2SetReal and fmi2GetReal with
 *                                                nvr = 2^40 (the arrays one element long),
 *                                                then fmi2GetReal of one value: the statuses
 *        fmi2_stress reentrant DEPTH FMU         one step, the logger calling fmi2GetReal
 *                                                of the FMU's first r: reference for each
 *                                                message, DEPTH calls deep at most (-1: no
 *                                                limit)
 * exit status: 0 done, 1 a failed call, 2 usage, 3 a binary or function not loaded
 * build: cc -I<fmpy>/c-code fmi2_stress.c -ldl -lpthread -o fmi2_stress
 */
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include "fmi2Functions.h"

#define MAX_REFS 32
#define MAX_FMUS 16
#define PATH_SIZE 4096
#define STEP 1e-3
#define THREAD_STEPS 2000
#define WARM_UP 50          /* cycles (rss) or threads (short-threads) before the first RSS */
#define CYCLE_STEPS 10      /* steps per instance cycle in rss */
#define FATAL_FIRST 20      /* fatal: maps counted after this many instances, then at the end */

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setupExperiment;
    fmi2EnterInitializationModeTYPE *enterInitializationMode;
    fmi2ExitInitializationModeTYPE *exitInitializationMode;
    fmi2DoStepTYPE *doStep;
    fmi2GetRealTYPE *getReal;
    fmi2SetRealTYPE *setReal;
    fmi2SetIntegerTYPE *setInteger;
    fmi2GetFMUstateTYPE *getFMUstate;
    fmi2SetFMUstateTYPE *setFMUstate;
    fmi2FreeFMUstateTYPE *freeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *serializedFMUstateSize;
    fmi2SerializeFMUstateTYPE *serializeFMUstate;
    fmi2DeSerializeFMUstateTYPE *deSerializeFMUstate;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *freeInstance;
} Api;

typedef struct {
    const char *dir, *model, *guid;
    char path[PATH_SIZE], uri[PATH_SIZE];
    fmi2ValueReference reads[MAX_REFS];
    size_t n_reads;
    fmi2ValueReference real_refs[MAX_REFS], int_refs[MAX_REFS];
    fmi2Real real_values[MAX_REFS];
    fmi2Integer int_values[MAX_REFS];
    size_t n_reals, n_ints;
    void *lib;
    Api api;
} Fmu;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list args;
    (void)env;
    flockfile(stderr);  /* one line per message, even from two threads */
    fprintf(stderr, "[%s] %s status %d: ", category ? category : "(null)",
            instance ? instance : "(null)", status);
    if (message) {
        va_start(args, message);
        vfprintf(stderr, message, args);
        va_end(args);
    } else {
        fputs("(null)", stderr);
    }
    fputc('\n', stderr);
    fflush(stderr);
    funlockfile(stderr);
}

static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

/* reentrant: the instance the logger calls back into, and how deep */
static struct {
    Fmu *fmu;
    fmi2Component c;
    long depth, limit;
} reentry;

static void reentrant_logger(fmi2ComponentEnvironment env, fmi2String instance,
                             fmi2Status status, fmi2String category, fmi2String message, ...) {
    va_list args;
    char text[8192];
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "(null)", args);
    va_end(args);
    logger(env, instance, status, category, "%s", text);
    if (reentry.c && (reentry.limit < 0 || reentry.depth < reentry.limit)) {
        fmi2Real value;
        reentry.depth++;
        reentry.fmu->api.getReal(reentry.c, reentry.fmu->reads, 1, &value);
        reentry.depth--;
    }
}

static void usage(const char *program) {
    fprintf(stderr,
            "usage: %s cycles N STEPS FMU... | rss N FMU | reload N FMU | threads FMU_A FMU_B | "
            "serial FMU_A FMU_B | short-threads N FMU | fatal N FMU | instantiate FMU "
            "[--uri URI] [--guid G] [--type me|cs] [--null-name] [--null-guid] [--null-uri] "
            "[--after-terminate] | reentrant DEPTH FMU | environment FMU [-- PROGRAM ARG...] "
            "| beside LIBPYTHON lazy|now start|idle FMU | fork N FMU [FMU_B] | huge-nvr FMU\n"
            "  FMU = DIR MODEL GUID [r:VR] [d:VR=VALUE] [i:VR=VALUE]\n",
            program);
    exit(2);
}

/* A failed call in a mode that expects none: report it and leave (any thread). */
static void must(const char *function, fmi2Status status) {
    if (status <= fmi2Warning) return;
    fprintf(stderr, "%s returned status %d\n", function, status);
    fflush(stdout);
    fflush(stderr);
    _exit(1);
}

static long parse_count(const char *text, const char *program) {
    char *end;
    long n = strtol(text, &end, 10);
    if (*text == '\0' || *end != '\0' || n < 0) usage(program);
    return n;
}

static int parse_ref(const char *text, fmi2ValueReference *vr, const char **value) {
    char *end;
    unsigned long n = strtoul(text, &end, 10);
    if (end == text) return 0;
    if (value) {
        if (*end != '=') return 0;
        *value = end + 1;
    } else if (*end != '\0') {
        return 0;
    }
    *vr = (fmi2ValueReference)n;
    return 1;
}

/* Read one FMU's arguments from argv[*a]: DIR MODEL GUID and its r:/d:/i: options. */
static void parse_fmu(int argc, char **argv, int *a, Fmu *fmu) {
    if (*a + 3 > argc) usage(argv[0]);
    memset(fmu, 0, sizeof *fmu);
    fmu->dir = argv[*a];
    fmu->model = argv[*a + 1];
    fmu->guid = argv[*a + 2];
    *a += 3;
    if ((size_t)snprintf(fmu->path, sizeof fmu->path, "%s/binaries/linux64/%s.so", fmu->dir,
                         fmu->model) >= sizeof fmu->path ||
        (size_t)snprintf(fmu->uri, sizeof fmu->uri, "file://%s/resources", fmu->dir)
            >= sizeof fmu->uri) {
        fprintf(stderr, "path too long: %s\n", fmu->dir);
        exit(2);
    }
    for (; *a < argc; (*a)++) {
        const char *option = argv[*a], *value = NULL;
        fmi2ValueReference vr;
        if (strncmp(option, "r:", 2) == 0 && fmu->n_reads < MAX_REFS &&
            parse_ref(option + 2, &vr, NULL)) {
            fmu->reads[fmu->n_reads++] = vr;
        } else if (strncmp(option, "d:", 2) == 0 && fmu->n_reals < MAX_REFS &&
                   parse_ref(option + 2, &vr, &value)) {
            fmu->real_refs[fmu->n_reals] = vr;
            fmu->real_values[fmu->n_reals++] = strtod(value, NULL);
        } else if (strncmp(option, "i:", 2) == 0 && fmu->n_ints < MAX_REFS &&
                   parse_ref(option + 2, &vr, &value)) {
            fmu->int_refs[fmu->n_ints] = vr;
            fmu->int_values[fmu->n_ints++] = (fmi2Integer)strtol(value, NULL, 10);
        } else if (option[0] != '\0' && option[1] == ':') {
            usage(argv[0]);
        } else {
            break;
        }
    }
    if (fmu->n_reads == 0) fmu->reads[fmu->n_reads++] = 0;
}

#define LOAD(field, name) \
    if (!(fmu->api.field = (name##TYPE *)dlsym(fmu->lib, #name))) { \
        fprintf(stderr, "%s: missing %s\n", fmu->path, #name); \
        exit(3); \
    }

static void load(Fmu *fmu) {
    fmu->lib = dlopen(fmu->path, RTLD_NOW | RTLD_LOCAL);
    if (!fmu->lib) {
        fprintf(stderr, "%s\n", dlerror());
        exit(3);
    }
    LOAD(instantiate, fmi2Instantiate)
    LOAD(setupExperiment, fmi2SetupExperiment)
    LOAD(enterInitializationMode, fmi2EnterInitializationMode)
    LOAD(exitInitializationMode, fmi2ExitInitializationMode)
    LOAD(doStep, fmi2DoStep)
    LOAD(getReal, fmi2GetReal)
    LOAD(setReal, fmi2SetReal)
    LOAD(setInteger, fmi2SetInteger)
    LOAD(getFMUstate, fmi2GetFMUstate)
    LOAD(setFMUstate, fmi2SetFMUstate)
    LOAD(freeFMUstate, fmi2FreeFMUstate)
    LOAD(serializedFMUstateSize, fmi2SerializedFMUstateSize)
    LOAD(serializeFMUstate, fmi2SerializeFMUstate)
    LOAD(deSerializeFMUstate, fmi2DeSerializeFMUstate)
    LOAD(terminate, fmi2Terminate)
    LOAD(freeInstance, fmi2FreeInstance)
}

static void unload(Fmu *fmu) {
    if (fmu->lib && dlclose(fmu->lib) != 0) {
        fprintf(stderr, "dlclose: %s\n", dlerror());
        exit(3);
    }
    fmu->lib = NULL;
}

/* Set the FMU's d: and i: values (in initialisation mode); the worst status. */
static fmi2Status set_values(Fmu *fmu, fmi2Component c) {
    fmi2Status worst = fmi2OK, status;
    if (fmu->n_reals) {
        status = fmu->api.setReal(c, fmu->real_refs, fmu->n_reals, fmu->real_values);
        if (status > worst) worst = status;
    }
    if (fmu->n_ints) {
        status = fmu->api.setInteger(c, fmu->int_refs, fmu->n_ints, fmu->int_values);
        if (status > worst) worst = status;
    }
    return worst;
}

/* An instance set up and initialised, or exit 1. */
static fmi2Component start(Fmu *fmu, const char *name) {
    fmi2Component c = fmu->api.instantiate(name, fmi2CoSimulation, fmu->guid, fmu->uri,
                                           &callbacks, fmi2False, fmi2True);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate returned NULL\n");
        _exit(1);
    }
    must("fmi2SetupExperiment", fmu->api.setupExperiment(c, fmi2False, 0.0, 0.0, fmi2False,
                                                         0.0));
    must("fmi2EnterInitializationMode", fmu->api.enterInitializationMode(c));
    must("fmi2SetReal/fmi2SetInteger", set_values(fmu, c));
    must("fmi2ExitInitializationMode", fmu->api.exitInitializationMode(c));
    return c;
}

static void steps(Fmu *fmu, fmi2Component c, long n, fmi2Real *values) {
    for (long k = 0; k < n; k++) {
        must("fmi2DoStep", fmu->api.doStep(c, (double)k * STEP, STEP, fmi2True));
        if (values) must("fmi2GetReal", fmu->api.getReal(c, fmu->reads, fmu->n_reads, values));
    }
}

static void finish(Fmu *fmu, fmi2Component c) {
    must("fmi2Terminate", fmu->api.terminate(c));
    fmu->api.freeInstance(c);
}

/* Get, serialize, deserialize and set the state; free both states. */
static void state_round_trip(Fmu *fmu, fmi2Component c) {
    fmi2FMUstate state = NULL, copy = NULL;
    size_t size = 0;
    must("fmi2GetFMUstate", fmu->api.getFMUstate(c, &state));
    must("fmi2SerializedFMUstateSize", fmu->api.serializedFMUstateSize(c, state, &size));
    fmi2Byte *buffer = malloc(size ? size : 1);
    if (!buffer) {
        fprintf(stderr, "out of memory for a state of %zu bytes\n", size);
        _exit(1);
    }
    must("fmi2SerializeFMUstate", fmu->api.serializeFMUstate(c, state, buffer, size));
    must("fmi2DeSerializeFMUstate", fmu->api.deSerializeFMUstate(c, buffer, size, &copy));
    free(buffer);
    must("fmi2SetFMUstate", fmu->api.setFMUstate(c, copy));
    must("fmi2FreeFMUstate", fmu->api.freeFMUstate(c, &state));
    must("fmi2FreeFMUstate", fmu->api.freeFMUstate(c, &copy));
}

static double resident_bytes(void) {
    long size = 0, resident = 0;
    FILE *statm = fopen("/proc/self/statm", "r");
    if (!statm || fscanf(statm, "%ld %ld", &size, &resident) != 2) {
        fprintf(stderr, "cannot read /proc/self/statm\n");
        exit(3);
    }
    fclose(statm);
    return (double)resident * (double)sysconf(_SC_PAGESIZE);
}

static long mappings(void) {
    FILE *maps = fopen("/proc/self/maps", "r");
    long lines = 0;
    int ch;
    if (!maps) {
        fprintf(stderr, "cannot read /proc/self/maps\n");
        exit(3);
    }
    while ((ch = fgetc(maps)) != EOF)
        if (ch == '\n') lines++;
    fclose(maps);
    return lines;
}

static int mode_cycles(int argc, char **argv) {
    if (argc < 7) usage(argv[0]);
    long n = parse_count(argv[2], argv[0]), n_steps = parse_count(argv[3], argv[0]);
    Fmu fmus[MAX_FMUS];
    int count = 0;
    for (int a = 4; a < argc;) {
        if (count == MAX_FMUS) usage(argv[0]);
        parse_fmu(argc, argv, &a, &fmus[count++]);
    }
    fmi2Real values[MAX_REFS];
    char name[64];
    for (long cycle = 0; cycle < n; cycle++) {
        for (int i = 0; i < count; i++) {
            Fmu *fmu = &fmus[i];
            snprintf(name, sizeof name, "cycle%ld_%d", cycle, i);
            load(fmu);
            fmi2Component c = start(fmu, name);
            steps(fmu, c, n_steps, NULL);
            must("fmi2GetReal", fmu->api.getReal(c, fmu->reads, fmu->n_reads, values));
            state_round_trip(fmu, c);
            finish(fmu, c);
            unload(fmu);
        }
    }
    printf("cycles done\n");
    return 0;
}

/* "MODE N FMU": the count N and the one loaded FMU (usage unless the count is at least min). */
static long count_and_fmu(int argc, char **argv, long min, Fmu *fmu) {
    if (argc < 6) usage(argv[0]);
    long n = parse_count(argv[2], argv[0]);
    int a = 3;
    parse_fmu(argc, argv, &a, fmu);
    if (a != argc || n < min) usage(argv[0]);
    load(fmu);
    return n;
}

static void instance_cycle(Fmu *fmu) {
    fmi2Component c = start(fmu, "rss");
    steps(fmu, c, CYCLE_STEPS, NULL);
    finish(fmu, c);
}

static int mode_rss(int argc, char **argv) {
    Fmu fmu;
    long n = count_and_fmu(argc, argv, 1, &fmu);
    for (int k = 0; k < WARM_UP; k++) instance_cycle(&fmu);
    double before = resident_bytes();
    for (long k = 0; k < n; k++) instance_cycle(&fmu);
    double after = resident_bytes();
    printf("rss_bytes_per_cycle %.6g\n", (after - before) / (double)n);
    unload(&fmu);
    return 0;
}

static void reload_cycle(Fmu *fmu) {
    load(fmu);
    instance_cycle(fmu);
    unload(fmu);
}

static int mode_reload(int argc, char **argv) {
    Fmu fmu;
    long n = count_and_fmu(argc, argv, 1, &fmu);
    unload(&fmu);
    for (int k = 0; k < WARM_UP; k++) reload_cycle(&fmu);
    double before = resident_bytes();
    for (long k = 0; k < n; k++) reload_cycle(&fmu);
    double after = resident_bytes();
    printf("rss_bytes_per_reload %.6g\n", (after - before) / (double)n);
    return 0;
}

typedef struct {
    Fmu *fmu;
    int index;
    pthread_barrier_t *barrier;  /* NULL when run in the main thread */
    fmi2Real values[MAX_REFS];
} Worker;

static void *work(void *argument) {
    Worker *worker = argument;
    char name[32];
    snprintf(name, sizeof name, "thread%d", worker->index);
    if (worker->barrier) pthread_barrier_wait(worker->barrier);  /* instantiate together */
    fmi2Component c = start(worker->fmu, name);
    if (worker->barrier) pthread_barrier_wait(worker->barrier);  /* and step together */
    steps(worker->fmu, c, THREAD_STEPS, worker->values);
    finish(worker->fmu, c);
    return NULL;
}

static int mode_threads(int argc, char **argv, int threaded) {
    Fmu fmus[2];
    int a = 2;
    parse_fmu(argc, argv, &a, &fmus[0]);
    parse_fmu(argc, argv, &a, &fmus[1]);
    if (a != argc) usage(argv[0]);
    load(&fmus[0]);
    load(&fmus[1]);  /* the same handle, counted twice, when both are one FMU */
    pthread_barrier_t barrier;
    Worker workers[2];
    pthread_t threads[2];
    if (threaded && pthread_barrier_init(&barrier, NULL, 2) != 0) {
        fprintf(stderr, "pthread_barrier_init failed\n");
        return 3;
    }
    for (int i = 0; i < 2; i++) {
        workers[i] = (Worker){&fmus[i], i, threaded ? &barrier : NULL, {0}};
        if (!threaded) {
            work(&workers[i]);
        } else if (pthread_create(&threads[i], NULL, work, &workers[i]) != 0) {
            fprintf(stderr, "pthread_create failed\n");
            return 3;
        }
    }
    if (threaded) {
        for (int i = 0; i < 2; i++) pthread_join(threads[i], NULL);
        pthread_barrier_destroy(&barrier);
    }
    for (int i = 0; i < 2; i++)
        for (size_t r = 0; r < fmus[i].n_reads; r++)
            printf("thread %d value %.17g\n", i, workers[i].values[r]);
    unload(&fmus[1]);
    unload(&fmus[0]);
    return 0;
}

typedef struct {
    Fmu *fmu;
    fmi2Component c;
} Reader;

static void *read_once(void *argument) {
    Reader *reader = argument;
    fmi2Real values[MAX_REFS];
    must("fmi2GetReal", reader->fmu->api.getReal(reader->c, reader->fmu->reads,
                                                  reader->fmu->n_reads, values));
    return NULL;
}

static void short_threads(Reader *reader, long n) {
    for (long k = 0; k < n; k++) {
        pthread_t thread;
        if (pthread_create(&thread, NULL, read_once, reader) != 0) {
            fprintf(stderr, "pthread_create failed after %ld threads\n", k);
            exit(3);
        }
        pthread_join(thread, NULL);
    }
}

static int mode_short_threads(int argc, char **argv) {
    Fmu fmu;
    long n = count_and_fmu(argc, argv, 1, &fmu);
    Reader reader = {&fmu, start(&fmu, "main")};
    short_threads(&reader, WARM_UP);
    double before = resident_bytes();
    short_threads(&reader, n);
    double after = resident_bytes();
    printf("rss_bytes_per_thread %.6g\n", (after - before) / (double)n);
    finish(&fmu, reader.c);
    unload(&fmu);
    return 0;
}

static void expect_fatal(const char *function, fmi2Status status, long instance) {
    if (status == fmi2Fatal) return;
    fprintf(stderr, "instance %ld: %s returned status %d, not fmi2Fatal\n", instance,
            function, status);
    _exit(1);
}

static int mode_fatal(int argc, char **argv) {
    Fmu fmu;
    long n = count_and_fmu(argc, argv, FATAL_FIRST, &fmu), first = -1;
    fmi2Real values[MAX_REFS];
    for (long k = 0; k < n; k++) {
        fmi2Component c = start(&fmu, "fatal");
        expect_fatal("fmi2DoStep", fmu.api.doStep(c, 0.0, STEP, fmi2True), k);
        expect_fatal("fmi2DoStep (again)", fmu.api.doStep(c, 0.0, STEP, fmi2True), k);
        expect_fatal("fmi2GetReal", fmu.api.getReal(c, fmu.reads, fmu.n_reads, values), k);
        fmu.api.freeInstance(c);
        if (k + 1 == FATAL_FIRST) first = mappings();
    }
    printf("maps_first %ld\nmaps_last %ld\n", first, mappings());
    unload(&fmu);
    return 0;
}

static int mode_instantiate(int argc, char **argv) {
    int a = 2, after_terminate = 0;
    Fmu fmu;
    parse_fmu(argc, argv, &a, &fmu);
    const char *name = "instantiate", *guid = fmu.guid, *uri = fmu.uri;
    fmi2Type type = fmi2CoSimulation;
    for (; a < argc; a++) {
        const char *flag = argv[a];
        int has_value = a + 1 < argc;
        if (strcmp(flag, "--uri") == 0 && has_value) uri = argv[++a];
        else if (strcmp(flag, "--guid") == 0 && has_value) guid = argv[++a];
        else if (strcmp(flag, "--type") == 0 && has_value && strcmp(argv[a + 1], "me") == 0)
            type = fmi2ModelExchange, a++;
        else if (strcmp(flag, "--type") == 0 && has_value && strcmp(argv[a + 1], "cs") == 0)
            type = fmi2CoSimulation, a++;
        else if (strcmp(flag, "--null-name") == 0) name = NULL;
        else if (strcmp(flag, "--null-guid") == 0) guid = NULL;
        else if (strcmp(flag, "--null-uri") == 0) uri = NULL;
        else if (strcmp(flag, "--after-terminate") == 0) after_terminate = 1;
        else usage(argv[0]);
    }
    load(&fmu);
    fmi2Component c = fmu.api.instantiate(name, type, guid, uri, &callbacks, fmi2False,
                                          fmi2True);
    if (!c) {
        printf("instance NULL\n");
        fflush(stdout);
        unload(&fmu);
        return 0;
    }
    printf("instance OK\n");
    fflush(stdout);
    fmi2Status worst = fmi2OK, status;
#define CALL(label, call) \
    status = (call); \
    printf("%s status %d\n", label, status); \
    fflush(stdout); \
    if (status > worst) worst = status;
    CALL("setupExperiment", fmu.api.setupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0))
    if (worst <= fmi2Warning) {
        CALL("enterInitializationMode", fmu.api.enterInitializationMode(c))
        CALL("set", set_values(&fmu, c))
        CALL("exitInitializationMode", fmu.api.exitInitializationMode(c))
    }
    fmi2Real values[MAX_REFS];
    if (worst <= fmi2Warning) {
        CALL("doStep", fmu.api.doStep(c, 0.0, STEP, fmi2True))
        if (status <= fmi2Warning) {
            CALL("getReal", fmu.api.getReal(c, fmu.reads, fmu.n_reads, values))
            if (status <= fmi2Warning)
                for (size_t r = 0; r < fmu.n_reads; r++) printf("value %.17g\n", values[r]);
        }
    }
    if (worst < fmi2Fatal) {
        fmi2Status run = worst;
        CALL("terminate", fmu.api.terminate(c))
        if (after_terminate) {
            status = fmu.api.doStep(c, STEP, STEP, fmi2True);
            printf("doStep after terminate status %d\n", status);
        }
        if (run <= fmi2Warning && worst <= fmi2Warning) printf("run OK\n");
    }
    fflush(stdout);
    fmu.api.freeInstance(c);
    unload(&fmu);
    return 0;
#undef CALL
}

/* ---- Model Exchange ---------------------------------------------------------------------- */
typedef struct {
    fmi2SetTimeTYPE *setTime;
    fmi2SetContinuousStatesTYPE *setContinuousStates;
    fmi2GetContinuousStatesTYPE *getContinuousStates;
    fmi2GetDerivativesTYPE *getDerivatives;
    fmi2GetEventIndicatorsTYPE *getEventIndicators;
    fmi2GetNominalsOfContinuousStatesTYPE *getNominals;
    fmi2EnterEventModeTYPE *enterEventMode;
    fmi2NewDiscreteStatesTYPE *newDiscreteStates;
    fmi2EnterContinuousTimeModeTYPE *enterContinuousTimeMode;
    fmi2CompletedIntegratorStepTYPE *completedIntegratorStep;
} MeApi;

#define LOAD_ME(field, name) \
    if (!(me->field = (name##TYPE *)dlsym(fmu->lib, #name))) { \
        fprintf(stderr, "%s: missing %s\n", fmu->path, #name); \
        exit(3); \
    }

static void load_me(Fmu *fmu, MeApi *me) {
    LOAD_ME(setTime, fmi2SetTime)
    LOAD_ME(setContinuousStates, fmi2SetContinuousStates)
    LOAD_ME(getContinuousStates, fmi2GetContinuousStates)
    LOAD_ME(getDerivatives, fmi2GetDerivatives)
    LOAD_ME(getEventIndicators, fmi2GetEventIndicators)
    LOAD_ME(getNominals, fmi2GetNominalsOfContinuousStates)
    LOAD_ME(enterEventMode, fmi2EnterEventMode)
    LOAD_ME(newDiscreteStates, fmi2NewDiscreteStates)
    LOAD_ME(enterContinuousTimeMode, fmi2EnterContinuousTimeMode)
    LOAD_ME(completedIntegratorStep, fmi2CompletedIntegratorStep)
}

/* Event mode until the event is settled, then continuous-time mode. */
static void settle(const MeApi *me, fmi2Component c) {
    fmi2EventInfo info;
    do must("fmi2NewDiscreteStates", me->newDiscreteStates(c, &info));
    while (info.newDiscreteStatesNeeded);
    must("fmi2EnterContinuousTimeMode", me->enterContinuousTimeMode(c));
}

/* A hostile call must return fmi2Error (never crash): else report it and exit 1. */
static void refused(const char *what, fmi2Status status) {
    if (status != fmi2Error) {
        fprintf(stderr, "hostile call %s returned status %d, not fmi2Error\n", what, status);
        _exit(1);
    }
}

static int mode_me_cycles(int argc, char **argv) {
    if (argc < 9) usage(argv[0]);
    long n = parse_count(argv[2], argv[0]), n_steps = parse_count(argv[3], argv[0]);
    size_t nx = (size_t)parse_count(argv[4], argv[0]), nz = (size_t)atol(argv[5]);
    Fmu fmu;
    MeApi me;
    int a = 6;
    parse_fmu(argc, argv, &a, &fmu);
    if (a != argc || nx + 1 > MAX_REFS || nz + 1 > MAX_REFS) usage(argv[0]);
    fmi2Real x[MAX_REFS], dx[MAX_REFS], z[MAX_REFS], nominal[MAX_REFS];
    char name[64];
    for (long cycle = 0; cycle < n; cycle++) {
        load(&fmu);
        load_me(&fmu, &me);
        snprintf(name, sizeof name, "me%ld", cycle);
        fmi2Component c = fmu.api.instantiate(name, fmi2ModelExchange, fmu.guid, fmu.uri,
                                              &callbacks, fmi2False, fmi2True);
        if (!c) {
            fprintf(stderr, "fmi2Instantiate (Model Exchange) returned NULL\n");
            _exit(1);
        }
        must("fmi2SetupExperiment", fmu.api.setupExperiment(c, fmi2False, 0.0, 0.0, fmi2False,
                                                            0.0));
        must("fmi2EnterInitializationMode", fmu.api.enterInitializationMode(c));
        must("fmi2SetReal/fmi2SetInteger", set_values(&fmu, c));
        must("fmi2ExitInitializationMode", fmu.api.exitInitializationMode(c));
        must("fmi2GetNominalsOfContinuousStates", me.getNominals(c, nominal, nx));
        settle(&me, c);
        double t = 0.0;
        for (long k = 0; k < n_steps; k++) {
            fmi2Boolean enter = fmi2False, terminate = fmi2False;
            must("fmi2GetContinuousStates", me.getContinuousStates(c, x, nx));
            must("fmi2GetDerivatives", me.getDerivatives(c, dx, nx));
            t += STEP;
            for (size_t i = 0; i < nx; i++) x[i] += STEP * dx[i];
            must("fmi2SetTime", me.setTime(c, t));
            must("fmi2SetContinuousStates", me.setContinuousStates(c, x, nx));
            must("fmi2GetEventIndicators", me.getEventIndicators(c, z, nz));
            must("fmi2CompletedIntegratorStep",
                 me.completedIntegratorStep(c, fmi2True, &enter, &terminate));
            if (enter || k % 100 == 99) {   /* a step event, and a time event every 0.1 s */
                must("fmi2EnterEventMode", me.enterEventMode(c));
                settle(&me, c);
            }
        }
        must("fmi2GetReal", fmu.api.getReal(c, fmu.reads, fmu.n_reads, x));
        state_round_trip(&fmu, c);
        /* hostile calls, each refused with fmi2Error and a message; an error leaves the
         * instance in the error state, so the FMU state taken before puts it back (and in
         * Continuous-Time Mode) for the next */
        fmi2FMUstate before = NULL;
        must("fmi2GetFMUstate", fmu.api.getFMUstate(c, &before));
        must("fmi2GetContinuousStates", me.getContinuousStates(c, x, nx));
        refused("fmi2GetDerivatives nx + 1", me.getDerivatives(c, dx, nx + 1));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        refused("fmi2GetEventIndicators ni + 1", me.getEventIndicators(c, z, nz + 1));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        refused("fmi2SetContinuousStates NULL", me.setContinuousStates(c, NULL, nx));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        x[0] = 0.0 / 0.0;
        refused("fmi2SetContinuousStates NaN", me.setContinuousStates(c, x, nx));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        refused("fmi2SetTime before the last event", me.setTime(c, -1.0));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        refused("fmi2DoStep on a Model Exchange instance",
                fmu.api.doStep(c, t, STEP, fmi2True));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        fmi2EventInfo info;
        refused("fmi2NewDiscreteStates in Continuous-Time Mode", me.newDiscreteStates(c, &info));
        must("fmi2SetFMUstate", fmu.api.setFMUstate(c, before));
        must("fmi2GetDerivatives", me.getDerivatives(c, dx, nx));  /* alive and usable */
        must("fmi2FreeFMUstate", fmu.api.freeFMUstate(c, &before));
        fmu.api.freeInstance(c);
        unload(&fmu);
    }
    printf("me cycles done\n");
    return 0;
}

extern char **environ;

static int in_list(char **list, const char *entry) {
    for (; *list; list++)
        if (strcmp(*list, entry) == 0) return 1;
    return 0;
}

static int mode_environment(int argc, char **argv) {
    Fmu fmu;
    int a = 2, program = argc;
    parse_fmu(argc, argv, &a, &fmu);
    if (a < argc && strcmp(argv[a], "--") == 0 && a + 1 < argc) program = a + 1;
    else if (a != argc) usage(argv[0]);
    size_t count = 0;
    while (environ[count]) count++;
    char **before = calloc(count + 1, sizeof *before);
    for (size_t i = 0; i < count; i++) before[i] = strdup(environ[i]);
    load(&fmu);
    fmi2Component c = start(&fmu, "environment");
    steps(&fmu, c, 10, NULL);
    finish(&fmu, c);
    int same = 1;
    for (char **entry = environ; *entry; entry++)
        if (!in_list(before, *entry)) printf("added %s\n", *entry), same = 0;
    for (size_t i = 0; i < count; i++)
        if (!in_list(environ, before[i])) printf("removed %s\n", before[i]), same = 0;
    printf("environment %s\n", same ? "unchanged" : "changed");
    fflush(stdout);
    if (program < argc) {
        pid_t child = fork();
        if (child == 0) {
            execv(argv[program], &argv[program]);
            _exit(127);
        }
        int status = 0;
        waitpid(child, &status, 0);
        printf("child exit %d\n", WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    }
    for (size_t i = 0; i < count; i++) free(before[i]);
    free(before);
    unload(&fmu);
    return 0;
}

/* The host's own Python: run code in it (the host's thread taking the GIL); 0 when done. */
static int host_python(void *python, const char *code) {
    int (*initialized)(void) = (int (*)(void))dlsym(python, "Py_IsInitialized");
    int (*ensure)(void) = (int (*)(void))dlsym(python, "PyGILState_Ensure");
    void (*release)(int) = (void (*)(int))dlsym(python, "PyGILState_Release");
    int (*run)(const char *) = (int (*)(const char *))dlsym(python, "PyRun_SimpleString");
    if (!initialized || !ensure || !release || !run || !initialized()) return -1;
    int gil = ensure();
    int failed = run(code);
    release(gil);
    return failed;
}

static int mode_beside(int argc, char **argv) {
    if (argc < 8) usage(argv[0]);
    int lazy = strcmp(argv[3], "lazy") == 0, started = strcmp(argv[4], "start") == 0;
    if ((!lazy && strcmp(argv[3], "now") != 0) || (!started && strcmp(argv[4], "idle") != 0))
        usage(argv[0]);
    void *python = dlopen(argv[2], (lazy ? RTLD_LAZY : RTLD_NOW) | RTLD_LOCAL);
    if (!python) {
        fprintf(stderr, "%s\n", dlerror());
        return 3;
    }
    if (started) {  /* as an embedding host does: start it, then let other threads in */
        void (*initialize)(int) = (void (*)(int))dlsym(python, "Py_InitializeEx");
        void *(*save)(void) = (void *(*)(void))dlsym(python, "PyEval_SaveThread");
        if (!initialize || !save) return 3;
        initialize(0);
        save();
        if (host_python(python, "import sys\nassert sum([1, 1]) == 2\n") != 0)
            return 1;
    }
    Fmu fmu;
    int a = 5;
    parse_fmu(argc, argv, &a, &fmu);
    if (a != argc) usage(argv[0]);
    load(&fmu);
    fmi2Real values[MAX_REFS];
    fmi2Component c = start(&fmu, "beside");
    steps(&fmu, c, 100, NULL);
    must("fmi2GetReal", fmu.api.getReal(c, fmu.reads, fmu.n_reads, values));
    for (size_t r = 0; r < fmu.n_reads; r++) printf("value %.17g\n", values[r]);
    finish(&fmu, c);
    unload(&fmu);
    if (started || host_python(python, "pass") == 0) {
        int failed = host_python(python, "import json, math\n"
                                         "assert json.loads(json.dumps([math.pi]))[0] == math.pi\n");
        printf("host python %s\n", failed == 0 ? "OK" : "failed");
    }
    fflush(stdout);
    return 0;
}

typedef struct {
    Fmu *fmu;
    fmi2Component c;
    volatile int stop, steps;
} Stepper;

static void *step_until_stopped(void *argument) {
    Stepper *stepper = argument;
    fmi2Real value;
    for (long k = 0; !stepper->stop; k++) {
        must("fmi2DoStep", stepper->fmu->api.doStep(stepper->c, (double)k * STEP, STEP,
                                                    fmi2True));
        must("fmi2GetReal", stepper->fmu->api.getReal(stepper->c, stepper->fmu->reads, 1,
                                                      &value));
        stepper->steps++;
    }
    return NULL;
}

static int mode_fork(int argc, char **argv) {
    Fmu fmus[2];
    if (argc < 6) usage(argv[0]);
    long n = parse_count(argv[2], argv[0]);
    int a = 3;
    parse_fmu(argc, argv, &a, &fmus[0]);
    Fmu *second = &fmus[0];
    if (a < argc) parse_fmu(argc, argv, &a, second = &fmus[1]);
    if (a != argc) usage(argv[0]);
    load(&fmus[0]);
    if (second != &fmus[0]) load(second);
    Fmu fmu = *second;  /* the children's */
    fmi2Component other = start(&fmu, "forked");
    Stepper stepper = {&fmus[0], start(&fmus[0], "stepping"), 0, 0};
    pthread_t thread;
    if (pthread_create(&thread, NULL, step_until_stopped, &stepper) != 0) return 3;
    while (stepper.steps < 10) usleep(1000);  /* the thread is in its calls by now */
    long finished = 0;
    for (long k = 0; k < n; k++) {
        fflush(stdout);
        fflush(stderr);
        pid_t child = fork();
        if (child < 0) return 3;
        if (child == 0) {  /* a second thread was inside an FMU call at the fork */
            fmi2Real value;
            alarm(10);
            int ok = fmu.api.doStep(other, 0.0, STEP, fmi2True) == fmi2OK &&
                     fmu.api.getReal(other, fmu.reads, 1, &value) == fmi2OK;
            _exit(ok ? 0 : 1);
        }
        int status = 0;
        waitpid(child, &status, 0);
        finished += WIFEXITED(status) && WEXITSTATUS(status) == 0;
    }
    stepper.stop = 1;
    pthread_join(thread, NULL);
    printf("children finished %ld of %ld\n", finished, n);
    finish(&fmus[0], stepper.c);
    finish(second, other);
    if (second != &fmus[0]) unload(second);
    unload(&fmus[0]);
    fflush(stdout);
    pid_t child = fork();  /* no handler of an unloaded runtime may run */
    if (child == 0) _exit(0);
    int status = -1;
    if (child > 0) waitpid(child, &status, 0);
    printf("fork after unloading: %s\n", status == 0 ? "OK" : "failed");
    return 0;
}

static int mode_huge_nvr(int argc, char **argv) {
    Fmu fmu;
    int a = 2;
    parse_fmu(argc, argv, &a, &fmu);
    if (a != argc) usage(argv[0]);
    load(&fmu);
    fmi2Component c = start(&fmu, "huge");
    steps(&fmu, c, 1, NULL);
    fmi2Real value = 0.0;
    const size_t huge = (size_t)1 << 40;
    printf("setReal huge status %d\n", fmu.api.setReal(c, fmu.reads, huge, &value));
    printf("getReal huge status %d\n", fmu.api.getReal(c, fmu.reads, huge, &value));
    printf("getReal status %d\n", fmu.api.getReal(c, fmu.reads, 1, &value));
    fmu.api.freeInstance(c);
    unload(&fmu);
    return 0;
}

static int mode_reentrant(int argc, char **argv) {
    Fmu fmu;
    long limit = argc > 2 ? strtol(argv[2], NULL, 10) : 0;
    int a = 3;
    parse_fmu(argc, argv, &a, &fmu);
    if (a != argc) usage(argv[0]);
    load(&fmu);
    const fmi2CallbackFunctions reentrant = {reentrant_logger, calloc, free, NULL, NULL};
    fmi2Component c = fmu.api.instantiate("reentrant", fmi2CoSimulation, fmu.guid, fmu.uri,
                                          &reentrant, fmi2False, fmi2True);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate returned NULL\n");
        return 1;
    }
    must("fmi2SetupExperiment", fmu.api.setupExperiment(c, fmi2False, 0.0, 0.0, fmi2False,
                                                        0.0));
    must("fmi2EnterInitializationMode", fmu.api.enterInitializationMode(c));
    must("fmi2SetReal/fmi2SetInteger", set_values(&fmu, c));
    must("fmi2ExitInitializationMode", fmu.api.exitInitializationMode(c));
    reentry.fmu = &fmu;
    reentry.c = c;
    reentry.limit = limit;
    fmi2Status status = fmu.api.doStep(c, 0.0, STEP, fmi2True);
    reentry.c = NULL;
    printf("doStep status %d\n", status);
    fmu.api.freeInstance(c);
    unload(&fmu);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 2) usage(argv[0]);
    const char *mode = argv[1];
    if (strcmp(mode, "cycles") == 0) return mode_cycles(argc, argv);
    if (strcmp(mode, "rss") == 0) return mode_rss(argc, argv);
    if (strcmp(mode, "reload") == 0) return mode_reload(argc, argv);
    if (strcmp(mode, "threads") == 0) return mode_threads(argc, argv, 1);
    if (strcmp(mode, "serial") == 0) return mode_threads(argc, argv, 0);
    if (strcmp(mode, "short-threads") == 0) return mode_short_threads(argc, argv);
    if (strcmp(mode, "fatal") == 0) return mode_fatal(argc, argv);
    if (strcmp(mode, "instantiate") == 0) return mode_instantiate(argc, argv);
    if (strcmp(mode, "me-cycles") == 0) return mode_me_cycles(argc, argv);
    if (strcmp(mode, "reentrant") == 0) return mode_reentrant(argc, argv);
    if (strcmp(mode, "environment") == 0) return mode_environment(argc, argv);
    if (strcmp(mode, "beside") == 0) return mode_beside(argc, argv);
    if (strcmp(mode, "fork") == 0) return mode_fork(argc, argv);
    if (strcmp(mode, "huge-nvr") == 0) return mode_huge_nvr(argc, argv);
    usage(argv[0]);
    return 2;
}
