"""Random tasks from a task model, each a scenario file of the existing format (docs/study.md).

Task i of a study with seed S is drawn from its own generator, numpy's
`default_rng([S, i])`, so that a task does not depend on how many others are drawn: a study
of 200 tasks holds the first 100 of the same seed. A task draws its number of moves, the
fraction of the speed limit its moves use, its mean hold (log-uniformly) and its probability
of a payload change per move; then a start posture, and per move a target in each joint's
range, a hold after it (exponential with the task's mean, at least MIN_HOLD_S) and whether
the payload changes before it (always before the first move, where the model has a payload)
to a mass uniform in its range.

The scenario of a task (phases, in order): `0 hold` at the start posture, then per move k:
`k change` where the payload changes (if it does), the procedure phases of the variants that
regulate at a posture (performed by them alone: `Phase.variants`), `k move` and `k hold`. A
move lasts long enough for the farthest start any variant makes it from (the start posture,
or the regulation posture), so that no variant exceeds the speed limit. A variant that
regulates in place ramps the payload along its shape and moves its balancing joint in the
change phase (`phase_inputs`, `phase_targets`); the realistic loss set's balancing targets
come from the realistic parameters, in realistic/<task>.toml beside the task.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from fmu_src.mechanisms.active_spring import model as active_spring
from fmu_src.units.sequencer import scenario_format
from harness import scenarios
from harness.design import active_spring as active_design
from harness.errors import UserError
from harness.io import write_atomic
from harness.scenarios import losses
from harness.study.model import Procedure, TaskModel

MIN_HOLD_S = 0.1     # [s] the shortest hold
QUINTIC_PEAK = 1.875  # peak speed of a quintic move over its mean speed


@dataclass(frozen=True)
class Task:
    """A drawn task: its scenario file's data, that of its realistic loss file (None: the
    template has no realistic set) and the figures that describe it (`row`)."""

    name: str
    data: dict[str, Any]
    realistic: dict[str, Any] | None
    row: dict[str, Any]

    def loss_sets(self) -> list[tuple[str, scenarios.Scenario]]:
        """(loss set, scenario) of the task, as `cosim` loads them from its files."""
        try:
            ideal = scenario_format.parse(self.data, self.name, scenarios.Scenario)
        except ValueError as error:
            raise UserError(str(error)) from None
        sets = [("ideal", ideal)]
        if self.realistic is not None:
            sets.append(("realistic", losses.realistic(ideal, self.realistic)))
        return sets


def task_name(model: TaskModel, index: int) -> str:
    return f"{model.name}-task-{index:04d}"


def _move_duration(model: TaskModel, start: tuple[float, ...], end: tuple[float, ...],
                   speed_fraction: float) -> float:
    """[s] the slowest joint's move at the task's speed, at least its min_move_s."""
    return max(max(r.min_move_s, QUINTIC_PEAK * abs(b - a) / (r.speed_limit * speed_fraction))
               for r, a, b in zip(model.joints.values(), start, end))


def _targets(names: list[str] | None, position: tuple[float, ...]) -> dict[str, Any]:
    """A phase's targets in the template's form: `target_deg` for a scenario with one
    default joint (names None), else `targets` by joint name [rad or m]."""
    if names is None:
        return {"target_deg": math.degrees(position[0])}
    return {"targets": dict(zip(names, position))}


def _payload_inputs(inputs: dict[str, Any], payload: float) -> dict[str, Any]:
    """A procedure's inputs with `{ ramp = "payload" }` (or "payload") as the new payload."""
    def value(v: Any) -> Any:
        if v == "payload":
            return payload
        if isinstance(v, dict) and v.get("ramp") == "payload":
            return {**v, "ramp": payload}
        return v
    return {name: value(v) for name, v in inputs.items()}


def balancing_target(scenario: scenarios.Scenario, variant: str, procedure: Procedure,
                     payload: float) -> float:
    """Where the variant's balancing joint (an ActiveSpringBalancer's carriage q = Y_B -
    Y_B0) balances the payload [m] at the procedure's design angle, with the variant's
    parameters in this loss set (`harness.design.active_spring`)."""
    chosen = scenario.variant(variant)
    values = {**scenario.parameters, **chosen.parameters}
    names = {f.name for f in dataclasses.fields(active_spring.Parameters)}
    p = active_spring.Parameters(**{k: v for k, v in values.items() if k in names})
    return active_design.design(p, payload, math.radians(procedure.design_deg)).delta_Y_B


def draw(model: TaskModel, seed: int, index: int) -> Task:
    """Task `index` of the study with this seed (see the module docstring)."""
    rng = np.random.default_rng([seed, index])
    low, high = model.moves
    moves = int(rng.integers(low, high + 1))
    speed = float(rng.uniform(*model.speed_fraction))
    mean_hold = float(np.exp(rng.uniform(*np.log(model.mean_hold_s))))
    p_change = float(rng.uniform(*model.change_probability))
    ranges = list(model.joints.values())
    start = tuple(float(rng.uniform(r.low, r.high)) for r in ranges)
    holds = [max(MIN_HOLD_S, float(rng.exponential(mean_hold))) for _ in range(moves + 1)]
    targets = [tuple(float(rng.uniform(r.low, r.high)) for r in ranges) for _ in range(moves)]
    changes = [bool(k == 0 or rng.uniform() < p_change) for k in range(moves)]
    payloads = [float(rng.uniform(*model.payload_kg)) for _ in range(moves)]
    if model.strokes:   # out to the range's upper end and back, from the lower one
        start = (ranges[0].low,)
        targets = [(ranges[0].high if k % 2 == 0 else ranges[0].low,) for k in range(moves)]
        changes = [change and k % 2 == 0 for k, change in enumerate(changes)]
    if model.payload_kg[1] == 0.0:   # a mechanism without a payload input
        changes = [False] * moves
    return _build(model, index, seed, start, holds, targets, changes, payloads,
                  {"moves": moves, "speed_fraction": speed, "mean_hold_s": mean_hold,
                   "change_probability": p_change}, speed)


def _build(model: TaskModel, index: int, seed: int, start: tuple[float, ...],
           holds: list[float], targets: list[tuple[float, ...]], changes: list[bool],
           payloads: list[float], drawn: dict[str, Any], speed: float) -> Task:
    template = model.template
    raw = scenarios.read_toml(scenarios.scenario_file(template.name))
    first_inputs = raw["phases"][0].get("inputs", {})
    name = task_name(model, index)
    names = list(raw["joints"]) if "joints" in raw else None
    phases: list[dict[str, Any]] = [{"name": "0 hold", "duration": holds[0],
                                     **_targets(names, start), "inputs": first_inputs}]
    variant_inputs: dict[str, dict[str, Any]] = {v: {} for v in template.variants}
    variant_targets: dict[str, dict[str, Any]] = {v: {} for v in template.variants}
    realistic_targets: dict[str, dict[str, Any]] = {v: {} for v in template.variants}
    loss_sets = dict(losses.loss_sets(template, "all"))
    position, payload, n_changes = start, 0.0, 0
    for k, (target, change, new) in enumerate(zip(targets, changes, payloads), start=1):
        starts = [position]
        if model.strokes:
            if change:
                n_changes += 1
                payload = new
            outward = k % 2 == 1
            phases.append({"name": f"{k} move", **_targets(names, target),
                           "duration": _move_duration(model, position, target, speed),
                           "inputs": {"payload": {"ramp": payload if outward else 0.0}}})
            for variant in template.variants:
                procedure = model.procedure(variant)
                shape = procedure.payload_shape if outward else procedure.return_shape
                if shape != "linear":
                    variant_inputs[variant][f"{k} move"] = {"payload": {
                        "ramp": payload if outward else 0.0, "shape": shape}}
            phases.append({"name": f"{k} hold", "duration": holds[k],
                           **_targets(names, target)})
            position = target
            continue
        if change:
            n_changes += 1
            payload = new
            change_phase = f"{k} change"
            phases.append({"name": change_phase, "duration": model.change_s,
                           **_targets(names, position),
                           "inputs": {"payload": {"ramp": payload}}})
            for variant in template.variants:
                procedure = model.procedure(variant)
                if procedure.kind == "in_place":
                    if procedure.payload_shape != "linear":
                        variant_inputs[variant][change_phase] = {"payload": {
                            "ramp": payload, "shape": procedure.payload_shape}}
                    if procedure.balance is not None:
                        for sets, table in ((("ideal",), variant_targets),
                                            (("realistic",), realistic_targets)):
                            if sets[0] in loss_sets:
                                table[variant][change_phase] = {procedure.balance: (
                                    balancing_target(loss_sets[sets[0]], variant, procedure,
                                                     payload))}
                    continue
                posture = (math.radians(procedure.posture_deg), *position[1:])
                if posture != position:
                    phases.append({"name": f"{k} to posture", "variants": [variant],
                                   "duration": _move_duration(model, position, posture, speed),
                                   **_targets(names, posture)})
                for step in procedure.phases:
                    phases.append({**step, "name": f"{k} {step['name']}", "variants": [variant],
                                   **_targets(names, posture),
                                   **({"inputs": _payload_inputs(step["inputs"], payload)}
                                      if "inputs" in step else {})})
                variant_inputs[variant][f"{k} move"] = _payload_inputs(procedure.after, payload)
                starts.append(posture)
        phases.append({"name": f"{k} move", **_targets(names, target),
                       "duration": max(_move_duration(model, s, target, speed) for s in starts)})
        phases.append({"name": f"{k} hold", "duration": holds[k], **_targets(names, target)})
        position = target
    data = {key: value for key, value in raw.items()
            if key not in ("phases", "variants", "initial_angle_deg")}
    data["name"] = name
    data["description"] = (f"Task {index} of the {template.name} study (seed {seed}): "
                           f"{len(targets)} moves, {n_changes} payload changes")
    if "joints" in raw:
        data["joints"] = {j: {**t, "initial": x} for (j, t), x
                          in zip(raw["joints"].items(), start)}
    else:
        data["initial_angle_deg"] = math.degrees(start[0])
    data["phases"] = phases
    data["variants"] = {}
    for variant, table in raw["variants"].items():
        table = {k: v for k, v in table.items() if k not in ("phase_inputs", "phase_targets")}
        if variant_inputs[variant]:
            table["phase_inputs"] = variant_inputs[variant]
        if variant_targets[variant]:
            table["phase_targets"] = variant_targets[variant]
        data["variants"][variant] = table
    realistic = None
    if losses.has_realistic(template):
        realistic = scenarios.read_toml(losses.loss_file(template))
        realistic["variants"] = {v: {k: x for k, x in t.items() if k != "phase_targets"}
                                 for v, t in realistic.get("variants", {}).items()}
        for variant, table in realistic_targets.items():
            if table:
                realistic["variants"].setdefault(variant, {})["phase_targets"] = table
    brought = [p for p, c in zip(payloads, changes) if c]   # the masses the changes bring
    duration = sum(p["duration"] for p in phases if "variants" not in p)
    hold = sum(holds)
    row = {"task": index, "name": name, "seed": seed, **drawn, "changes": n_changes,
           "duration": duration, "hold_fraction": hold / duration,
           "changes_per_min": n_changes / (duration / 60.0),
           "payload_mean": float(np.mean(brought)) if brought else 0.0}
    return Task(name, data, realistic, row)


def pinned(task: Task, drives: dict[str, dict[str, dict[str, Any]]]) -> Task:
    """The task with each variant's drives pinned ({variant: {joint: spec}}: the study's
    sizing), so that `cosim` reruns it with them."""
    data = {**task.data, "variants": {
        v: {**table, "drives": drives[v]} if drives.get(v) else table
        for v, table in task.data["variants"].items()}}
    return dataclasses.replace(task, data=data)


def text(data: dict[str, Any]) -> str:
    """A scenario or loss file's TOML text."""
    return tomli_w.dumps(data)


def write(task: Task, folder: Path) -> Path:
    """Write the task's scenario file (and its realistic loss file) into folder, unless the
    same text is there; UserError if another one is (a study of another seed or model)."""
    files = [(folder / f"{task.name}.toml", text(task.data))]
    if task.realistic is not None:
        files.append((folder / losses.REALISTIC_FOLDER / f"{task.name}.toml",
                      text(task.realistic)))
    for path, content in files:
        if path.exists():
            if path.read_text() != content:
                raise UserError(f"{path} holds another task: the folder holds a study of "
                                "another seed, task model or drive sizing; choose another "
                                "--out or remove it")
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, lambda tmp, content=content: tmp.write_text(content))
    return files[0][0]
