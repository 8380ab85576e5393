"""Reading a scenario file's data (a parsed TOML table) into a `Scenario` (standard library
only): the file format of `fmu_src.units.sequencer.scenario`, checked key by key (`checks`),
every problem a ValueError naming the key and what it allows."""

from __future__ import annotations

import math
from typing import Any

from fmu_src.units.sequencer.checks import (
    check_name,
    finite_number,
    parameter_values,
    position,
    shown,
    table,
    table_list,
    unknown_keys,
)
from fmu_src.units.sequencer.scenario import (
    DEFAULT_JOINT,
    JOINT_KEYS,
    MAX_PHASES,
    OPTIONAL_JOINT_KEYS,
    PHASE_KEYS,
    RAMP_SHAPES,
    Joint,
    Phase,
    Ramp,
    Scenario,
    Variant,
)


def _input_change(name: str, value: Any) -> Any:
    if isinstance(value, dict):
        shape = value.get("shape", "linear")
        if ("ramp" not in value or set(value) - {"ramp", "shape"} or not isinstance(shape, str)
                or shape not in RAMP_SHAPES):
            raise ValueError(f"input {name} must be a value or {{ ramp = value, "
                             f"shape = one of {', '.join(RAMP_SHAPES)} }}")
        return Ramp(finite_number(value["ramp"], f"input {name} ramp"), shape)
    if isinstance(value, bool):
        return value
    return finite_number(value, f"input {name}", "a finite number or boolean")


def _input_changes(raw: Any, where: str) -> dict[str, Any]:
    try:
        return {name: _input_change(name, value)
                for name, value in table(raw, "inputs").items()}
    except ValueError as error:
        raise ValueError(f"{where}: {error}") from None


def _joint(name: str, raw: dict[str, Any]) -> Joint:
    """A joint from its table; exactly one of static_effort and static_load."""
    unknown_keys(raw, JOINT_KEYS + OPTIONAL_JOINT_KEYS, f"joint {name}")
    statics = [key for key in ("static_effort", "static_load") if key in raw]
    missing = [key for key in JOINT_KEYS if key not in raw]
    if missing or len(statics) != 1:
        raise ValueError(f"joint {name} needs {', '.join(JOINT_KEYS)} and one of "
                         "static_effort, static_load (missing or doubled: "
                         f"{', '.join(missing) or ', '.join(statics) or 'static_effort'})")
    rests = raw.get("rest_when_holding", False)
    if not isinstance(rests, bool):
        raise ValueError(f"joint {name}: rest_when_holding = {rests!r} is not true or false")
    drive = table(raw.get("drive", {}), f"joint {name}: drive")
    return Joint(name, **{key: str(raw[key]) for key in JOINT_KEYS if key != "initial"},
                 static_output=str(raw[statics[0]]), static_is_load=statics[0] == "static_load",
                 kind=str(raw.get("kind", "revolute")), motor=str(raw.get("motor", "geared")),
                 screw=None if raw.get("screw") is None else str(raw["screw"]),
                 drive=tuple(sorted(drive.items())), rest_when_holding=rests)


def _initial_positions(joints: tuple[Joint, ...], tables: dict[str, Any]) -> tuple[float, ...]:
    """The `initial` position [rad or m] of each joint's table."""
    return tuple(position(raw["initial"], f"joint {joint.name}: initial", joint.unit)
                 for joint, raw in zip(joints, tables.values()))


def _joints(data: dict[str, Any]) -> tuple[tuple[Joint, ...], tuple[float, ...]]:
    """The scenario's joints and their initial positions [rad or m]."""
    if "joints" not in data:
        if "initial_angle_deg" not in data:
            raise ValueError("initial_angle_deg is missing (or declare [joints.<name>] tables)")
        initial = math.radians(position(data["initial_angle_deg"], "initial_angle_deg",
                                        "deg"))
        names = table(data.get("joint", {}), "joint")
        default = {k: v for k, v in DEFAULT_JOINT.items()
                   if not (k == "static_load" and "static_effort" in names)}
        raw = {**default, **names, "initial": initial}
        return (_joint("theta", raw),), (initial,)
    if "joint" in data or "initial_angle_deg" in data:
        raise ValueError("with [joints.<name>] tables give each joint's names and `initial` "
                         "there, not [joint] or initial_angle_deg")
    joints = tuple(_joint(name, table(raw, f"joints.{name}"))
                   for name, raw in table(data["joints"], "joints").items())
    return joints, _initial_positions(joints, data["joints"])


def _targets(raw: dict[str, Any], joints: tuple[Joint, ...], previous: tuple[float, ...]
             ) -> tuple[float, ...]:
    """A phase's target per joint [rad or m]; joints it does not name hold their target."""
    names = [j.name for j in joints]
    if "target_deg" in raw:
        if len(joints) != 1 or joints[0].kind != "revolute" or "targets" in raw:
            raise ValueError("target_deg is for a scenario with one revolute joint; give "
                             f"targets = {{ {', '.join(f'{n} = ...' for n in names)} }} in rad "
                             "(revolute) or m (prismatic)")
        return (math.radians(position(raw["target_deg"], "target_deg", "deg")),)
    targets = table(raw.get("targets", {}), "targets")
    unknown = sorted(set(targets) - set(names))
    if unknown:
        raise ValueError(f"targets name no joint {', '.join(unknown)} "
                         f"(joints: {', '.join(names)})")
    units = {j.name: j.unit for j in joints}
    checked = {name: position(value, f"target {name}", units[name])
               for name, value in targets.items()}
    return tuple(checked.get(n, p) for n, p in zip(names, previous))


def _phases(data: dict[str, Any], joints: tuple[Joint, ...], initial: tuple[float, ...]
            ) -> tuple[Phase, ...]:
    phases, target = [], initial
    skipped = None  # the first phase only some variants perform
    raw_phases = table_list(data["phases"], "phases")
    if len(raw_phases) > MAX_PHASES:
        raise ValueError(f"phases: {len(raw_phases):,} [[phases]] tables, more than "
                         f"{MAX_PHASES:,}")
    for i, raw in enumerate(raw_phases):
        name = str(raw.get("name", i + 1))
        where = f"phase {name}"
        unknown_keys(raw, PHASE_KEYS, where)
        if "duration" not in raw:
            raise ValueError(f"{where}: duration [s] is missing")
        try:
            target = _targets(raw, joints, target)
        except ValueError as error:
            raise ValueError(f"{where}: {error}") from None
        duration = finite_number(raw["duration"], f"{where}: duration", "a number of seconds "
                                 "in (0, inf)")
        performers = raw.get("variants")
        if performers is not None and (not isinstance(performers, list) or not performers
                                       or not all(isinstance(v, str) for v in performers)):
            names = data.get("variants")
            raise ValueError(f"{where}: variants = {shown(performers)} must be a non-empty list "
                             "of variant names (leave it out for every variant); choose from "
                             f"{', '.join(names) if isinstance(names, dict) else names}")
        # a target left out holds the previous one, which after a phase some variants skip
        # depends on the variant: each joint's target must then be given
        given = {joints[0].name} if "target_deg" in raw else set(raw.get("targets", {}))
        missing = [j.name for j in joints if j.name not in given]
        if skipped is not None and missing:
            raise ValueError(f"{where} gives no target for {', '.join(missing)}: after phase "
                             f"{skipped}, which only some variants perform, where a joint "
                             "stands depends on the variant, so each phase gives every "
                             "joint's target")
        if performers and skipped is None:
            skipped = name
        phases.append(Phase(name, duration, target,
                            _input_changes(raw.get("inputs", {}), where),
                            tuple(performers or ())))
    return tuple(phases)


def _variant_joints(name: str, raw: dict[str, Any], scenario_joints: tuple[Joint, ...],
                    phase_names: set[str]
                    ) -> tuple[tuple[Joint, ...], tuple[float, ...], dict[str, dict[str, float]]]:
    """A variant's own joints, their initial positions and their targets by phase."""
    tables = table(raw.get("joints", {}), f"variant {name} joints")
    joints = tuple(_joint(joint, table(raw_joint, f"variant {name} joints.{joint}"))
                   for joint, raw_joint in tables.items())
    taken = sorted({j.name for j in joints} & {j.name for j in scenario_joints})
    if taken:
        raise ValueError(f"variant {name} joints {', '.join(taken)}: the scenario has "
                         "joints of these names")
    targets = table(raw.get("phase_targets", {}), f"variant {name} phase_targets")
    unknown = sorted(set(targets) - phase_names)
    if unknown:
        raise ValueError(f"variant {name} phase_targets names no phase {', '.join(unknown)}")
    resolved = {}
    for phase, changes in targets.items():
        try:
            values = _targets({"targets": changes}, joints, (0.0,) * len(joints))
        except ValueError as error:
            raise ValueError(f"variant {name} phase_targets {phase}: {error} (the variant's "
                             "own joints)") from None
        resolved[phase] = {j.name: v for j, v in zip(joints, values)
                           if j.name in changes}
    return joints, _initial_positions(joints, tables), resolved


def _variants(data: dict[str, Any], phase_names: set[str], joints: tuple[Joint, ...]
              ) -> dict[str, Variant]:
    variants = {}
    for name, raw in table(data["variants"], "variants").items():
        check_name(name, "variant name")
        raw = table(raw, f"variant {name}")
        phase_inputs = table(raw.get("phase_inputs", {}), f"variant {name} phase_inputs")
        drop = raw.get("drop_inputs", [])
        if not isinstance(drop, list) or not all(isinstance(n, str) for n in drop):
            raise ValueError(f"variant {name} drop_inputs = {shown(drop)} must be a list of input "
                             "names")
        for key in ("description", "model", "baseline"):
            if not isinstance(raw.get(key, ""), str):
                raise ValueError(f"variant {name} {key} = {shown(raw[key])} must be a string")
        unknown = set(phase_inputs) - phase_names
        if unknown:
            raise ValueError(f"variant {name} phase_inputs names no phase "
                             f"{', '.join(sorted(unknown))}")
        variants[name] = Variant(
            name, raw.get("description", ""), raw.get("model"),
            parameter_values(raw.get("parameters", {}), f"variant {name} parameters"),
            parameter_values(raw.get("inputs", {}), f"variant {name} inputs"),
            tuple(drop),
            {phase: _input_changes(changes, f"variant {name} phase {phase}")
             for phase, changes in phase_inputs.items()},
            raw.get("baseline"), *_variant_joints(name, raw, joints, phase_names),
            _variant_drives(name, raw, joints))
    return variants


def _variant_drives(name: str, raw: dict[str, Any], scenario_joints: tuple[Joint, ...]
                    ) -> dict[str, tuple[tuple[str, Any], ...]]:
    """The drives a variant pins on joints (the scenario's or its own), by joint name."""
    drives = table(raw.get("drives", {}), f"variant {name} drives")
    own = table(raw.get("joints", {}), f"variant {name} joints")
    names = [j.name for j in scenario_joints] + list(own)
    unknown = sorted(set(drives) - set(names))
    if unknown:
        raise ValueError(f"variant {name} drives names no joint {', '.join(unknown)}; choose "
                         f"from {', '.join(names)}")
    return {joint: tuple(sorted(table(spec, f"variant {name} drives.{joint}").items()))
            for joint, spec in drives.items()}


def parse(data: dict[str, Any], where: str, scenario_type: type[Scenario] = Scenario
          ) -> Scenario:
    """A scenario from the data of its TOML file (where: the file's name, for messages)."""
    try:
        for key in ("name", "description", "source", "model", "baseline"):
            if not isinstance(data.get(key, ""), str):
                raise ValueError(f"{key} = {shown(data[key])} must be a string")
        joints, initial = _joints(data)
        phases = _phases(data, joints, initial)
        variants = _variants(data, {phase.name for phase in phases}, joints)
        scenario = scenario_type(
            name=check_name(data["name"], "name"), description=data.get("description", ""),
            model=data["model"],
            parameters=parameter_values(data.get("parameters", {}), "parameters"),
            initial_angle=initial, phases=phases, variants=variants,
            baseline=data.get("baseline", next(iter(variants), "")), joints=joints,
            source=data.get("source", ""))
        for phase in phases:
            unknown = [v for v in phase.variants if v not in variants]
            if unknown:
                raise ValueError(f"phase {phase.name}: variants names no variant "
                                 f"{', '.join(unknown)}; choose from {', '.join(variants)}")
        idle = [v for v in variants if all(p.variants and v not in p.variants for p in phases)]
        if idle:
            raise ValueError(f"variant {', '.join(idle)} performs no phase: every phase names "
                             "other variants (`variants = [...]`)")
        unknown = sorted(set(scenario.baselines.values()) - set(variants))
        if unknown:
            raise ValueError(f"baseline {', '.join(unknown)} names no variant; choose from "
                             f"{', '.join(variants)}")
        return scenario
    except ValueError as error:
        raise ValueError(f"{where}: {error}") from None
    except KeyError as error:
        raise ValueError(f"{where}: {error.args[0]} is missing") from None
    except (TypeError, AttributeError) as error:  # a list or value where a table belongs
        raise ValueError(f"{where}: a value has the wrong type ({error}); see the scenario "
                         "file format") from None
