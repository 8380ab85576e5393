"""A sweep file (docs/sweeps.md): its parsing and checks, the configuration paths its axes
set, and the plan of runs (the grid or the sample).

A sweep file (harness/sweeps/*.toml) names a scenario, its variants, parameter axes, the
metrics to keep and the plots to draw. Each axis sets one or more paths of the run's
configuration to its value:

- `parameters.L0`: an FMU parameter of the scenario (a variant's own parameters, e.g.
  `unbalanced`'s k = 0, still win; `variants.NAME.parameters.k` changes one variant);
- `motor.N`, `design.omega_c`: fields of MotorParameters and ControllerDesign;
- `phases["III regulate"].inputs.payload`: a phase input (a ramp keeps its shape and
  gets the value as its target); `phases["II move", "III regulate"].target_deg`: phase
  targets in degrees (`initial_angle_deg` likewise); `phases["V move"].duration` [s];
- `duration_scale`: every phase duration times the value (task speed);
- `0.0583 * variants.active_relocation.phase_targets["III regulate"].q`: any path preceded by
  a factor takes the axis value times it (a joint target proportional to the payload).

Axes take `values = [...]` or `range = { start, stop, num }` (inclusive), at most
MAX_AXIS_VALUES values; a set path has at most MAX_PATH_LENGTH characters. `sample = "grid"`
(default) runs the full factorial; `sample = "lhs"` draws a Latin-hypercube sample of
`samples` points (seeded by `seed`): ranges are sampled continuously over [start, stop],
value lists by stratified choice. Every point runs every listed variant. A path that names
nothing stops the sweep at load (PathError), and so does an axis value the configuration
refuses by itself (out of the range of its field, e.g. `design.omega_c = 0`). A value refused
only in combination with another axis (RefusedValueError), or by the FMU, fails the runs that
have it.

run_id hashes the scenario definition with the run's variant, the step size and the axis
assignments, so changing any of them gives new runs.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from fmu_src.units.sequencer.checks import check_name, finite_number, shown
from harness import scenarios
from harness.drive.metrics import METRICS
from harness.engines import DEFAULT_STEP
from harness.engines import plan as run_plan
from harness.errors import UserError
from harness.sweeps.paths import RefusedValueError, configure

SWEEP_DIR = Path(__file__).resolve().parent  # the sweep files beside this code
DEFAULT_CHUNK = 8                  # runs per task at most
MAX_RUNS = 100_000                 # runs per sweep: a plan this long takes days on a laptop
MAX_AXIS_VALUES = 10_000           # values of one axis (a 100 x 100 grid has 100 per axis)
MAX_PATH_LENGTH = 1_000            # characters of a set path
RUN_METRICS = tuple(m for m in METRICS if m != "eps")  # eps needs a baseline run
# the [plots] tables: saving and map compare two variants' E_drawn, lines draws result columns
PLOT_KINDS = ("saving", "map", "lines")


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
    step_size: float = DEFAULT_STEP     # [s]
    sample: str = "grid"                       # "grid" or "lhs"
    samples: int = 0                           # LHS points
    seed: int = 0
    chunk_size: int = DEFAULT_CHUNK
    # kind -> its [plots.<kind>] table; saving and map with their variant and baseline set
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
    try:
        return finite_number(value, what)
    except ValueError as error:
        raise UserError(str(error)) from None


def _count(value: Any, what: str, lowest: int, highest: int) -> int:
    """A whole number in [lowest, highest] from the file (2.0 counts, 2.7 does not)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            lowest <= value <= highest and float(value).is_integer()):
        raise UserError(f"{what} = {shown(value)} is not a whole number in [{lowest}, "
                        f"{highest}]")
    return int(value)


def _axis(raw: Any, where: str) -> Axis:
    if not isinstance(raw, dict):
        raise UserError(f"{where}: an axis is a table ([[axes]]), not {shown(raw)}")
    name = raw.get("name")
    paths = raw.get("set")
    paths = [paths] if isinstance(paths, str) else paths
    if not isinstance(name, str) or not name or not isinstance(paths, list) or not paths or not all(
            isinstance(p, str) and p.strip() for p in paths):
        raise UserError(f"{where}: an axis needs name = \"...\" and set = a path or a list of "
                        f"paths (strings); got name = {shown(name)}, set = "
                        f"{shown(raw.get('set'))}")
    long = [p for p in paths if len(p) > MAX_PATH_LENGTH]
    if long:
        raise UserError(f"{where}: axis {name} set path {shown(long[0])} has {len(long[0]):,} "
                        f"characters, more than {MAX_PATH_LENGTH:,}")
    paths = tuple(paths)
    if ("values" in raw) == ("range" in raw):
        raise UserError(f"{where}: axis {name} needs either values or range")
    if "values" in raw:
        if not isinstance(raw["values"], list) or not 1 <= len(raw["values"]) <= MAX_AXIS_VALUES:
            raise UserError(f"{where}: axis {name} values = {shown(raw['values'])} must be a "
                            f"list of 1 to {MAX_AXIS_VALUES:,} numbers")
        values = tuple(_number(v, f"{where}: axis {name} values item") for v in raw["values"])
        range_ = None
    else:
        span = raw["range"]
        if not isinstance(span, dict) or {"start", "stop"} - set(span) or set(span) - {
                "start", "stop", "num"}:
            raise UserError(f"{where}: axis {name} range = {shown(span)} must be a table "
                            "{ start = number, stop = number, num = whole number }")
        start = _number(span["start"], f"{where}: axis {name} range start")
        stop = _number(span["stop"], f"{where}: axis {name} range stop")
        num = _count(span.get("num", 2), f"{where}: axis {name} range num", 1,
                     MAX_AXIS_VALUES)
        values, range_ = tuple(float(v) for v in np.linspace(start, stop, num)), (start, stop)
    repeated = sorted(v for v, count in Counter(values).items() if count > 1)
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
    data = scenarios.read_toml(path)
    where = path.name
    name = data.get("name", path.stem)
    try:
        check_name(name, "name")
    except ValueError as error:
        raise UserError(f"{where}: {error}") from None
    scenario_ref = data.get("scenario")
    if not isinstance(scenario_ref, str) or not scenario_ref:
        raise UserError(f"{where}: scenario = {shown(scenario_ref)} is not a scenario name or "
                        "a path to a scenario file (a string)")
    scenario = scenarios.load(path.parent / scenario_ref if Path(scenario_ref).suffix
                              else scenario_ref)
    variants = data.get("variants", list(scenario.variants))
    if not isinstance(variants, list) or not variants or not all(
            isinstance(v, str) for v in variants):
        raise UserError(f"{where}: variants = {shown(variants)} is not a non-empty list of "
                        "variant names")
    repeated = sorted(v for v, count in Counter(variants).items() if count > 1)
    if repeated:
        raise UserError(f"{where}: variants = {shown(variants)} names {', '.join(repeated)} "
                        "more than once (each variant runs once per point)")
    variants = tuple(variants)
    unknown = [v for v in variants if v not in scenario.variants]
    if unknown:
        raise UserError(f"{where}: scenario {scenario.name} has no variant "
                        f"{', '.join(unknown)} (its variants: "
                        f"{', '.join(scenario.variants)})")
    if not data.get("axes") or not isinstance(data["axes"], list):
        raise UserError(f"{where}: no [[axes]]")
    axes = tuple(_axis(raw, f"{where} axis {i + 1}") for i, raw in enumerate(data["axes"]))
    names = [axis.name for axis in axes]
    if len(set(names)) < len(names):
        raise UserError(f"{where}: axis names repeat: {', '.join(names)}")
    sample = data.get("sample", "grid")
    if sample not in ("grid", "lhs"):
        raise UserError(f"{where}: sample = {shown(sample)}, not 'grid' or 'lhs'")
    samples = _count(data.get("samples", 0), f"{where}: samples", 0, MAX_RUNS)
    if sample == "lhs" and samples < 1:
        raise UserError(f"{where}: a Latin-hypercube sample needs samples >= 1")
    size = (samples if sample == "lhs" else math.prod(len(a.values) for a in axes)) * len(
        variants)
    if size > MAX_RUNS:
        raise UserError(f"{where}: {size:,} runs planned, more than {MAX_RUNS:,}: fewer axis "
                        "values or samples")
    # bad paths and values out of their field's range stop the sweep here; values refused
    # in combination, or by the FMU, are runs that fail
    configure(scenario, [(p, None) for axis in axes for p in axis.paths])
    _check_values(scenario, axes, where)
    _check_first_point(scenario, variants, axes)
    metrics = data.get("metrics", list(RUN_METRICS))
    if not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics):
        raise UserError(f"{where}: metrics = {metrics!r} is not a list of metric names")
    metrics = tuple(metrics)
    unknown = sorted(set(metrics) - set(RUN_METRICS))
    if unknown:
        raise UserError(f"{where}: unknown metrics {', '.join(unknown)} "
                        f"(choose from {', '.join(RUN_METRICS)})")
    plots = _plots(data.get("plots", {}), names, variants, metrics, where)
    step_size = _number(data.get("step_size", DEFAULT_STEP), f"{where}: step_size")
    scenario.check_step(step_size, f"{where}: step_size")
    chunk_size = _count(data.get("chunk_size", DEFAULT_CHUNK), f"{where}: chunk_size", 1,
                        MAX_RUNS)
    seed = _count(data.get("seed", 0), f"{where}: seed", 0, 2 ** 63 - 1)
    outputs = data.get("outputs", [])
    if not isinstance(outputs, list) or not all(isinstance(n, str) for n in outputs):
        raise UserError(f"{where}: outputs = {outputs!r} is not a list of output names")
    return Sweep(name, data.get("description", ""), scenario, variants,
                 axes, metrics, step_size, sample, samples, seed, chunk_size, plots,
                 tuple(outputs))


def _check_values(scenario: scenarios.Scenario, axes: Sequence[Axis], where: str) -> None:
    """UserError naming the first axis value that its paths' fields refuse by themselves (the
    other axes at their defaults): every value, and the ends of a range."""
    for axis in axes:
        for value in dict.fromkeys((*axis.values, *(axis.bounds or ()))):
            try:
                configure(scenario, [(p, value) for p in axis.paths])
            except RefusedValueError as error:
                raise UserError(f"{where}: axis {axis.name} value {value:g}: {error}") from None


def _check_first_point(scenario: scenarios.Scenario, variants: Sequence[str],
                       axes: Sequence[Axis]) -> None:
    """UserError naming an FMU parameter, input or model that no run can have, found on the
    first value of every axis before any run. Values the configuration or the model refuse
    fail per run: if the first point's are refused, its runs say why (RefusedValueError)."""
    try:
        configured, _, _ = configure(scenario, [(p, a.values[0]) for a in axes for p in a.paths])
    except RefusedValueError:
        return
    for name in variants:
        variant = configured.variant(name)
        run_plan.check(configured, variant, values=False)


def _plots(raw: Any, axes: Sequence[str], variants: Sequence[str], metrics: Sequence[str],
           where: str) -> dict[str, dict[str, Any]]:
    """The [plots] tables, checked: the roles (x, y, lines, panels) name axes, a lines plot
    names its y columns; saving and map compare `variant` with `baseline` on E_drawn, by
    default the sweep's first two variants."""
    if not isinstance(raw, dict):
        raise UserError(f"{where}: plots = {raw!r} is not a table of [plots.<kind>]")
    plots = {}
    for kind, spec in raw.items():
        if kind not in PLOT_KINDS:
            raise UserError(f"{where}: unknown plot {kind!r} (choose from "
                            f"{', '.join(PLOT_KINDS)})")
        if not isinstance(spec, dict):
            raise UserError(f"{where}: plots.{kind} = {spec!r} is not a table")
        if kind == "lines":
            _check_lines_plot(spec, axes, where)
            plots[kind] = spec
            continue
        roles = [spec.get(role) for role in ("x", "y", "lines", "panels") if spec.get(role)]
        if set(roles) - set(axes) or not spec.get("x") or (kind == "map" and not spec.get("y")):
            raise UserError(f"{where}: plot {kind} needs x{' and y' if kind == 'map' else ''}"
                            f" and may have lines, panels, all axes ({', '.join(axes)})")
        compared = {"variant": spec.get("variant", variants[0]),
                    "baseline": spec.get("baseline", variants[1] if len(variants) > 1 else None)}
        if ("E_drawn" not in metrics or compared["variant"] == compared["baseline"]
                or not all(name in variants for name in compared.values())):
            raise UserError(f"{where}: plot {kind} compares variant = "
                            f"{compared['variant']!r} with baseline = "
                            f"{compared['baseline']!r} on the metric E_drawn: it needs that "
                            f"metric and two different variants of the sweep "
                            f"({', '.join(variants)})")
        plots[kind] = {**spec, **compared}
    return plots


def _check_lines_plot(spec: dict[str, Any], axes: list[str], where: str) -> None:
    """UserError unless a lines plot names an x axis, optional lines axis and y columns."""
    roles = [spec.get(role) for role in ("x", "lines") if spec.get(role)]
    y = spec.get("y")
    if (set(roles) - set(axes) or not spec.get("x") or not isinstance(y, list) or not y
            or not all(isinstance(c, str) for c in y)):
        raise UserError(f"{where}: plot lines needs x and may have lines, both axes "
                        f"({', '.join(axes)}), and y = [result columns]")


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


