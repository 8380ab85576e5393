"""Parameter sweeps on Dask: `python -m harness sweep SWEEP.toml`.

A sweep file (harness/sweeps/*.toml) names a scenario, its variants, parameter axes and the
metrics to keep. Each axis sets one or more paths of the run's configuration to its value:

- `parameters.L0`: an FMU parameter of the scenario (a variant's own parameters, e.g.
  `unbalanced`'s k = 0, still win; `variants.NAME.parameters.k` changes one variant);
- `motor.N`, `design.omega_c`: fields of MotorParameters and ControllerDesign;
- `phases["III regulate"].inputs.payload`: a phase input (a ramp keeps its shape and
  gets the value as its target); `phases["II move", "III regulate"].target_deg`: phase
  targets in degrees (`initial_angle_deg` likewise); `phases["V move"].duration` [s];
- `duration_scale`: every phase duration times the value (task speed);
- `0.0583 * variants.active_relocation.phase_targets["III regulate"].q`: any path preceded by
  a factor takes the axis value times it (a joint target proportional to the payload).

Axes take `values = [...]` or `range = { start, stop, num }` (inclusive). `sample = "grid"`
(default) runs the full factorial; `sample = "lhs"` draws a Latin-hypercube sample of
`samples` points (seeded by `seed`): ranges are sampled continuously over [start, stop],
value lists by stratified choice. Every point runs every listed variant.

Execution: dask.distributed, a LocalCluster of `--workers` single-threaded processes by
default (pythonfmu runs one interpreter per process, so never threads) or the cluster at
`--scheduler ADDRESS`; workers must be able to import `harness` and find built FMUs (run
`python -m harness build-fmus` there first). A task runs a chunk of runs; each worker process
keeps one instance per FMU model and resets it between runs (an instance that failed is
freed and replaced).

Results: one row per run (point and variant) with run_id, point, variant, the axis values,
status ("ok" or "failed"), error, the kept metrics, the FMU's calculated parameters (e.g.
payload_max), the final values of the mechanism outputs listed in `outputs` (NaN where the
variant's model has no such output), the number of FMU log messages and the first one, and
the wall time [s].
The client writes each finished chunk atomically as results/sweeps/<name>/part-*.parquet;
a restart skips the run_ids found there, so a killed sweep loses at most the chunks in
flight. run_id hashes the scenario definition with the run's variant, the step size and
the axis assignments, so changing any of them gives new runs (rows of runs no longer in the
plan stay in the parts but leave the tables). Failed runs are not retried on restart (bad
parameters fail again), unless `--retry-failed`. At the end every stored row of the plan
is consolidated, in plan order, into results/sweeps/<name>.parquet and .csv (atomically),
and the plots of the `[plots]` table are drawn beside them.
"""

from __future__ import annotations

import argparse
import ast
import atexit
import contextlib
import hashlib
import itertools
import json
import logging
import math
import re
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from distributed import Client, LocalCluster, WorkerPlugin, as_completed
from matplotlib.axes import Axes
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from tqdm import tqdm

from fmu_src.scenario import check_name
from harness import fmu_build, master, results, scenarios
from harness.controller import ControllerDesign
from harness.drive import MotorParameters
from harness.errors import UserError
from harness.fmi import CoSimFMU, FMUCallError
from harness.metrics import METRICS

SWEEP_DIR = Path(__file__).resolve().parent / "sweeps"
SWEEP_RESULTS_DIR = results.RESULTS_DIR / "sweeps"
DEFAULT_CHUNK = 8                  # runs per task at most
CHUNKS_PER_WORKER = 4              # at least this many tasks per worker, for load balance
MAX_RUNS = 100_000                 # runs per sweep: a plan this long takes days on a laptop
RUN_METRICS = tuple(m for m in METRICS if m != "eps")  # eps needs a baseline run
DEGREE_FIELDS = {"target_deg": "target", "initial_angle_deg": "initial_angle"}
SAVING_REGULATED, SAVING_REFERENCE = "self_regulating", "unregulated"
# [%] the plots' floor: the saving tends to -inf where E_drawn(unregulated) tends to 0
SAVING_FLOOR = -100.0


# ---- sweep definition ---------------------------------------------------------------------
@dataclass(frozen=True)
class Axis:
    """One swept quantity: the configuration paths it sets and its values or range."""

    name: str
    paths: tuple[str, ...]
    values: tuple[float, ...]                  # grid values, or LHS choices if no bounds
    bounds: tuple[float, float] | None = None  # [start, stop] of a range
    unit: str = ""

    @property
    def label(self) -> str:
        return f"{self.name} [{self.unit}]" if self.unit else self.name


@dataclass(frozen=True)
class Sweep:
    """A sweep file: the scenario and variants to run over the axes, what to keep and plot."""

    name: str
    description: str
    scenario: scenarios.Scenario
    variants: tuple[str, ...]
    axes: tuple[Axis, ...]
    metrics: tuple[str, ...]
    step_size: float = master.DEFAULT_STEP     # [s]
    sample: str = "grid"                       # "grid" or "lhs"
    samples: int = 0                           # LHS points
    seed: int = 0
    chunk_size: int = DEFAULT_CHUNK
    plots: dict[str, dict[str, Any]] = field(default_factory=dict)
    outputs: tuple[str, ...] = ()              # mechanism outputs kept at the run's end


@dataclass(frozen=True)
class Run:
    """One co-simulation of a sweep: a variant at a parameter point."""

    run_id: str
    point: str
    variant: str
    values: dict[str, float]                   # axis name -> value


def _number(value: Any, what: str) -> float:
    """A finite number from the file, else UserError naming it."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise UserError(f"{what} = {value!r} is not a finite number")
    return float(value)


def _count(value: Any, what: str, lowest: int, highest: int) -> int:
    """A whole number in [lowest, highest] from the file (2.0 counts, 2.7 does not)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            lowest <= value <= highest and float(value).is_integer()):
        raise UserError(f"{what} = {value!r} is not a whole number in [{lowest}, {highest}]")
    return int(value)


def _axis(raw: Any, where: str) -> Axis:
    if not isinstance(raw, dict):
        raise UserError(f"{where}: an axis is a table ([[axes]]), not {raw!r}")
    name = raw.get("name")
    paths = raw.get("set")
    paths = [paths] if isinstance(paths, str) else paths
    if not isinstance(name, str) or not name or not isinstance(paths, list) or not paths or not all(
            isinstance(p, str) and p.strip() for p in paths):
        raise UserError(f"{where}: an axis needs name = \"...\" and set = a path or a list of "
                        f"paths (strings); got name = {name!r}, set = {raw.get('set')!r}")
    paths = tuple(paths)
    if ("values" in raw) == ("range" in raw):
        raise UserError(f"{where}: axis {name} needs either values or range")
    if "values" in raw:
        if not isinstance(raw["values"], list) or not raw["values"]:
            raise UserError(f"{where}: axis {name} values = {raw['values']!r} must be a "
                            "non-empty list of numbers")
        values = tuple(_number(v, f"{where}: axis {name} values item") for v in raw["values"])
        range_ = None
    else:
        span = raw["range"]
        if not isinstance(span, dict) or {"start", "stop"} - set(span) or set(span) - {
                "start", "stop", "num"}:
            raise UserError(f"{where}: axis {name} range = {span!r} must be a table "
                            "{ start = number, stop = number, num = whole number }")
        start = _number(span["start"], f"{where}: axis {name} range start")
        stop = _number(span["stop"], f"{where}: axis {name} range stop")
        num = _count(span.get("num", 2), f"{where}: axis {name} range num", 1, MAX_RUNS)
        values, range_ = tuple(float(v) for v in np.linspace(start, stop, num)), (start, stop)
    repeated = sorted({v for v in values if values.count(v) > 1})
    if repeated:
        raise UserError(f"{where}: axis {name} values repeat: "
                        f"{', '.join(f'{v:g}' for v in repeated)} (runs would share run ids)")
    return Axis(name, paths, values, range_, raw.get("unit", ""))


def load(path: str | Path) -> Sweep:
    """Load a sweep file; the scenario is a name or a path relative to the sweep file."""
    path = Path(path)
    if not path.suffix:
        path = SWEEP_DIR / f"{path}.toml"
    if not path.exists():
        raise UserError(f"no sweep file {path}")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as error:
        raise UserError(f"{path.name}: not valid TOML ({error})") from None
    where = path.name
    name = data.get("name", path.stem)
    try:
        check_name(name, "name")
    except ValueError as error:
        raise UserError(f"{where}: {error}") from None
    scenario_ref = data.get("scenario")
    if not scenario_ref:
        raise UserError(f"{where}: no scenario")
    scenario = scenarios.load(path.parent / scenario_ref if Path(scenario_ref).suffix
                              else scenario_ref)
    variants = tuple(data.get("variants", scenario.variants))
    for variant in variants:
        scenario.variant(variant)
    if not data.get("axes") or not isinstance(data["axes"], list):
        raise UserError(f"{where}: no [[axes]]")
    axes = tuple(_axis(raw, f"{where} axis {i + 1}") for i, raw in enumerate(data["axes"]))
    names = [axis.name for axis in axes]
    if len(set(names)) < len(names):
        raise UserError(f"{where}: axis names repeat: {', '.join(names)}")
    for axis in axes:  # bad paths stop the sweep here; bad values are runs that fail
        try:
            configure(scenario, [(p, axis.values[0]) for p in axis.paths])
        except PathError:
            raise
        except ValueError:
            pass
    _check_first_point(scenario, variants, axes)
    metrics = tuple(data.get("metrics", RUN_METRICS))
    unknown = sorted(set(metrics) - set(RUN_METRICS))
    if unknown:
        raise UserError(f"{where}: unknown metrics {', '.join(unknown)} "
                        f"(choose from {', '.join(RUN_METRICS)})")
    sample = data.get("sample", "grid")
    if sample not in ("grid", "lhs"):
        raise UserError(f"{where}: sample = {sample!r}, not 'grid' or 'lhs'")
    samples = _count(data.get("samples", 0), f"{where}: samples", 0, MAX_RUNS)
    if sample == "lhs" and samples < 1:
        raise UserError(f"{where}: a Latin-hypercube sample needs samples >= 1")
    size = (samples if sample == "lhs" else math.prod(len(a.values) for a in axes)) * len(
        variants)
    if size > MAX_RUNS:
        raise UserError(f"{where}: {size:,} runs planned, more than {MAX_RUNS:,}: fewer axis "
                        "values or samples")
    plots = data.get("plots", {})
    for kind, spec in plots.items():
        if kind not in PLOTS:
            raise UserError(f"{where}: unknown plot {kind!r} (choose from {', '.join(PLOTS)})")
        if kind == "lines":
            _check_lines_plot(spec, names, where)
            continue
        roles = [spec.get(role) for role in ("x", "y", "lines", "panels") if spec.get(role)]
        if set(roles) - set(names) or not spec.get("x") or (kind == "map" and not spec.get("y")):
            raise UserError(f"{where}: plot {kind} needs x{' and y' if kind == 'map' else ''}"
                            f" and may have lines, panels, all axes ({', '.join(names)})")
        if "E_drawn" not in metrics or {SAVING_REGULATED, SAVING_REFERENCE} - set(variants):
            raise UserError(f"{where}: plot {kind} needs the metric E_drawn and the variants "
                            f"{SAVING_REGULATED} and {SAVING_REFERENCE}")
    step_size = _number(data.get("step_size", master.DEFAULT_STEP), f"{where}: step_size")
    if not 0.0 < step_size <= scenario.duration:
        raise UserError(f"{where}: step_size = {step_size} s is outside (0, "
                        f"{scenario.duration:g}] (the scenario's duration)")
    chunk_size = _count(data.get("chunk_size", DEFAULT_CHUNK), f"{where}: chunk_size", 1,
                        MAX_RUNS)
    seed = _count(data.get("seed", 0), f"{where}: seed", 0, 2 ** 63 - 1)
    outputs = data.get("outputs", [])
    if not isinstance(outputs, list) or not all(isinstance(n, str) for n in outputs):
        raise UserError(f"{where}: outputs = {outputs!r} is not a list of output names")
    return Sweep(name, data.get("description", ""), scenario, variants,
                 axes, metrics, step_size, sample, samples, seed, chunk_size, plots,
                 tuple(outputs))


def _check_first_point(scenario: scenarios.Scenario, variants: Sequence[str],
                       axes: Sequence[Axis]) -> None:
    """UserError naming an FMU parameter, input or model that no run can have, found on the
    first value of every axis before any run (values the model refuses still fail per run)."""
    try:
        configured, _, _ = configure(scenario, [(p, a.values[0]) for a in axes for p in a.paths])
    except PathError:
        raise
    except ValueError:
        return
    for name in variants:
        variant = configured.variant(name)
        master.check_names(configured, variant, configured.parameters | variant.parameters)


# ---- configuration paths ------------------------------------------------------------------
class PathError(UserError):
    """A set path that does not name anything in the run's configuration."""


_TOKEN = re.compile(r"\s*(?:\.?\s*([A-Za-z_]\w*)|\[([^\]]*)\])")


def _tokens(path: str) -> list[tuple[str, ...]]:
    """`phases["II move", "V move"].target_deg` -> [("phases",), ("II move", "V move"),
    ("target_deg",)]: each token names one attribute/key or a selection of names."""
    tokens, position = [], 0
    while position < len(path):
        match = _TOKEN.match(path, position)
        if not match:
            raise PathError(f"set path {path!r}: cannot read {path[position:]!r}")
        if match.group(1):
            tokens.append((match.group(1),))
        else:
            try:
                names = ast.literal_eval(f"({match.group(2)},)")
            except (ValueError, SyntaxError):
                names = None
            if not names or not all(isinstance(n, str) for n in names):
                raise PathError(f"set path {path!r}: [{match.group(2)}] is not a list of "
                                 "quoted names")
            tokens.append(tuple(names))
        position = match.end()
    return tokens


def _replace(obj: Any, tokens: list[tuple[str, ...]], value: float, path: str) -> Any:
    """A copy of obj with the element at tokens set to value (a Ramp gets a new target)."""
    if not tokens:
        return replace(obj, target=value) if isinstance(obj, scenarios.Ramp) else value
    names, rest = tokens[0], tokens[1:]
    if is_dataclass(obj):
        name = names[0]
        if name in DEGREE_FIELDS and not rest:
            name, value = DEGREE_FIELDS[name], math.radians(value)
        known = [f.name for f in fields(obj)]
        if len(names) > 1 or name not in known:
            raise PathError(f"set path {path!r}: {type(obj).__name__} has no {names[0]!r} "
                             f"(fields: {', '.join(known)})")
        return replace(obj, **{name: _replace(getattr(obj, name), rest, value, path)})
    if isinstance(obj, dict):
        if rest and set(names) - set(obj):
            raise PathError(f"set path {path!r}: no {', '.join(set(names) - set(obj))} "
                             f"(known: {', '.join(obj)})")
        return {**obj, **{n: _replace(obj.get(n), rest, value, path) for n in names}}
    if isinstance(obj, tuple) and all(hasattr(item, "name") for item in obj):
        known = [item.name for item in obj]
        if set(names) - set(known):
            raise PathError(f"set path {path!r}: no {', '.join(set(names) - set(known))} "
                             f"(known: {', '.join(known)})")
        return tuple(_replace(item, rest, value, path) if item.name in names else item
                     for item in obj)
    raise PathError(f"set path {path!r}: cannot select {names} in a {type(obj).__name__}")


def _scaled(path: str) -> tuple[str, float]:
    """`0.5 * parameters.k` -> ("parameters.k", 0.5); a path without a factor has factor 1."""
    factor, times, rest = path.partition("*")
    if not times:
        return path, 1.0
    try:
        return rest.strip(), float(factor)
    except ValueError:
        raise PathError(f"set path {path!r}: {factor.strip()!r} is not a number (write "
                        "'<factor> * <path>')") from None


def configure(scenario: scenarios.Scenario, assignments: Iterable[tuple[str, float]]
              ) -> tuple[scenarios.Scenario, MotorParameters, ControllerDesign]:
    """The scenario, motor and controller design of one run: defaults with the assignments
    (path, value) applied in order, as new objects (the given scenario is not changed)."""
    config: dict[str, Any] = {"scenario": scenario, "motor": MotorParameters(),
                              "design": ControllerDesign()}
    for path, value in assignments:
        path, factor = _scaled(path)
        value *= factor
        tokens = _tokens(path)
        head = tokens[0][0]
        if tokens == [("duration_scale",)]:
            if not (value > 0.0 and math.isfinite(value)):
                raise UserError(f"duration_scale = {value} is outside (0, inf)")
            current = config["scenario"]
            config["scenario"] = replace(current, phases=tuple(
                replace(p, duration=p.duration * value) for p in current.phases))
        elif head in ("motor", "design"):
            config[head] = _replace(config[head], tokens[1:], value, path)
        else:
            config["scenario"] = _replace(config["scenario"], tokens, value, path)
    return config["scenario"], config["motor"], config["design"]


def assignments(sweep: Sweep, values: dict[str, float]) -> list[tuple[str, float]]:
    """(path, value) of every axis at a point, in axis order."""
    return [(path, values[axis.name]) for axis in sweep.axes for path in axis.paths]


# ---- plan ---------------------------------------------------------------------------------
def points(sweep: Sweep) -> list[dict[str, float]]:
    """Parameter points: the full factorial, or a Latin-hypercube sample."""
    if sweep.sample == "grid":
        return [dict(zip((a.name for a in sweep.axes), combo, strict=True))
                for combo in itertools.product(*(a.values for a in sweep.axes))]
    rng = np.random.default_rng(sweep.seed)
    n = sweep.samples
    columns = {}
    for axis in sweep.axes:  # one stratum per sample and axis, strata shuffled per axis
        u = (rng.permutation(n) + rng.random(n)) / n
        if axis.bounds is not None:
            start, stop = axis.bounds
            columns[axis.name] = [float(start + (stop - start) * s) for s in u]
        else:
            columns[axis.name] = [axis.values[int(s * len(axis.values))] for s in u]
    return [{name: column[i] for name, column in columns.items()} for i in range(n)]


def _digest(data: Any) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def plan(sweep: Sweep) -> list[Run]:
    """Every run of the sweep, point by point and variant by variant, with stable ids.

    A run_id covers the scenario with only the run's variant (and the joints it drives,
    `Scenario.for_variant`), so adding or editing another variant of the scenario leaves
    stored runs valid."""
    scenario = sweep.scenario
    definitions = {v: repr(replace(scenario.for_variant(scenario.variant(v)),
                                   variants={v: scenario.variant(v)}))
                   for v in sweep.variants}
    runs = []
    for values in points(sweep):
        setting = {a.name: {"set": list(a.paths), "value": values[a.name]} for a in sweep.axes}
        point = _digest({"scenario": scenario.name, "step_size": sweep.step_size,
                        "axes": setting})
        runs.extend(Run(_digest({"scenario": definitions[v], "step_size": sweep.step_size,
                                 "axes": setting}), point, v, values)
                    for v in sweep.variants)
    return runs


# ---- worker side --------------------------------------------------------------------------
_FMUS: dict[str, CoSimFMU] = {}  # per worker process: model -> instance, reused across runs


def _close_fmus() -> None:
    for model in list(_FMUS):
        _discard(model)


class CloseFMUs(WorkerPlugin):
    """Frees a Dask worker's FMU instances (and their extracted files) when it closes;
    atexit does not run in worker processes."""

    name = "harness.sweep.CloseFMUs"

    def teardown(self, worker: Any) -> None:
        _close_fmus()


def _instance(model: str) -> CoSimFMU:
    """This process's instance of the model, made on first use (freed at exit)."""
    if model not in _FMUS:
        if not _FMUS:
            atexit.register(_close_fmus)
        _FMUS[model] = CoSimFMU(fmu_build.fmu_path(model), f"sweep.{model}")
    return _FMUS[model]


def warm_up(model: str) -> None:
    """Instantiate the model in this worker process (e.g. before timing a benchmark)."""
    _instance(model)


def _discard(model: str) -> None:
    """Free an instance (after a failure it may be unusable; the next run makes a new one)."""
    fmu = _FMUS.pop(model)
    try:
        fmu.close()
    except Exception:  # noqa: BLE001 - a broken instance must not stop the sweep
        pass


def run_one(sweep: Sweep, run: Run) -> dict[str, Any]:
    """Co-simulate one run; any error makes a failed row instead of an exception."""
    start = time.perf_counter()
    row: dict[str, Any] = {"run_id": run.run_id, "point": run.point, "variant": run.variant,
                           **run.values}
    model = None
    try:
        scenario, motor, design = configure(sweep.scenario, assignments(sweep, run.values))
        variant = scenario.variant(run.variant)
        model = variant.model or scenario.model
        fmu = _instance(model)
        fmu.messages.clear()
        result = master.run(scenario, variant, sweep.step_size, motor, design, fmu=fmu)
        row.update(status="ok", error="", **result.metrics,
                   **fmu.get(fmu.names("calculatedParameter")),
                   **{name: float(result.series[name].iloc[-1]) if name in result.series
                      else math.nan for name in sweep.outputs},
                   fmu_messages=len(result.messages),
                   first_message=result.messages[0] if result.messages else "")
    except Exception as error:  # noqa: BLE001 - recorded, and the sweep goes on
        details = [f"{error.__class__.__name__}: {error}"]
        if model in _FMUS:
            if not isinstance(error, FMUCallError):  # that one carries the FMU's messages
                details += [m.message for m in _FMUS[model].messages
                            if m.status in ("Error", "Fatal")]
            _discard(model)
        row.update(status="failed", error=" ".join("; ".join(details).split()))
    row["seconds"] = time.perf_counter() - start
    return row


def run_chunk(sweep: Sweep, runs: Sequence[Run]) -> list[dict[str, Any]]:
    """One Dask task: a chunk of runs in this worker process."""
    return [run_one(sweep, run) for run in runs]


# ---- stored results -----------------------------------------------------------------------
def parts_dir(sweep: Sweep, out: Path) -> Path:
    return out / sweep.name


def stored(sweep: Sweep, out: Path) -> pd.DataFrame:
    """Every row in the sweep's parts; of a run stored twice (retried), the later one."""
    parts = sorted(parts_dir(sweep, out).glob("part-*.parquet"))
    if not parts:
        return pd.DataFrame(columns=["run_id", "status"])
    table = pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True)
    return table.drop_duplicates("run_id", keep="last").reset_index(drop=True)


def _write_part(sweep: Sweep, out: Path, rows: list[dict[str, Any]]) -> Path:
    """Store finished rows atomically; part names sort in the order they were written."""
    path = parts_dir(sweep, out) / f"part-{time.time_ns():020d}-{rows[0]['run_id'][:8]}.parquet"
    frame = pd.DataFrame(rows)
    return results.write_atomic(path, lambda tmp: frame.to_parquet(tmp, index=False))


def pending(sweep: Sweep, out: Path, retry_failed: bool = False) -> list[Run]:
    """The planned runs without a stored row (or with a failed one, if retry_failed)."""
    table = stored(sweep, out)
    done = set(table.run_id if not retry_failed else table.run_id[table.status == "ok"])
    return [run for run in plan(sweep) if run.run_id not in done]


def execute(sweep: Sweep, runs: Sequence[Run], out: Path, client: Client,
            chunk_size: int | None = None, quiet: bool = False) -> tuple[int, int]:
    """Run on the Dask client, storing each finished chunk; returns (runs done, failed).

    A chunk whose task itself fails (e.g. its worker died) is stored as failed runs.
    """
    if not runs:
        return 0, 0
    workers = max(1, sum(client.nthreads().values()))
    size = chunk_size or min(sweep.chunk_size,
                             max(1, math.ceil(len(runs) / (CHUNKS_PER_WORKER * workers))))
    chunks = [list(runs[i:i + size]) for i in range(0, len(runs), size)]
    client.register_plugin(CloseFMUs())
    futures = {client.submit(run_chunk, sweep, chunk, pure=False): chunk for chunk in chunks}
    done = failed = 0
    with tqdm(total=len(runs), unit="run", disable=quiet, desc=sweep.name) as bar:
        bar.set_postfix(failed=0)
        try:
            for future in as_completed(futures):
                try:
                    rows = future.result()
                except Exception as error:  # noqa: BLE001 - the task, not a run, failed
                    rows = [{"run_id": r.run_id, "point": r.point, "variant": r.variant,
                             **r.values, "status": "failed",
                             "error": f"{error.__class__.__name__}: {error}"}
                            for r in futures[future]]
                _write_part(sweep, out, rows)
                done += len(rows)
                failed += sum(row["status"] == "failed" for row in rows)
                bar.update(len(rows))
                bar.set_postfix(failed=failed)
        finally:
            client.cancel(list(futures))
    return done, failed


def consolidate(sweep: Sweep, out: Path) -> pd.DataFrame:
    """The rows of the planned runs, in plan order, written to <name>.parquet and .csv."""
    runs = plan(sweep)
    table = stored(sweep, out).set_index("run_id")
    table = table.reindex([r.run_id for r in runs if r.run_id in table.index]).reset_index()
    axes = [a.name for a in sweep.axes]
    last = ["fmu_messages", "first_message", "seconds"]
    extra = [c for c in table.columns if c not in {"run_id", "point", "variant", "status",
                                                   "error", *last, *axes, *RUN_METRICS}]
    columns = ["run_id", "point", "variant", *axes, "status", "error", *sweep.metrics,
               *extra, *last]
    table = table.reindex(columns=columns)
    out.mkdir(parents=True, exist_ok=True)
    # both files into one temporary folder, then renamed one after the other: the window in
    # which a kill leaves them with different rows is two renames, not a whole CSV write
    with tempfile.TemporaryDirectory(dir=out, prefix=f".{sweep.name}.") as tmp:
        staged = Path(tmp)
        table.to_parquet(staged / "table.parquet", index=False)
        results.write_csv(table, staged / "table.csv")
        for suffix in ("parquet", "csv"):
            (staged / f"table.{suffix}").chmod(0o644)
            (staged / f"table.{suffix}").replace(out / f"{sweep.name}.{suffix}")
    return table


# ---- plots --------------------------------------------------------------------------------
def saving(sweep: Sweep, table: pd.DataFrame) -> pd.DataFrame:
    """Per point: the axis values, E_drawn_<variant> [J] of the two variants compared and
    saving = 1 - E_drawn(self_regulating) / E_drawn(unregulated) (NaN where a run failed)."""
    axes = [a.name for a in sweep.axes]
    drawn = table[table.status == "ok"].pivot_table(index="point", columns="variant",
                                                    values="E_drawn")
    points = table.drop_duplicates("point").set_index("point")[axes]
    for variant in (SAVING_REGULATED, SAVING_REFERENCE):
        points[f"E_drawn_{variant}"] = drawn[variant] if variant in drawn else np.nan
    points["saving"] = 1.0 - (points[f"E_drawn_{SAVING_REGULATED}"]
                              / points[f"E_drawn_{SAVING_REFERENCE}"])
    marks = {spec["mark"] for spec in sweep.plots.values() if spec.get("mark") in table}
    for column in marks:
        points[column] = table.groupby("point")[column].first()
    return points.reset_index(drop=True)


def _panels(sweep: Sweep, spec: dict[str, Any], data: pd.DataFrame, rows: int = 1
            ) -> tuple[Figure, list[tuple[Any, Sequence[Axes], pd.DataFrame]]]:
    """A figure with a column of `rows` panels per value of the spec's `panels` axis."""
    panel = spec.get("panels")
    groups = list(data.groupby(panel)) if panel else [(None, data)]
    fig = Figure(figsize=(5.2 * len(groups), 0.6 + 4.0 * rows), layout="constrained")
    axes = fig.subplots(rows, len(groups), squeeze=False, sharex=True, sharey="row")
    return fig, [(value, axes[:, i], group) for i, (value, group) in enumerate(groups)]


def _axis_label(sweep: Sweep, name: str) -> str:
    return next(a.label for a in sweep.axes if a.name == name)


def _panel_title(sweep: Sweep, spec: dict[str, Any], value: Any) -> str:
    return "" if value is None else f"{_axis_label(sweep, spec['panels'])} = {value:g}"


def _save(fig: Figure, path: Path) -> Path:
    return results.write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))


def plot_saving(sweep: Sweep, points: pd.DataFrame, spec: dict[str, Any], path: Path) -> Path:
    """Against the x axis: the energy saving [%] (top; values below SAVING_FLOOR drawn on it
    and labelled) and E_drawn of both variants [J] (bottom, log scale); one line per value
    of `lines`, one column per value of `panels`, a dashed line at the value of `mark`."""
    x, lines, mark = spec["x"], spec.get("lines"), spec.get("mark")
    fig, panels = _panels(sweep, spec, points, rows=2)
    for value, (top, bottom), group in panels:
        for i, (line, data) in enumerate(group.groupby(lines) if lines else [(None, group)]):
            data = data.sort_values(x)
            label = None if line is None else f"{_axis_label(sweep, lines)} = {line:g}"
            percent = 100.0 * data.saving
            top.plot(data[x], percent.clip(lower=SAVING_FLOOR), "o-", color=f"C{i}", ms=4,
                     lw=1.4, label=label)
            for at, below in zip(data[x][percent < SAVING_FLOOR],
                                 percent[percent < SAVING_FLOOR], strict=True):
                top.annotate(f"{below:.0f}", (at, SAVING_FLOOR), textcoords="offset points",
                             xytext=(5, 3 + 9 * i), fontsize=7, color=f"C{i}")
            bottom.semilogy(data[x], data[f"E_drawn_{SAVING_REGULATED}"], "o-", color=f"C{i}",
                            ms=4, lw=1.4)
            bottom.semilogy(data[x], data[f"E_drawn_{SAVING_REFERENCE}"], "s--",
                            color=f"C{i}", ms=4, lw=1.0, mfc="none")
        for ax in (top, bottom):
            if mark and mark in group and group[mark].notna().any():
                ax.axvline(float(group[mark].median()), color="k", ls=":", lw=1)
            ax.grid(alpha=0.3)
        if mark and mark in group and group[mark].notna().any():
            top.annotate(f"{mark} = {float(group[mark].median()):.3g} ",
                        (float(group[mark].median()), 0.5), ha="right",
                        xycoords=("data", "axes fraction"), fontsize=8)
        top.axhline(0.0, color="0.5", lw=0.8)
        top.set_ylim(SAVING_FLOOR - 8.0, 105.0)
        top.set_title(_panel_title(sweep, spec, value), fontsize=10)
        bottom.plot([], [], "ko-", ms=4, label=f"{SAVING_REGULATED}")
        bottom.plot([], [], "ks--", ms=4, mfc="none", label=f"{SAVING_REFERENCE}")
        bottom.legend(fontsize=8, loc="lower right")
        bottom.set_xlabel(_axis_label(sweep, x))
        if lines:
            top.legend(fontsize=8, loc="lower right")
    panels[0][1][0].set_ylabel("saving 1 - E_drawn(self-reg.) / E_drawn(unreg.) [%]")
    panels[0][1][1].set_ylabel("E_drawn [J]")
    fig.suptitle(f"{sweep.name}: drive energy saved by self-regulation ({sweep.scenario.name})")
    return _save(fig, path)


def plot_map(sweep: Sweep, points: pd.DataFrame, spec: dict[str, Any], path: Path) -> Path:
    """Energy saving [%] over two axes (a cell grid, or coloured points for a sample), one
    panel per value of `panels`; colours saturate below SAVING_FLOOR, numbers do not."""
    x, y = spec["x"], spec["y"]
    fig, panels = _panels(sweep, spec, points)
    norm = TwoSlopeNorm(vcenter=0.0, vmin=SAVING_FLOOR, vmax=100.0)
    for value, (ax,), group in panels:
        if sweep.sample == "grid":
            grid = 100.0 * group.pivot_table(index=y, columns=x, values="saving", dropna=False)
            image = ax.pcolormesh(np.arange(grid.shape[1] + 1), np.arange(grid.shape[0] + 1),
                                  grid.to_numpy(), cmap="RdYlGn", norm=norm)
            ax.set_xticks(np.arange(grid.shape[1]) + 0.5, [f"{v:g}" for v in grid.columns])
            ax.set_yticks(np.arange(grid.shape[0]) + 0.5, [f"{v:g}" for v in grid.index])
            for (row, col), cell in np.ndenumerate(grid.to_numpy()):
                if np.isfinite(cell):
                    ax.text(col + 0.5, row + 0.5, f"{cell:.0f}", ha="center", va="center",
                            fontsize=7)
        else:
            image = ax.scatter(group[x], group[y], c=100.0 * group.saving, cmap="RdYlGn",
                               norm=norm, s=30, edgecolors="k", linewidths=0.3)
        ax.set_title(_panel_title(sweep, spec, value), fontsize=10)
        ax.set_xlabel(_axis_label(sweep, x))
    panels[0][1][0].set_ylabel(_axis_label(sweep, y))
    fig.colorbar(image, ax=[axes[0] for _, axes, _ in panels], extend="min",
                 label="energy saving [%]")
    fig.suptitle(f"{sweep.name}: drive energy saved by self-regulation vs unregulated [%]")
    return _save(fig, path)


def _check_lines_plot(spec: dict[str, Any], axes: list[str], where: str) -> None:
    """UserError unless a lines plot names an x axis, optional lines axis and y columns."""
    roles = [spec.get(role) for role in ("x", "lines") if spec.get(role)]
    y = spec.get("y")
    if (set(roles) - set(axes) or not spec.get("x") or not isinstance(y, list) or not y
            or not all(isinstance(c, str) for c in y)):
        raise UserError(f"{where}: plot lines needs x and may have lines, both axes "
                        f"({', '.join(axes)}), and y = [result columns]")


def plot_lines(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any], path: Path) -> Path:
    """One panel per `y` column (a row) and variant (a column) against the x axis, one line
    per value of `lines`; a variant without the column (all NaN) leaves its panel empty.
    `labels` may give a y column a longer label."""
    x, lines, labels = spec["x"], spec.get("lines"), spec.get("labels", {})
    ok = table[table.status == "ok"]
    variants = list(sweep.variants)
    fig = Figure(figsize=(5.2 * len(variants), 0.6 + 2.6 * len(spec["y"])), layout="constrained")
    axes = fig.subplots(len(spec["y"]), len(variants), squeeze=False, sharex=True)
    for row, column in enumerate(spec["y"]):
        for col, variant in enumerate(variants):
            ax = axes[row, col]
            data = ok[ok.variant == variant]
            if column in data and data[column].notna().any():
                groups = data.groupby(lines) if lines else [(None, data)]
                for i, (line, group) in enumerate(groups):
                    group = group.sort_values(x)
                    label = None if line is None else f"{_axis_label(sweep, lines)} = {line:g}"
                    ax.plot(group[x], group[column], "o-", color=f"C{i}", ms=3, lw=1.2,
                            label=label)
                if lines and row == 0:
                    ax.legend(fontsize=7)
            else:
                ax.text(0.5, 0.5, f"no {column}", transform=ax.transAxes, ha="center",
                        color="0.5")
            ax.grid(alpha=0.3)
            ax.set_ylabel(labels.get(column, column), fontsize=8)
            if row == 0:
                ax.set_title(variant, fontsize=10)
            if row == len(spec["y"]) - 1:
                ax.set_xlabel(_axis_label(sweep, x))
    fig.suptitle(f"{sweep.name}: {sweep.description or sweep.scenario.name}")
    return _save(fig, path)


PLOTS: dict[str, Callable[[Sweep, pd.DataFrame, dict[str, Any], Path], Path]] = {
    "saving": plot_saving, "map": plot_map, "lines": plot_lines}


def plot(sweep: Sweep, table: pd.DataFrame, out: Path) -> list[Path]:
    """Draw the sweep's [plots] as <name>_<plot>.png in out (saving and map from the saving
    of each point, lines from the rows)."""
    if not sweep.plots:
        return []
    points = saving(sweep, table) if set(sweep.plots) - {"lines"} else table
    return [PLOTS[kind](sweep, table if kind == "lines" else points, spec,
                        out / f"{sweep.name}_{kind}.png")
            for kind, spec in sweep.plots.items()]


# ---- driver -------------------------------------------------------------------------------
def local_client(workers: int) -> Client:
    """A distributed Client on a LocalCluster of single-threaded worker processes."""
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    return Client(cluster)


def _close(client: Client) -> None:
    """Close the client and its local cluster. After Ctrl-C the workers may be gone already:
    a closed connection (CommClosedError, an OSError) is then expected, not an error."""
    cluster = client.cluster
    with contextlib.suppress(OSError):
        client.close()
        if cluster is not None:
            cluster.close()


def run_sweep(path: str | Path, out: Path = SWEEP_RESULTS_DIR, workers: int = 2,
          scheduler: str | None = None, chunk_size: int | None = None,
          retry_failed: bool = False, quiet: bool = False) -> pd.DataFrame:
    """Run the missing runs of a sweep file, then write its tables and plots."""
    definition = load(path)
    todo = pending(definition, out, retry_failed)
    if not quiet:
        total = len(plan(definition))
        print(f"{definition.name}: {total} runs, {total - len(todo)} stored, {len(todo)} to do")
    if todo:
        for model in {definition.scenario.variant(v).model or definition.scenario.model
                      for v in definition.variants}:
            fmu_build.fmu_path(model)  # build once here, not racing in the workers
        client = local_client(workers) if scheduler is None else Client(scheduler)
        try:
            execute(definition, todo, out, client, chunk_size, quiet)
        finally:
            _close(client)
    table = consolidate(definition, out)
    written = [out / f"{definition.name}.parquet", out / f"{definition.name}.csv",
               *plot(definition, table, out)]
    if not quiet:
        print("\n".join(str(p) for p in written))
        counts = table.status.value_counts()
        print(f"{len(table)} rows: {counts.get('ok', 0)} ok, {counts.get('failed', 0)} failed")
    return table


# ---- benchmark ----------------------------------------------------------------------------
BENCH_SWEEP = """
name = "bench"
scenario = "franchetti2021"
variants = ["self_regulating"]
[[axes]]
name = "payload"
set = ['phases["III regulate"].inputs.payload',
       'phases["III regulate"].inputs.counterweight_added']
range = {{ start = 0.0, stop = 8.0, num = {runs} }}
"""


def sweep_benchmark(runs: int = 12, workers: Sequence[int] = (1, 2)) -> pd.DataFrame:
    """Runs per second of a franchetti2021 payload sweep (35 s task at 1 ms) with each number
    of worker processes, one run per task, results stored as in a sweep. Start-up (cluster,
    imports, one FMU instance per worker) is not timed. speed_up is against the first row."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="sweep_bench_") as tmp:
        path = Path(tmp) / "bench.toml"
        path.write_text(BENCH_SWEEP.format(runs=runs))
        definition = load(path)
        fmu_build.fmu_path(definition.scenario.model)
        for n in workers:
            out = Path(tmp) / f"workers_{n}"
            client = local_client(n)
            try:
                client.run(warm_up, definition.scenario.model)
                start = time.perf_counter()
                done, failed = execute(definition, plan(definition), out, client, 1, quiet=True)
                seconds = time.perf_counter() - start
            finally:
                _close(client)
            if failed:
                raise RuntimeError(f"{failed} of {done} benchmark runs failed")
            rows.append({"workers": n, "runs": done, "seconds": seconds,
                        "runs_per_s": done / seconds})
    table = pd.DataFrame(rows)
    table["speed_up"] = table.runs_per_s / table.runs_per_s.iloc[0]
    return table


# ---- command ------------------------------------------------------------------------------

def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", help="sweep TOML file, or the name of one in harness/sweeps")
    parser.add_argument("--workers", type=int, default=2,
                        help="local worker processes (default 2; ignored with --scheduler)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="dask.distributed scheduler address, e.g. tcp://host:8786 "
                             "(default: local workers)")
    parser.add_argument("--chunk-size", type=int,
                        help="runs per task (default: the file's chunk_size, at most 8, and "
                             f"at least {CHUNKS_PER_WORKER} tasks per worker)")
    parser.add_argument("--retry-failed", action="store_true",
                        help="run again the runs stored as failed")
    parser.add_argument("--out", type=Path, default=SWEEP_RESULTS_DIR,
                        help="results folder (default results/sweeps)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def run(args: argparse.Namespace) -> int:
    if args.workers < 1 or (args.chunk_size is not None and args.chunk_size < 1):
        raise UserError("--workers and --chunk-size must be at least 1")
    try:
        table = run_sweep(args.file, args.out, args.workers, args.scheduler, args.chunk_size,
                          args.retry_failed, args.quiet)
    except KeyboardInterrupt:
        print("interrupted: finished chunks are stored; run the same command to resume",
              file=sys.stderr)
        return 130
    if len(table) and not (table.status == "ok").any():
        print(f"error: all {len(table)} runs failed; the first: {table.error.iloc[0]}",
              file=sys.stderr)
        return 1
    return 0
