"""Shared set-up of the fuzz suite: hypothesis profiles and an FMU runner in a child process.

Profiles (select with the environment variable HYPOTHESIS_PROFILE):
- `ci` (default, used by `make test`): a fixed seed (derandomize) and a small example budget;
- `deep` (`make fuzz`): random seeds and 3000 examples a property, about 13 minutes in all.

FMU cases run in a child process (`FmuRunner`), so a call that never returns or crashes the
process is reported as a failure of that case instead of hanging the test session.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import time
from collections.abc import Iterator, Mapping
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

settings.register_profile("ci", max_examples=15, derandomize=True, deadline=None,
                          database=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("deep", max_examples=3000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# Hostile floats: the special values and the edges of double precision, then anything.
SPECIAL = (0.0, -0.0, 5e-324, -5e-324, 1e-300, 1e-15, 1e15, 1e50, 1e51, 1e300, -1e300,
           math.inf, -math.inf, math.nan)
hostile_floats = st.one_of(st.sampled_from(SPECIAL), st.floats(allow_nan=True,
                                                               allow_infinity=True))
# communication step sizes from 1e-15 s to 10 s, log-uniform
step_sizes = st.floats(min_value=-15.0, max_value=1.0).map(lambda e: 10.0 ** e)

CASE_TIMEOUT = 60.0   # s: a case that takes longer counts as a hang
CALL_LIMIT = 5.0      # s: the most one FMI call may take (MAX_SUBSTEPS RK4 sub-steps)
# FMPy keeps the binary of every FMU it extracted loaded, a few memory mappings each: a
# process meets the kernel's limit (vm.max_map_count, 65530) after some thousands ("failed
# to map segment" when the next FMU loads), so the child that runs the cases is replaced
# after this many.
CASES_PER_PROCESS = 500


def run_case(case: Mapping[str, Any]) -> dict[str, Any]:
    """In the child: instantiate, initialise with the case's parameters and inputs, take its
    steps. Reports statuses, messages, outputs before and after each step and call times.
    After a refused set or step the FMU state taken before it is set again, as FMI 2.0 asks
    of a host that goes on (the instance is in the error or stepFailed state until then)."""
    from harness.fmu import build as fmu_build
    from harness.fmu.loader import CoSimFMU, FMICallException

    fmu = CoSimFMU(fmu_build.fmu_path(case["model"]), "fuzz")
    report: dict[str, Any] = {"init": "ok", "steps": [], "slowest": 0.0, "restored": []}
    reals = [v.name for v in fmu.model_description.modelVariables
             if v.type == "Real" and v.causality in ("output", "calculatedParameter")]

    def timed(call: Any, *args: Any) -> str:
        start = time.perf_counter()
        try:
            call(*args)
            status = "ok"
        except FMICallException as error:
            status = f"status {error.status}"
        report["slowest"] = max(report["slowest"], time.perf_counter() - start)
        return status

    @contextlib.contextmanager
    def resumable() -> Iterator[dict[str, str]]:
        """Around a call whose status the block puts in the dict it gets: the FMU state
        before it is set again after it if the call was refused."""
        taken = fmu.slave.getFMUstate()
        outcome = {"status": "ok"}
        try:
            yield outcome
            if outcome["status"] != "ok":
                report["restored"].append(timed(fmu.slave.setFMUstate, taken))
        finally:
            fmu.slave.freeFMUstate(taken)

    try:
        report["init"] = timed(fmu.initialize, {**case["parameters"], **case["inputs"]})
        t = 0.0
        report["sets"] = []
        if report["init"] == "ok":
            for name, value in case.get("later_inputs", {}).items():
                before = fmu.get([name])[name]
                with resumable() as outcome:
                    outcome["status"] = timed(fmu.set, {name: value})
                    report["sets"].append({"name": name, "value": value,
                                           "status": outcome["status"], "before": before,
                                           "after": fmu.get([name])[name]})
            for h in case["steps"]:
                before = fmu.get(reals)
                with resumable() as outcome:
                    outcome["status"] = status = timed(fmu.step, t, h)
                    report["steps"].append({"h": h, "status": status, "before": before,
                                            "after": fmu.get(reals)})
                if status == "ok":
                    t += h
                elif status != "status 2":
                    break
        report["messages"] = [(m.status, m.message) for m in fmu.messages]
    finally:
        fmu.close()
    return report


def _serve(connection: Any) -> None:
    while True:
        case = connection.recv()
        if case is None:
            return
        try:
            connection.send(run_case(case))
        except Exception as error:  # noqa: BLE001 - reported to the parent as the case's result
            connection.send({"exception": f"{type(error).__name__}: {error}"})


class FmuRunner:
    """A child process that runs FMU cases; restarted after a hang or a crash."""

    def __init__(self) -> None:
        self._context = multiprocessing.get_context("spawn")
        self._start()

    def _start(self) -> None:
        self.cases_run = 0
        self.connection, child = self._context.Pipe()
        self.process = self._context.Process(target=_serve, args=(child,), daemon=True)
        self.process.start()

    def run(self, case: Mapping[str, Any]) -> dict[str, Any]:
        if self.cases_run == CASES_PER_PROCESS:
            self.close()
            self._start()
        self.cases_run += 1
        self.connection.send(dict(case))
        if not self.connection.poll(CASE_TIMEOUT):
            self.process.kill()
            self._start()
            raise AssertionError(f"no answer within {CASE_TIMEOUT} s (a hang): {case}")
        try:
            return self.connection.recv()
        except EOFError:
            self.process.join()
            code = self.process.exitcode
            self._start()
            raise AssertionError(f"the FMU process died (exit code {code}): {case}") from None

    def close(self) -> None:
        self.connection.send(None)
        self.process.join(10.0)
        if self.process.is_alive():
            self.process.kill()
