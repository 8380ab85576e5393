"""Task scenarios as data: TOML files in harness/scenarios/ (or any path).

A scenario names the mechanism FMU, its parameters, the joint the drive moves and a list of
phases. Each phase has a duration [s], a target angle [deg] reached by a quintic (zero
velocity and acceleration at both ends) over the phase, and input changes applied at the
phase start: a plain value steps there, `{ ramp = value }` ramps to value over the phase,
linearly or with `shape` one of RAMP_SHAPES (e.g. `{ ramp = 4.0, shape = "ease_out" }`).
Inputs keep their value until a later phase changes them.

Variants are configurations of the same run (SPEC.md section 3): they may replace the FMU
(`model`), override its parameters (`parameters`), hold inputs at fixed values for the whole
run (`inputs`), replace the input changes of named phases (`phase_inputs`, e.g.
`{ down = { payload = { ramp = 0.4, shape = "quintic" } } }`), drop scenario inputs the model
does not have (`drop_inputs`), or name their own eps `baseline` (default: the scenario's).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"


def quintic(s: np.ndarray) -> np.ndarray:
    """Quintic 10 s^3 - 15 s^4 + 6 s^5: 0 -> 1 with zero speed and acceleration at both ends."""
    return s ** 3 * (10.0 + s * (-15.0 + 6.0 * s))


def ease_out(s: np.ndarray) -> np.ndarray:
    """Parabola s (2 - s): 0 -> 1 with zero slope at the end."""
    return s * (2.0 - s)


def ease_in(s: np.ndarray) -> np.ndarray:
    """Parabola s^2: 0 -> 1 with zero slope at the start."""
    return s * s


# ramp shapes f(s), f(0) = 0, f(1) = 1, s the fraction of the phase. The quintic_* shapes
# are functions of the joint's travel over the phase (the reference is a quintic in time),
# so an input given as a law of the angle follows the angle: "quintic" is linear in the
# angle, "quintic_ease_out" is ease_out of the angle's fraction of the move.
RAMP_SHAPES = {
    "linear": lambda s: s,
    "quintic": quintic,
    "ease_out": ease_out,
    "ease_in": ease_in,
    "quintic_ease_out": lambda s: ease_out(quintic(s)),
    "quintic_ease_in": lambda s: ease_in(quintic(s)),
}


@dataclass(frozen=True)
class Ramp:
    """Ramp to `target` over the phase with one of RAMP_SHAPES."""

    target: float
    shape: str = "linear"


@dataclass(frozen=True)
class Phase:
    name: str
    duration: float                 # [s]
    target: float                   # joint target at the end of the phase [rad]
    inputs: dict[str, Any] = field(default_factory=dict)  # value or Ramp, from phase start


@dataclass(frozen=True)
class Variant:
    name: str
    description: str = ""
    model: str | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    inputs: dict[str, float | bool] = field(default_factory=dict)
    drop_inputs: tuple[str, ...] = ()
    phase_inputs: dict[str, dict[str, Any]] = field(default_factory=dict)  # by phase name
    baseline: str | None = None     # variant against which eps is computed, if not the default


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    model: str
    parameters: dict[str, float]
    initial_angle: float            # [rad]
    phases: tuple[Phase, ...]
    variants: dict[str, Variant]
    baseline: str                   # default variant against which eps is computed
    joint: dict[str, str]           # FMU names of angle, speed, torque and parameter names

    @property
    def duration(self) -> float:
        return sum(p.duration for p in self.phases)

    def phase_times(self) -> list[tuple[str, float, float]]:
        """(name, start, end) of each phase [s]."""
        out, t = [], 0.0
        for phase in self.phases:
            out.append((phase.name, t, t + phase.duration))
            t += phase.duration
        return out

    @property
    def baselines(self) -> dict[str, str]:
        """The eps baseline of each variant: its own `baseline`, else the scenario's."""
        return {name: v.baseline or self.baseline for name, v in self.variants.items()}

    def variant(self, name: str) -> Variant:
        try:
            return self.variants[name]
        except KeyError:
            raise ValueError(f"scenario {self.name} has no variant {name!r}; "
                             f"choose from {', '.join(self.variants)}") from None

    def reference(self, times: np.ndarray) -> np.ndarray:
        """Joint reference angle [rad] at the given times: quintic segments."""
        ref = np.full(times.shape, self.initial_angle)
        start_angle = self.initial_angle
        for (_, t0, t1), phase in zip(self.phase_times(), self.phases, strict=True):
            inside = (times >= t0) & (times <= t1) if t1 == self.duration else (
                (times >= t0) & (times < t1))
            s = (times[inside] - t0) / (t1 - t0)
            ref[inside] = start_angle + (phase.target - start_angle) * quintic(s)
            start_angle = phase.target
        ref[times > self.duration] = start_angle
        return ref

    def input_segments(self, variant: Variant) -> list[dict[str, tuple[Any, Any, str]]]:
        """Per phase, each input as (value at start, value at end, ramp shape).

        The variant's phase inputs replace those of the phases they name, its fixed inputs
        replace the scenario's, and its dropped inputs are left out.
        """
        changes = [phase.inputs | variant.phase_inputs.get(phase.name, {})
                   for phase in self.phases]
        names = [n for phase_changes in changes for n in phase_changes]
        names = [n for n in dict.fromkeys(names) if n not in variant.drop_inputs]
        booleans = {n for phase_changes in changes for n, v in phase_changes.items()
                    if isinstance(v, bool)}
        values: dict[str, Any] = {n: False if n in booleans else 0.0 for n in names}
        segments = []
        for phase_changes in changes:
            segment = {}
            for name in names:
                change = phase_changes.get(name)
                if isinstance(change, Ramp):
                    segment[name] = (values[name], change.target, change.shape)
                    values[name] = change.target
                else:
                    if change is not None:
                        values[name] = change
                    segment[name] = (values[name], values[name], "linear")
            segment.update({n: (v, v, "linear") for n, v in variant.inputs.items()})
            segments.append(segment)
        return segments

    def inputs(self, times: np.ndarray, variant: Variant) -> dict[str, np.ndarray]:
        """Input signals at the given times (a phase's changes apply from its start)."""
        signals: dict[str, np.ndarray] = {}
        segments = self.input_segments(variant)
        for (_, t0, t1), segment in zip(self.phase_times(), segments, strict=True):
            inside = times >= t0
            s = np.clip((times[inside] - t0) / (t1 - t0), 0.0, 1.0)
            for name, (start, end, shape) in segment.items():
                signal = signals.setdefault(
                    name, np.zeros(times.shape, dtype=bool if isinstance(end, bool) else float))
                signal[inside] = end if start == end else start + (end - start) * \
                    RAMP_SHAPES[shape](s)
        return signals


def _input_change(name: str, value: Any, where: str) -> Any:
    if isinstance(value, dict):
        shape = value.get("shape", "linear")
        if "ramp" not in value or set(value) - {"ramp", "shape"} or shape not in RAMP_SHAPES:
            raise ValueError(f"{where}: input {name} must be a value or {{ ramp = value, "
                             f"shape = one of {', '.join(RAMP_SHAPES)} }}")
        return Ramp(float(value["ramp"]), shape)
    if not isinstance(value, bool | int | float) or not math.isfinite(value):
        raise ValueError(f"{where}: input {name} = {value!r} is not a finite number or boolean")
    return value if isinstance(value, bool) else float(value)


def load(name_or_path: str | Path) -> Scenario:
    """Load a scenario by name (harness/scenarios/<name>.toml) or from a TOML file."""
    path = Path(name_or_path)
    if not path.suffix:
        path = SCENARIO_DIR / f"{name_or_path}.toml"
    if not path.exists():
        known = ", ".join(available())
        raise ValueError(f"no scenario {name_or_path!r} (known: {known})")
    data = tomllib.loads(path.read_text())
    where = path.name
    phases = []
    for i, raw in enumerate(data["phases"]):
        duration = float(raw["duration"])
        if not duration > 0.0:
            raise ValueError(f"{where}: phase {i} duration = {duration} s is outside (0, inf)")
        inputs = {n: _input_change(n, v, f"{where} phase {raw.get('name', i)}")
                  for n, v in raw.get("inputs", {}).items()}
        phases.append(Phase(str(raw.get("name", i + 1)), duration,
                            math.radians(float(raw["target_deg"])), inputs))
    phase_names = {phase.name for phase in phases}
    variants = {}
    for name, raw in data["variants"].items():
        phase_inputs = raw.get("phase_inputs", {})
        unknown = set(phase_inputs) - phase_names
        if unknown:
            raise ValueError(f"{where}: variant {name} phase_inputs names no phase "
                             f"{', '.join(sorted(unknown))}")
        variants[name] = Variant(
            name, raw.get("description", ""), raw.get("model"),
            {k: float(v) for k, v in raw.get("parameters", {}).items()},
            dict(raw.get("inputs", {})), tuple(raw.get("drop_inputs", ())),
            {phase: {n: _input_change(n, v, f"{where} variant {name} phase {phase}")
                     for n, v in changes.items()}
             for phase, changes in phase_inputs.items()},
            raw.get("baseline"))
    joint = {"angle": "theta", "speed": "omega", "torque": "tau_drive",
             "initial_angle": "theta0", "inertia": "J_link", "friction": "d_link",
             "drive_inertia": "J_drive"} | data.get("joint", {})
    scenario = Scenario(
        name=data["name"], description=data.get("description", ""), model=data["model"],
        parameters={k: float(v) for k, v in data.get("parameters", {}).items()},
        initial_angle=math.radians(float(data["initial_angle_deg"])), phases=tuple(phases),
        variants=variants, baseline=data.get("baseline", next(iter(variants))), joint=joint)
    for baseline in sorted(set(scenario.baselines.values())):
        scenario.variant(baseline)
    return scenario


def available() -> list[str]:
    """Names of the scenarios shipped in harness/scenarios."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))
