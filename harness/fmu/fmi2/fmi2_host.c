/* A minimal FMI 2.0 co-simulation host in C: no Python in the process.
 *
 * It stands for the importing tools that are not Python processes (libcosim's CLI,
 * OMSimulator, Simulink): it loads an unzipped FMU's binary, runs it from 0 to stop_time
 * with a fixed step and prints the final values of the given Real value references, one per
 * line. Arguments VR=VALUE set a Real (a parameter) before initialisation instead. Every
 * call that fails is reported on stderr as "<function> returned status <N>".
 *
 * usage: fmi2_host [-k] [-b INPUT_VR] UNZIPPED_DIR MODEL_IDENTIFIER GUID STOP_TIME STEP_SIZE
 *                  [VR=VALUE]... VR...
 *   -k           keep going after a failed call: after a failed initialisation or step, make
 *                one fmi2DoStep and one fmi2GetReal per output anyway (exit status 8)
 *   -b INPUT_VR  benchmark: at every step set INPUT_VR to 0, step, read all outputs in one
 *                fmi2GetReal, as harness.bench does in FMPy; prints the process CPU time per
 *                step on stderr as "cpu_seconds_per_step <T>"
 * build: cc -I<fmpy>/c-code fmi2_host.c -ldl -o fmi2_host
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "fmi2Functions.h"

#define MAX_OUTPUTS 64

static int keep_going, failures;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list args;
    (void)env;
    va_start(args, message);
    fprintf(stderr, "[%s] %s status %d: ", category, instance, status);
    vfprintf(stderr, message, args);
    fprintf(stderr, "\n");
    va_end(args);
}

/* Report a failed call; true when the host must stop there. */
static int failed(const char *function, fmi2Status status) {
    if (status <= fmi2Warning) return 0;
    fprintf(stderr, "%s returned status %d\n", function, status);
    failures++;
    return !keep_going;
}

static double cpu_seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
    return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}

#define LOAD(type, name) \
    type *name = (type *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 3; }

int main(int argc, char **argv) {
    int first = 1, bench = 0;
    fmi2ValueReference input = 0;
    for (; first < argc && argv[first][0] == '-'; first++) {
        if (strcmp(argv[first], "-k") == 0) keep_going = 1;
        else if (strcmp(argv[first], "-b") == 0 && first + 1 < argc) {
            bench = 1;
            input = (fmi2ValueReference)atoi(argv[++first]);
        } else break;
    }
    if (argc - first < 5) {
        fprintf(stderr, "usage: %s [-k] [-b INPUT_VR] DIR MODEL GUID STOP_TIME STEP_SIZE "
                        "[VR=VALUE]... VR...\n", argv[0]);
        return 2;
    }
    const char *dir = argv[first], *model = argv[first + 1], *guid = argv[first + 2];
    double stop = atof(argv[first + 3]), h = atof(argv[first + 4]);
    char path[4096], uri[4096];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, model);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    fmi2ValueReference outputs[MAX_OUTPUTS];
    size_t n_outputs = 0;
    for (int a = first + 5; a < argc; a++)
        if (!strchr(argv[a], '=') && n_outputs < MAX_OUTPUTS)
            outputs[n_outputs++] = (fmi2ValueReference)atoi(argv[a]);

    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 3; }
    LOAD(fmi2InstantiateTYPE, fmi2Instantiate)
    LOAD(fmi2SetupExperimentTYPE, fmi2SetupExperiment)
    LOAD(fmi2EnterInitializationModeTYPE, fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationModeTYPE, fmi2ExitInitializationMode)
    LOAD(fmi2DoStepTYPE, fmi2DoStep)
    LOAD(fmi2GetRealTYPE, fmi2GetReal)
    LOAD(fmi2SetRealTYPE, fmi2SetReal)
    LOAD(fmi2TerminateTYPE, fmi2Terminate)
    LOAD(fmi2FreeInstanceTYPE, fmi2FreeInstance)
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("native", fmi2CoSimulation, guid, uri, &callbacks,
                                      fmi2False, fmi2True);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 4; }
    if (failed("fmi2SetupExperiment", fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2True,
                                                          stop))) return 5;
    for (int a = first + 5; a < argc; a++) {
        char *eq = strchr(argv[a], '=');
        if (!eq) continue;
        fmi2ValueReference vr = (fmi2ValueReference)atoi(argv[a]);
        fmi2Real value = atof(eq + 1);
        if (failed("fmi2SetReal", fmi2SetReal(c, &vr, 1, &value))) return 5;
    }
    if (failed("fmi2EnterInitializationMode", fmi2EnterInitializationMode(c)) ||
        failed("fmi2ExitInitializationMode", fmi2ExitInitializationMode(c))) return 5;
    long n = failures ? 1 : (long)(stop / h + 0.5);
    fmi2Real values[MAX_OUTPUTS], zero = 0.0;
    double start = cpu_seconds();
    for (long k = 0; k < n; k++) {
        if (bench && failed("fmi2SetReal", fmi2SetReal(c, &input, 1, &zero))) return 6;
        fmi2Status status = fmi2DoStep(c, k * h, h, fmi2True);
        if (failed("fmi2DoStep", status)) return 6;
        if (status > fmi2Warning) break;
        if (bench && failed("fmi2GetReal", fmi2GetReal(c, outputs, n_outputs, values))) return 7;
    }
    if (bench) fprintf(stderr, "cpu_seconds_per_step %.9g\n", (cpu_seconds() - start) / n);
    for (size_t i = 0; i < n_outputs; i++) {
        fmi2Real value;
        fmi2Status status = fmi2GetReal(c, &outputs[i], 1, &value);
        if (failed("fmi2GetReal", status)) return 7;
        if (status <= fmi2Warning) printf("%.17g\n", value);
    }
    if (failures) return 8;
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    return 0;
}
