"""Co-simulation harness: FMPy master, drive, controller, scenarios, metrics and CLI."""
