"""What the harness's FMI layer does that is FMI 2.0's: FMPy's FMI 2.0 instances and calls
(`instances`), the FMI 2.0 parts of an FMU's build (`build`) and a minimal FMI 2.0 host in C
(`fmi2_host.c`), under the version-neutral modules of harness.fmu."""
