"""Each variant's drives by the one sizing rule (harness.drive.sizing, docs/drives.md), applied
before its runs.

What a variant's task asks of each joint comes from a run of the variant with the legacy
drives, every drive on (`Scenario.drives_always_on`), in the FMPy master at every
communication step: the effort the mechanism received, less what accelerated the legacy
drive's rotor, and the joint's speed and acceleration; the drive counts as on where the
scenario switches it on (`Scenario.drive_enabled`). A variant with a realistic loss set is
sized for both its tasks (ideal and realistic: the worst of each figure), so that one drive
serves both tables; the ideal set runs it with a lossless transmission. A joint whose
scenario pins its drive (`drive = { motor = ..., gearhead = ..., ratio = ... }`) keeps it,
sized all the same so that the summary can say whether it does the task.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness import scenarios
from harness.drive import catalogue
from harness.drive.motor import JointDrive
from harness.drive.sizing import JointLoad, Sizing, choose, combined, evaluate
from harness.engines import DEFAULT_STEP, fmpy_master
from harness.engines.plan import enabled_steps, prepare
from harness.engines.result import RunResult
from harness.errors import UserError


def joint_loads(scenario: scenarios.Scenario, run: RunResult) -> list[JointLoad]:
    """What the task asks of each joint of the scenario (resolved for the variant), from a
    run that kept its traces."""
    loads = []
    for j, (joint, trace) in enumerate(zip(scenario.joints, run.traces, strict=True)):
        dt = float(trace.step_size)
        n = len(trace.effort)
        speed = trace.speed[:n]
        acceleration = np.gradient(trace.speed, dt)[:n]
        rotor = run.parameters[joint.drive_inertia] * acceleration
        loads.append(JointLoad(dt, trace.effort - rotor, speed, acceleration,
                               enabled_steps(scenario, j, trace.times)))
    return loads


def size_variant(loss_sets: list[scenarios.Scenario], variant: str,
                 step_size: float = DEFAULT_STEP) -> dict[str, Sizing]:
    """Each joint's sizing for a variant that runs in the given loss sets (its scenario as
    loaded and, where it has one, its realistic set)."""
    tasks = []
    for scenario in loss_sets:
        legacy = scenario.drives_always_on()
        run = fmpy_master.run(prepare(legacy, legacy.variant(variant), step_size),
                              keep_traces=True)
        resolved = scenario.for_variant(scenario.variant(variant))
        tasks.append(joint_loads(resolved, run))
    resolved = loss_sets[0].for_variant(loss_sets[0].variant(variant))
    sized = {}
    for j, joint in enumerate(resolved.joints):
        loads = [task[j] for task in tasks]
        where = f"scenario {resolved.name} variant {variant} joint {joint.name}"
        if joint.kind == "prismatic" and joint.screw is None:
            raise UserError(f"{where}: a prismatic joint needs its lead screw (`screw`, one "
                            f"of {', '.join(catalogue.catalogue()[2])}) to be sized")
        if joint.drive:
            sized[joint.name] = combined([evaluate(pinned_drive(joint, where), load)
                                          for load in loads])
        else:
            sized[joint.name] = choose(catalogue.drives(joint.screw), loads)
    return sized


def pinned_drive(joint: scenarios.Joint, where: str) -> catalogue.Drive:
    """The catalogue drive a joint pins (`drive`, or its variant's `drives`); UserError
    naming where the pin is when the catalogue has no such drive."""
    return catalogue.pinned(dict(joint.drive), joint.screw, where)


def pinned_drives(resolved: scenarios.Scenario, loss_set: str, where: str
                  ) -> dict[str, JointDrive]:
    """The drives every joint of a scenario resolved for a variant pins, as the loss set runs
    them (lossless in the ideal set, as `joint_drives`): a study task's."""
    return {joint.name: pinned_drive(joint, f"{where} joint {joint.name}")
            .joint_drive(lossless=loss_set == "ideal") for joint in resolved.joints}


def joint_drives(sized: dict[str, Sizing], loss_set: str) -> dict[str, JointDrive]:
    """The drives a loss set's runs put on the joints: lossless in the ideal set."""
    return {name: s.drive.joint_drive(lossless=loss_set == "ideal") for name, s in sized.items()}


def table_row(variant: str, joint: str, sized: Sizing) -> dict[str, object]:
    """A row of a scenario's drives.csv: the drive the rule picked for a variant's joint,
    its transmission, and its figures over the tasks with the worst figure-to-limit ratio."""
    drive = sized.drive
    return {"variant": variant, "joint": joint, "drive": drive.label,
            "motor": drive.motor.name,
            "gearhead": "" if drive.gearhead is None else drive.gearhead.name,
            "screw": "" if drive.screw is None else drive.screw.name,
            "gear_ratio": drive.gear_ratio, "N": drive.N,
            "eta": drive.eta, "eta_back": drive.eta_back, "I_nom": drive.motor.I_nom,
            "P_nom": drive.motor.P_nom, "I_rms": sized.I_rms, "I_peak": sized.I_peak,
            "omega_motor_peak": sized.omega_motor_peak, "V_peak": sized.V_peak,
            "T_rms": sized.T_rms, "T_peak": sized.T_peak, "E_drawn": sized.E_drawn,
            "worst_load": sized.worst, "feasible": sized.feasible}


def _read_drives(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path, keep_default_na=False)
    except OSError as error:
        raise UserError(f"{path}: cannot be read ({error.strerror or error}); run cosim "
                        "with --drives sized") from None


def _pin(row: object) -> dict[str, object]:
    """A drives.csv row's drive as a scenario pins it (`catalogue.pinned`)."""
    return {"motor": row.motor} | (
        {"gearhead": row.gearhead, "ratio": float(row.gear_ratio)} if row.gearhead else {})


def stored_pins(path: Path) -> dict[str, dict[str, dict[str, object]]]:
    """The drives of a drives.csv (`table_row`) as a scenario pins them, {variant: {joint:
    {motor, gearhead, ratio}}}; UserError naming the file when it cannot be read."""
    pins: dict[str, dict[str, dict[str, object]]] = {}
    for row in _read_drives(path).itertuples():
        pins.setdefault(row.variant, {})[row.joint] = _pin(row)
    return pins


def stored_drives(folder: Path, variant: str, loss_set: str) -> dict[str, JointDrive]:
    """The drives a variant ran with in a written result set, from its folder's drives.csv
    (`table_row`), as the set's loss set runs them; UserError naming the file when it has
    none for the variant."""
    path = folder / "drives.csv"
    table = _read_drives(path)
    rows = table[table.variant == variant]
    if rows.empty:
        raise UserError(f"{path} has no drive of variant {variant}")
    return {row.joint: catalogue.pinned(_pin(row), row.screw or None,
                                        f"{path} {variant} {row.joint}")
            .joint_drive(lossless=loss_set == "ideal") for row in rows.itertuples()}
