"""The step-cost benchmarks: an FMU's step in FMPy against the floors and in the C host, a
co-simulation's steps, and the master's share of a run (see harness.bench)."""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from fmpy import read_model_description

from fmu_src.mechanism import Port
from harness import registry, scenarios
from harness.engines import fmpy_master
from harness.engines.fmpy_master import DriveStep, run_steps
from harness.engines.plan import RunPlan, prepare
from harness.engines.result import RunResult
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

FLOOR_SOURCE_DIR = fmu_build.SOURCE_DIR / "bench_floor"
FLOOR_BUILD_DIR = fmu_build.DEFAULT_DEST.parent / "bench"
STEP_SIZE = 1e-3  # communication step [s], the harness default
NATIVE_HOST_SOURCE = fmu_build.HOST_SOURCE
NATIVE_HOST_BUILD = fmu_build.DEFAULT_DEST.parent / "native_host" / "fmi2_host"


@dataclass(frozen=True)
class StepLoop:
    """A timed FMU and what the master sets and reads at every step (as
    harness.engines.fmpy_master)."""

    fmu_path: Callable[[], Path]  # the built FMU (the floors are built here, the others located)
    input: str
    outputs: tuple[str, ...]


def mechanism_loop(model: str, joints: tuple[Port, ...]) -> StepLoop:
    """The master's step loop of a mechanism: its first joint's effort set (the others stay
    at their start values), every joint's position and speed read."""
    return StepLoop(lambda: fmu_build.locate(model), joints[0].effort,
                    tuple(name for joint in joints for name in (joint.position, joint.flow)))


# the mechanism FMUs (harness.registry), and the floor: the trivial slave on pythonfmu's own
# binary (the stock floor every ratio is taken to) and on our runtime
MECHANISM_LOOPS = {model: mechanism_loop(model, r.joints())
                   for model, r in registry.mechanisms().items()}
FLOOR = "BenchFloor"
FLOOR_RUNTIME = "BenchFloorRuntime"
FLOOR_MODELS = (FLOOR, FLOOR_RUNTIME)
STEP_LOOPS = {
    FLOOR: StepLoop(lambda: fmu_build.fmu_path(FLOOR, FLOOR_BUILD_DIR / "stock",
                                               FLOOR_SOURCE_DIR, runtime=False), "u", ("y",)),
    FLOOR_RUNTIME: StepLoop(
        lambda: fmu_build.fmu_path(FLOOR, FLOOR_BUILD_DIR, FLOOR_SOURCE_DIR), "u", ("y",)),
    **MECHANISM_LOOPS,
}


def seconds_per_step(fmu: CoSimFMU, loop: StepLoop, steps: int,
                     start_time: float = 0.0) -> float:
    """Mean CPU time of one step [s]: setReal(input), doStep, getReal(outputs).

    CPU time of this process, not wall time: on a shared machine other processes would
    otherwise count (pythonfmu runs the slave in the calling thread).
    """
    slave = fmu.slave
    input_ref = fmu.references([loop.input])
    output_refs = fmu.references(loop.outputs)
    value = [0.0]
    t0 = time.process_time()
    for k in range(steps):
        slave.setReal(input_ref, value)
        slave.doStep(start_time + k * STEP_SIZE, STEP_SIZE)
        slave.getReal(output_refs)
    return (time.process_time() - t0) / steps


def fmu_step(steps: int = 20_000, repeats: int = 3) -> pd.DataFrame:
    """Best-of-repeats cost of one 1 ms step per model [us] and its ratio to BenchFloor.

    The models take turns within each repeat, so drifts of the machine's speed hit both.
    """
    fmus = {name: CoSimFMU(loop.fmu_path(), instance_name=f"bench.{name}")
            for name, loop in STEP_LOOPS.items()}
    try:
        best = dict.fromkeys(fmus, float("inf"))
        for fmu in fmus.values():
            fmu.initialize()
        for repeat in range(repeats):
            for name, fmu in fmus.items():
                cost = seconds_per_step(fmu, STEP_LOOPS[name], steps, repeat * steps * STEP_SIZE)
                best[name] = min(best[name], cost)
    finally:
        for fmu in fmus.values():
            fmu.close()
    floor = best[FLOOR]
    return pd.DataFrame({
        "model": list(best),
        "step_size": STEP_SIZE,
        "steps": steps,
        "repeats": repeats,
        "us_per_step": [1e6 * cost for cost in best.values()],
        "ratio_to_floor": [cost / floor for cost in best.values()],
    })


def native_host() -> Path:
    """The C host of tests/native_host, compiled when its inputs change."""
    return fmu_build.compiled(NATIVE_HOST_SOURCE, NATIVE_HOST_BUILD)


def stock_environment() -> dict[str, str]:
    """What a host that is not a Python process needs for pythonfmu's own binary: the
    building interpreter's libpython preloaded and its prefix as PYTHONHOME."""
    library = fmu_build.libpython()
    if library is None:
        raise UserError("the stock floor needs a shared-library CPython (libpython) to run in "
                        "the C host")
    return {"LD_PRELOAD": str(library), "PYTHONHOME": sys.base_prefix}


def native_seconds_per_step(host: Path, fmu: Path, loop: StepLoop, steps: int,
                            environment: dict[str, str] | None = None) -> float:
    """Mean CPU time of one step [s] of the C host's loop over an unzipped copy of the FMU,
    from t = 0, in the given environment (default: an empty one)."""
    md = read_model_description(fmu)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    with tempfile.TemporaryDirectory(prefix="native_") as folder:
        zipfile.ZipFile(fmu).extractall(folder)
        done = subprocess.run(
            [str(host), "-b", str(refs[loop.input]), folder, md.coSimulation.modelIdentifier,
             md.guid, str(steps * STEP_SIZE), str(STEP_SIZE),
             *(str(refs[n]) for n in loop.outputs)],
            env=environment or {}, capture_output=True, text=True, check=True)
    return float(re.search(r"^cpu_seconds_per_step (\S+)$", done.stderr, re.MULTILINE).group(1))


def native_step(steps: int = 20_000, repeats: int = 3) -> pd.DataFrame:
    """Best-of-repeats cost of one 1 ms step of the floors and of each mechanism FMU [us]: in
    the C host, in FMPy, and their ratio, and the C host's cost over the stock floor's in the C
    host. Both start from the initialised FMU at t = 0, so they run the same trajectory."""
    host = native_host()
    rows = []
    for model, loop in STEP_LOOPS.items():
        environment = stock_environment() if model == FLOOR else None
        native, python = float("inf"), float("inf")
        for _ in range(repeats):
            native = min(native, native_seconds_per_step(host, loop.fmu_path(), loop, steps,
                                                         environment))
            with CoSimFMU(loop.fmu_path(), instance_name=f"bench.{model}") as fmu:
                fmu.initialize()
                python = min(python, seconds_per_step(fmu, loop, steps))
        rows.append({"model": model, "step_size": STEP_SIZE, "steps": steps,
                     "repeats": repeats, "us_per_step_c_host": 1e6 * native,
                     "us_per_step_fmpy": 1e6 * python, "ratio_c_host_to_fmpy": native / python})
    table = pd.DataFrame(rows)
    table["ratio_c_host_to_floor"] = (table.us_per_step_c_host
                                      / table.us_per_step_c_host[table.model == FLOOR].iloc[0])
    return table


def cosim(steps: int = 20_000, repeats: int = 3) -> pd.DataFrame:
    """Wall time, real-time factor and CPU time per closed-loop step of each variant of each
    shipped scenario at 1 ms, the latter against the BenchFloor step.

    Each run is timed as `make cosim` runs it (FMU instantiation included); FMU-only time is
    the run's step count times the model's best fmu_step cost where that was measured.
    """
    step_cost = (fmu_step(steps, repeats).set_index("model").us_per_step * 1e-6).to_dict()
    floor = step_cost[FLOOR]
    rows = []
    for name in scenarios.available():
        scenario = scenarios.load(name)
        for variant in scenario.variants.values():
            start, cpu_start = time.perf_counter(), time.thread_time()
            run = fmpy_master.run(prepare(scenario, variant, STEP_SIZE))
            wall, cpu = time.perf_counter() - start, time.thread_time() - cpu_start
            n_steps = round(scenario.duration / STEP_SIZE)
            rows.append({"scenario": name, "variant": variant.name, "model": run.model,
                         "simulated_s": scenario.duration, "steps": n_steps, "wall_s": wall,
                         "real_time_factor": scenario.duration / wall,
                         "fmu_only_s": n_steps * step_cost.get(run.model, float("nan")),
                         "cpu_s": cpu, "us_per_step": 1e6 * cpu / n_steps,
                         "ratio_to_floor": cpu / n_steps / floor})
    table = pd.DataFrame(rows)
    total = {"scenario": "all", "variant": "all", "model": "",
             **table[["simulated_s", "steps", "wall_s", "cpu_s"]].sum().to_dict()}
    total["real_time_factor"] = total["simulated_s"] / total["wall_s"]
    total["fmu_only_s"] = float("nan")
    total["us_per_step"] = 1e6 * total["cpu_s"] / total["steps"]
    total["ratio_to_floor"] = total["cpu_s"] / total["steps"] / floor
    return pd.concat([table, pd.DataFrame([total])], ignore_index=True)


def replay_step(effort: list[float]) -> DriveStep:
    """A drive step that gives the recorded effort[k] at step k: a joint of the master's
    loop with the PID and motor replaced by a list read."""
    def step(k: int, _position: float, _speed: float) -> float:
        return effort[k]
    return step


def replay_seconds(plan: RunPlan, run: RunResult) -> float:
    """CPU time [s] of this thread in the master's loop (`fmpy_master.run_steps`) over the
    plan's run made with keep_traces, each joint's drive step replaced by its recorded
    efforts (`replay_step`): the FMU calls (setReal of the efforts, the input changes, doStep,
    getReal of the joints' states, and the recording read every RECORD_INTERVAL) and the
    loop's own work, one call per joint and step included, with no controller and no motor;
    the FMU instantiated and initialised as in the run, untimed. RuntimeError if the replay
    does not end where the run ended."""
    with CoSimFMU(fmu_build.locate(run.model), f"replay.{plan.name}") as fmu:
        calls = fmpy_master.master_calls(plan, fmu)
        drive_steps = [replay_step(trace.effort.tolist()) for trace in run.traces]
        step_times = plan.times.tolist()
        start = time.thread_time()
        run_steps(calls, drive_steps, step_times, plan.step_size)
        seconds = time.thread_time() - start
        end = [value for trace in run.traces for value in (trace.position[-1], trace.speed[-1])]
        if calls.states[:] != end:
            raise RuntimeError(f"{plan.name}: the replay ends at {calls.states[:]}, the run "
                               f"at {end}")
        return seconds


def master_share(steps: int = 0, repeats: int = 3,
                 scenario_name: str = "franchetti2021") -> pd.DataFrame:
    """The master's share of a closed-loop step at 1 ms per variant: the CPU time of one step
    of the run (as `cosim`: set-up, controller, motor, FMU calls, recording, result assembly;
    `us_per_step`) less that of the master's loop replaying its efforts (`replay_seconds`: the
    FMU calls and the loop; `fmu_calls_us_per_step`), best of repeats each (`make bench`
    takes at least harness.bench.MASTER_SHARE_REPEATS)."""
    scenario = scenarios.load(scenario_name)
    rows = []
    for variant in scenario.variants.values():
        run_cost = fmu_cost = float("inf")
        for _ in range(repeats):
            start = time.thread_time()
            plan = prepare(scenario, variant, STEP_SIZE)
            run = fmpy_master.run(plan, keep_traces=True)
            run_cost = min(run_cost, time.thread_time() - start)
            fmu_cost = min(fmu_cost, replay_seconds(plan, run))
        n_steps = round(scenario.duration / STEP_SIZE)
        rows.append({"scenario": scenario_name, "variant": variant.name, "model": run.model,
                     "steps": n_steps, "us_per_step": 1e6 * run_cost / n_steps,
                     "fmu_calls_us_per_step": 1e6 * fmu_cost / n_steps,
                     "master_us_per_step": 1e6 * (run_cost - fmu_cost) / n_steps,
                     "master_share": (run_cost - fmu_cost) / run_cost})
    return pd.DataFrame(rows)
