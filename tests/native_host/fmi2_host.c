/* A minimal FMI 2.0 co-simulation host in C: no Python in the process.
 *
 * It stands for the importing tools that are not Python processes (libcosim's CLI,
 * OMSimulator, Simulink): it loads an unzipped FMU's binary, runs it from 0 to stop_time
 * with a fixed step and prints the final values of the given Real value references, one per
 * line. Arguments VR=VALUE set a Real (a parameter) before initialisation instead.
 *
 * usage: fmi2_host UNZIPPED_DIR MODEL_IDENTIFIER GUID STOP_TIME STEP_SIZE [VR=VALUE]... VR...
 * build: cc -I<fmpy>/c-code fmi2_host.c -ldl -o fmi2_host
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

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

#define LOAD(type, name) \
    type *name = (type *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 3; }

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: %s DIR MODEL GUID STOP_TIME STEP_SIZE VR...\n", argv[0]);
        return 2;
    }
    char path[4096], uri[4096];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", argv[1], argv[2]);
    snprintf(uri, sizeof uri, "file://%s/resources", argv[1]);
    double stop = atof(argv[4]), h = atof(argv[5]);
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
    fmi2Component c = fmi2Instantiate("native", fmi2CoSimulation, argv[3], uri, &callbacks,
                                      fmi2False, fmi2False);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 4; }
    if (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2True, stop) > fmi2Warning) return 5;
    for (int a = 6; a < argc; a++) {
        char *eq = strchr(argv[a], '=');
        if (!eq) continue;
        fmi2ValueReference vr = (fmi2ValueReference)atoi(argv[a]);
        fmi2Real value = atof(eq + 1);
        if (fmi2SetReal(c, &vr, 1, &value) > fmi2Warning) return 5;
    }
    if (fmi2EnterInitializationMode(c) > fmi2Warning ||
        fmi2ExitInitializationMode(c) > fmi2Warning) return 5;
    long n = (long)(stop / h + 0.5);
    for (long k = 0; k < n; k++)
        if (fmi2DoStep(c, k * h, h, fmi2True) > fmi2Warning) return 6;
    for (int a = 6; a < argc; a++) {
        if (strchr(argv[a], '=')) continue;
        fmi2ValueReference vr = (fmi2ValueReference)atoi(argv[a]);
        fmi2Real value;
        if (fmi2GetReal(c, &vr, 1, &value) > fmi2Warning) return 7;
        printf("%.17g\n", value);
    }
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    return 0;
}
