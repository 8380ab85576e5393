"""The task model of a study: what a machine does, as data (harness/study/<scenario>.toml,
docs/study.md).

A task model names the scenario whose model, parameters, joints and variants every task uses
(its template), the ranges from which a task's moves, holds and payload changes are drawn,
and the procedure by which each variant regulates after a payload change:

- `in_place` (the default): the payload changes where the link stands, over `change_s`,
  along `payload_shape`; a joint named in `balance` (an ActiveSpringBalancer's carriage q)
  moves meanwhile to where it balances the new payload (`harness.design.active_spring`, at
  the regulation angle `design_deg`);
- `at_posture`: the payload changes where the link stands with the balancer locked; the link
  then moves to `posture_deg`, where the variant performs `phases` (phase tables of the
  scenario format, in which `{ ramp = "payload" }` ramps an input to the new payload),
  and the next phase applies the inputs `after`.

A model without `payload_kg` draws no payload (a mechanism without a payload input). With
`strokes = true` the payload is a law of the stroke instead (Ciupitu 2018's process: the
load is taken on while the link goes down and given back while it comes up): the link
strokes between the two ends of its range, the payload ramping to the stroke's mass on the
way to the upper end of the range along a variant's `payload_shape` and back to 0 on the way
back along its `return_shape`; the mass changes before a stroke out with the change
probability (always before the first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from harness import scenarios
from harness.errors import UserError

STUDY_DIR = Path(__file__).resolve().parent
PROCEDURES = ("in_place", "at_posture")
RAMP_SHAPES = tuple(scenarios.RAMP_SHAPES)
KEYS = ("scenario", "tasks", "reference", "step", "drive_sample", "moves", "joints",
        "speed_fraction", "mean_hold_s", "payload_kg", "change_probability", "change_s",
        "strokes", "procedures")
JOINT_KEYS = ("range", "speed_limit", "min_move_s")
PROCEDURE_KEYS = ("kind", "payload_shape", "return_shape", "balance", "design_deg",
                  "posture_deg", "phases", "after")


@dataclass(frozen=True)
class JointRange:
    """Where a joint's targets are drawn [rad or m] and how fast it may move: a move of
    distance d takes max(min_move_s, 15/8 d / speed_limit), the quintic whose peak speed is
    speed_limit [rad/s or m/s] (at the task's speed fraction)."""

    low: float
    high: float
    speed_limit: float
    min_move_s: float


@dataclass(frozen=True)
class Procedure:
    """How a variant regulates after a payload change (see the module docstring)."""

    kind: str = "in_place"
    payload_shape: str = "linear"
    return_shape: str = "linear"
    balance: str | None = None
    design_deg: float = 180.0
    posture_deg: float = 180.0
    phases: tuple[dict[str, Any], ...] = ()
    after: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TaskModel:
    """A scenario's task model (see the module docstring); ranges are (low, high)."""

    name: str
    template: scenarios.Scenario
    tasks: int
    reference: str
    step: float
    drive_sample: int
    moves: tuple[int, int]
    joints: dict[str, JointRange]
    speed_fraction: tuple[float, float]
    mean_hold_s: tuple[float, float]
    payload_kg: tuple[float, float]
    change_probability: tuple[float, float]
    change_s: float
    strokes: bool
    procedures: dict[str, Procedure]

    def procedure(self, variant: str) -> Procedure:
        return self.procedures.get(variant, Procedure())


def available() -> list[str]:
    """The scenarios with a task model in harness/study."""
    return sorted(p.stem for p in STUDY_DIR.glob("*.toml"))


def _range(raw: dict[str, Any], key: str, low: float = 0.0,
           high: float = math.inf) -> tuple[float, float]:
    value = raw.get(key)
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            or not low <= value[0] <= value[1] <= high):
        raise UserError(f"{key} = {value!r} must be [low, high] with {low:g} <= low <= high "
                        f"<= {high:g}")
    return float(value[0]), float(value[1])


def _positive(raw: dict[str, Any], key: str, integer: bool = False) -> Any:
    value = raw.get(key)
    kind = int if integer else (int, float)
    if not isinstance(value, kind) or isinstance(value, bool) or not 0 < value < math.inf:
        raise UserError(f"{key} = {value!r} must be a positive "
                        f"{'integer' if integer else 'number'}")
    return value


def _procedure(variant: str, raw: Any, template: scenarios.Scenario) -> Procedure:
    where = f"procedures.{variant}"
    if not isinstance(raw, dict):
        raise UserError(f"{where} must be a table")
    unknown = sorted(set(raw) - set(PROCEDURE_KEYS))
    if unknown:
        raise UserError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: "
                        f"{', '.join(PROCEDURE_KEYS)}")
    for key in ("design_deg", "posture_deg"):
        value = raw.get(key, 180.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
                value):
            raise UserError(f"{where}.{key} = {value!r} must be a finite number [deg]")
    phases = raw.get("phases", [])
    if not isinstance(phases, list) or not all(
            isinstance(p, dict) and isinstance(p.get("name"), str) and "duration" in p
            and not {"target_deg", "targets", "variants"} & set(p) for p in phases):
        raise UserError(f"{where}.phases must be phase tables with a name and a duration "
                        "(no targets: they hold the posture; no variants: the variant's own)")
    for key in ("balance", "kind", "payload_shape", "return_shape"):
        if key in raw and not isinstance(raw[key], str):
            raise UserError(f"{where}.{key} = {raw[key]!r} must be a string")
    if not isinstance(raw.get("after", {}), dict):
        raise UserError(f"{where}.after must be a table of inputs")
    procedure = Procedure(**{k: tuple(v) if k == "phases" else v for k, v in raw.items()})
    if procedure.kind not in PROCEDURES:
        raise UserError(f"{where}.kind = {procedure.kind!r} must be one of "
                        f"{', '.join(PROCEDURES)}")
    for key in ("payload_shape", "return_shape"):
        if getattr(procedure, key) not in RAMP_SHAPES:
            raise UserError(f"{where}.{key} = {getattr(procedure, key)!r} must be one of "
                            f"{', '.join(RAMP_SHAPES)}")
    own = [j.name for j in template.for_variant(template.variant(variant)).joints]
    if procedure.balance is not None and procedure.balance not in own:
        raise UserError(f"{where}.balance = {procedure.balance!r} is no joint of the variant "
                        f"({', '.join(own)})")
    if procedure.kind == "at_posture" and not procedure.phases:
        raise UserError(f"{where}: kind at_posture needs its phases")
    return procedure


def load(name: str) -> TaskModel:
    """The task model of a scenario (harness/study/<name>.toml); UserError naming the key
    that is wrong."""
    path = STUDY_DIR / f"{name}.toml"
    if not path.exists():
        raise UserError(f"no task model for scenario {name!r} (known: "
                        f"{', '.join(available())})")
    raw = scenarios.read_toml(path)
    try:
        unknown = sorted(set(raw) - set(KEYS))
        if unknown:
            raise UserError(f"unknown key(s) {', '.join(unknown)}; allowed: {', '.join(KEYS)}")
        template = scenarios.load(raw.get("scenario", name))
        names = [j.name for j in template.joints]
        joints = raw.get("joints", {})
        if not isinstance(joints, dict) or sorted(joints) != sorted(names):
            raise UserError(f"joints must have one table per joint of the scenario "
                            f"({', '.join(names)})")
        ranges = {}
        for joint in template.joints:
            table = joints[joint.name]
            unknown = sorted(set(table) - set(JOINT_KEYS))
            if unknown:
                raise UserError(f"joints.{joint.name}: unknown key(s) {', '.join(unknown)}")
            low, high = _range(table, "range", -1e3, 1e3)
            ranges[joint.name] = JointRange(low, high, _positive(table, "speed_limit"),
                                            _positive(table, "min_move_s"))
        procedures = raw.get("procedures", {})
        if not isinstance(procedures, dict) or set(procedures) - set(template.variants):
            raise UserError(f"procedures must be tables named after variants of "
                            f"{template.name} ({', '.join(template.variants)})")
        reference = raw.get("reference")
        if reference not in template.variants:
            raise UserError(f"reference = {reference!r} must be a variant of {template.name} "
                            f"({', '.join(template.variants)})")
        strokes = raw.get("strokes", False)
        if not isinstance(strokes, bool):
            raise UserError(f"strokes = {strokes!r} must be true or false")
        payload = "payload_kg" in raw   # a model without a payload input has none
        if strokes and (len(template.joints) != 1 or not payload):
            raise UserError("strokes = true needs a scenario of one joint and a payload_kg")
        step = _positive(raw, "step")
        template.check_step(step, "step")
        moves = _range(raw, "moves", 1, 1000)
        if not all(isinstance(v, int) for v in raw["moves"]):
            raise UserError(f"moves = {raw['moves']!r} must be two integers")
        return TaskModel(
            name=template.name, template=template, tasks=_positive(raw, "tasks", True),
            reference=reference, step=float(step),
            drive_sample=_positive(raw, "drive_sample", True),
            moves=(int(moves[0]), int(moves[1])), joints=ranges,
            speed_fraction=_range(raw, "speed_fraction", 1e-3, 1.0),
            mean_hold_s=_range(raw, "mean_hold_s", 1e-3, 1e4),
            payload_kg=_range(raw, "payload_kg", 0.0, 1e3) if payload else (0.0, 0.0),
            change_probability=(_range(raw, "change_probability", 0.0, 1.0) if payload
                                else (0.0, 0.0)),
            change_s=float(_positive(raw, "change_s")) if payload and not strokes else 0.0,
            strokes=strokes,
            procedures={v: _procedure(v, p, template) for v, p in procedures.items()})
    except UserError as error:
        raise UserError(f"{path.name}: {error}") from None
