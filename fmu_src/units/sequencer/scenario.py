"""Task scenarios as data: the one definition of the scenario file format and of its meaning
(standard library only, so the `ScenarioSequencer` FMU plays a scenario exactly as the
harness does; `harness.scenarios` finds the files and evaluates them on numpy arrays).
This module holds the data model; `scenario_format.parse` reads a file's data into it, each
value checked by `checks`.

A scenario (a TOML file) names the mechanism FMU, its parameters, the joints the drives move
and a list of phases, and optionally the work it reproduces (`source`, which figures cite).
Each phase has a duration [s], a target per joint reached by a quintic (zero velocity and
acceleration at both ends) over the phase, and input changes applied at the phase start: a
plain value steps there, `{ ramp = value }` ramps to value over the phase, linearly or with
`shape` one of RAMP_SHAPES (e.g. `{ ramp = 4.0, shape = "ease_out" }`). Inputs keep their
value until a later phase changes them; a joint a phase gives no target holds its previous
one. A phase with `variants = [...]` is performed only by the variants it names (the others
go on to the next phase from where they are): a variant's own procedure, such as moving to the
posture where it regulates (`Scenario.for_variant`). Where a joint stands then depends on the
variant, so every phase after the first such phase gives every joint's target.

Joints. Without a `joints` table the scenario has one revolute joint with the names of the
balancer FMUs (DEFAULT_JOINT; a `[joint]` table may rename them), its initial angle is
`initial_angle_deg` and a phase's target `target_deg` [deg]. Otherwise each `[joints.<name>]`
table declares one joint, in file order, with every key of JOINT_KEYS: the FMU names of its
position, speed, effort input, initial-position parameter (`start_parameter`), inertia
parameter [kg m2 or kg], friction parameter and drive-inertia parameter (where the harness
puts J_rotor N^2 of the joint's motor), the output reporting the static effort at t = 0 (either
`static_effort`, the effort the drive supplies to hold the mechanism, or `static_load`, the
effort gravity and springs exert on the joint, which the drive holds with the opposite sign),
`initial` (its position at t = 0), and optionally `kind` (JOINT_KINDS), `motor` (MOTORS, the
joint's drive in the `legacy` drive configuration), `screw` (the lead screw of a prismatic
joint, by its name in the harness's drive catalogue), `drive` (a table pinning the joint's
catalogue drive, `{ motor = ..., gearhead = ..., ratio = ... }`, instead of the one the sizing
rule picks) and `rest_when_holding` (true: the joint's axis holds by itself, e.g. through a
self-locking screw, so its drive is switched off in every phase where the joint holds its
position, and on again from the start of a phase that moves it; `Scenario.drive_enabled`).
Phases then give `targets = { <joint> = value, ... }` in SI units: rad for a revolute joint,
m for a prismatic one (`target_deg` remains for scenarios with one revolute joint).

Variants are configurations of the same run (docs/scenarios.md): they may replace the FMU
(`model`), override its parameters (`parameters`), hold inputs at fixed values for the whole
run (`inputs`), replace the input changes of named phases (`phase_inputs`, e.g.
`{ down = { payload = { ramp = 0.4, shape = "quintic" } } }`), drop scenario inputs the model
does not have (`drop_inputs`), name their own eps `baseline` (default: the scenario's), or pin
the catalogue drive of joints for themselves (`drives = { <joint> = { motor = ..., gearhead =
..., ratio = ... } }`, as a joint's `drive` pins it for every variant).
A variant whose model has more joints than the scenario drives them too: its own
`[variants.<v>.joints.<name>]` tables (the format of `[joints.<name>]`) come after the
scenario's joints, and `phase_targets = { <phase> = { <joint> = value } }` gives their
targets [rad or m] (a phase it does not name holds the previous one);
`Scenario.for_variant` resolves them into a scenario with every joint the variant drives.

Evaluation: `Scenario.reference_at(t)` and `Scenario.inputs_at(t, segments)` on floats. The
shape functions and `ramp` are plain arithmetic, so they work on floats and numpy arrays alike.
Both take a `tolerance` [s]: a time less than that before a phase start counts as that
start, for hosts that add up their time (STEP_TIME_TOLERANCE).

Limits: at most MAX_PHASES phases, and joint positions (initial and targets) of magnitude
at most `fmu_src.parameters.MAGNITUDE_LIMIT` [rad or m], the bound of the FMUs' inputs.
Loading and evaluating take time linear in the number of phases.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections import Counter
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

JOINT_KINDS = ("revolute", "prismatic")
# the legacy drives the harness can put on a joint: the default geared DC motor, a DC motor
# on a lead screw, or on a self-locking trapezoidal screw (harness.drive.motor.LEGACY maps
# these names to drives)
MOTORS = ("geared", "lead_screw", "trapezoidal_screw")
# the one joint of a scenario without a `joints` table: the balancer FMUs' names
DEFAULT_JOINT = {"position": "theta", "speed": "omega", "effort": "tau_drive",
                 "start_parameter": "theta0", "inertia": "J_link", "friction": "d_link",
                 "drive_inertia": "J_drive", "static_load": "tau_gravity"}
JOINT_KEYS = ("position", "speed", "effort", "start_parameter", "inertia", "friction",
              "drive_inertia", "initial")
OPTIONAL_JOINT_KEYS = ("kind", "motor", "static_effort", "static_load", "screw", "drive",
                       "rest_when_holding")
PHASE_KEYS = ("name", "duration", "target_deg", "targets", "inputs", "variants")
# Tolerance of phase start times, as a fraction of the communication step: a host that adds up
# its time (t += h) reaches a phase start a little early or late (13.99999999999768 for 14 s
# after 14 000 steps of 1 ms; at most 1.6e-8 steps after 35 000 steps of 1 ms and 1e-4 steps
# after 3.5 million steps of 10 us), so a time less than 1e-3 of a step before a phase start
# counts as that start: the phase switches at the same step as at the exact time i h.
STEP_TIME_TOLERANCE = 1e-3
# phases per scenario: a scenario of this many loads in about 0.1 s; a file of more is a
# generated mistake rather than a task
MAX_PHASES = 10_000


def quintic(s: Any) -> Any:
    """Quintic 10 s^3 - 15 s^4 + 6 s^5: 0 -> 1 with zero speed and acceleration at both ends."""
    return s ** 3 * (10.0 + s * (-15.0 + 6.0 * s))


def ease_out(s: Any) -> Any:
    """Parabola s (2 - s): 0 -> 1 with zero slope at the end."""
    return s * (2.0 - s)


def ease_in(s: Any) -> Any:
    """Parabola s^2: 0 -> 1 with zero slope at the start."""
    return s * s


# ramp shapes f(s), f(0) = 0, f(1) = 1, s the fraction of the phase. The quintic_* shapes
# are functions of the joint's travel over the phase (the reference is a quintic in time),
# so an input given as a law of the angle follows the angle: "quintic" is linear in the
# angle, "quintic_ease_out" is ease_out of the angle's fraction of the move.
RAMP_SHAPES = {
    "linear": lambda s: s,
    "quintic": lambda s: at_most_one(quintic(s)),
    "ease_out": ease_out,
    "ease_in": ease_in,
    "quintic_ease_out": lambda s: ease_out(quintic(s)),
    "quintic_ease_in": lambda s: ease_in(at_most_one(quintic(s))),
}


def at_most_one(x: Any) -> Any:
    """min(x, 1), elementwise on floats and numpy arrays alike (x itself where x <= 1). The
    quintic rounds to 1 + 2^-52 at some s just below 1, and a ramp to 0 through it ends at
    -2^-52 of its start: a payload of -5.6e-17 kg, which the FMUs refuse."""
    return x - (x - 1.0 + abs(x - 1.0)) * 0.5


def ramp(start: Any, end: Any, shape: str, s: Any) -> Any:
    """The value at fraction s (float or array) of a ramp from start to end with a shape."""
    return end if start == end else start + (end - start) * RAMP_SHAPES[shape](s)


@dataclass(frozen=True)
class Ramp:
    """Ramp to `target` over the phase with one of RAMP_SHAPES."""

    target: float
    shape: str = "linear"


def _positions(value: Any) -> tuple[float, ...]:
    """A position per joint; one number stands for a one-joint scenario's position."""
    return (float(value),) if isinstance(value, (int, float)) else tuple(map(float, value))


@dataclass(frozen=True)
class Phase:
    """A phase: duration [s], target per joint [rad or m] and input changes from its start.

    A single number for `target` means a one-joint scenario's target (sweep paths such as
    `phases["II move"].target_deg` set it so).
    """

    name: str
    duration: float                 # [s]
    target: tuple[float, ...]       # per joint, reached at the end of the phase [rad or m]
    inputs: dict[str, Any] = field(default_factory=dict)  # value or Ramp, from phase start
    # the variants that perform it, () for every variant; left out of repr, which sweep run
    # ids hash: a variant's resolved scenario (`Scenario.for_variant`) has its phases only
    variants: tuple[str, ...] = field(default=(), repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", _positions(self.target))
        if not 0.0 < self.duration < math.inf:
            raise ValueError(f"phase {self.name}: duration = {self.duration} s is outside "
                             "(0, inf)")


@dataclass(frozen=True)
class Joint:
    """One driven joint: FMU variable names, kind, motor and how its static effort is read."""

    name: str
    position: str
    speed: str
    effort: str
    start_parameter: str
    inertia: str
    friction: str
    drive_inertia: str
    static_output: str              # FMU output giving the static effort at t = 0
    static_is_load: bool            # True: the output is the load on the joint (drive: -it)
    kind: str = "revolute"
    motor: str = "geared"
    screw: str | None = None        # the lead screw of a prismatic joint (catalogue name)
    drive: tuple[tuple[str, Any], ...] = ()   # a pinned catalogue drive, as (key, value)s
    rest_when_holding: bool = False  # its drive is off where the joint holds its position

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"joint {self.name}: kind = {self.kind!r} is not one of "
                             f"{', '.join(JOINT_KINDS)}")
        if self.motor not in MOTORS:
            raise ValueError(f"joint {self.name}: motor = {self.motor!r} is not one of "
                             f"{', '.join(MOTORS)}")

    @property
    def unit(self) -> str:
        """Unit of the joint's position: rad or m."""
        return "rad" if self.kind == "revolute" else "m"

    def hold_effort(self, static_output: float) -> float:
        """The effort [N m or N] the drive supplies to hold the static output's value."""
        return -static_output if self.static_is_load else static_output


@dataclass(frozen=True)
class Variant:
    """A configuration of the scenario's run (see the module docstring)."""

    name: str
    description: str = ""
    model: str | None = None
    parameters: dict[str, float | bool] = field(default_factory=dict)
    inputs: dict[str, float | bool] = field(default_factory=dict)
    drop_inputs: tuple[str, ...] = ()
    phase_inputs: dict[str, dict[str, Any]] = field(default_factory=dict)  # by phase name
    baseline: str | None = None     # variant against which eps is computed, if not the default
    # joints driven besides the scenario's, their positions at t = 0 [rad or m] and targets
    # by phase; left out of repr (which sweep run ids hash), for_variant's scenario shows them
    joints: tuple[Joint, ...] = field(default=(), repr=False)
    joint_initial: tuple[float, ...] = field(default=(), repr=False)
    phase_targets: dict[str, dict[str, float]] = field(default_factory=dict, repr=False)
    # the catalogue drive pinned on joints by name, as a joint's `drive` pins it, for this
    # variant alone ({joint: ((key, value), ...)}); for_variant puts them on the joints
    drives: dict[str, tuple[tuple[str, Any], ...]] = field(default_factory=dict, repr=False)


@dataclass(frozen=True)
class Scenario:
    """A task: model, parameters, joints, phases and variants (see the module docstring).

    `initial_angle` holds the initial position of each joint [rad or m] (the name is that of
    one-joint scenarios, which sweep paths `initial_angle_deg` set).
    """

    name: str
    description: str
    model: str
    parameters: dict[str, float | bool]
    initial_angle: tuple[float, ...]  # per joint [rad or m]
    phases: tuple[Phase, ...]
    variants: dict[str, Variant]
    baseline: str                   # default variant against which eps is computed
    joints: tuple[Joint, ...]
    # the work the scenario reproduces, as figures cite it ("Franchetti et al. 2021"); a
    # citation, not part of the task, so left out of repr (which sweep run ids hash)
    source: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "initial_angle", _positions(self.initial_angle))
        names = [j.name for j in self.joints]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"scenario {self.name}: joints {names} must be one or more "
                             "distinct names")
        for what, positions in [("initial positions", self.initial_angle)] + [
                (f"phase {p.name} targets", p.target) for p in self.phases]:
            if len(positions) != len(names):
                raise ValueError(f"scenario {self.name}: {len(positions)} {what} for "
                                 f"{len(names)} joint(s) {', '.join(names)}")
        if not self.phases:
            raise ValueError(f"scenario {self.name} has no phases")
        repeated = sorted(n for n, count in Counter(p.name for p in self.phases).items()
                          if count > 1)
        if repeated:
            raise ValueError(f"scenario {self.name}: phase names repeat: {', '.join(repeated)} "
                             "(each phase needs its own name)")
        if not self.variants:
            raise ValueError(f"scenario {self.name} has no variants: [variants] needs at least "
                             "one table")
        for name, t0, t1 in self.phase_times():  # a duration lost in rounding, or a sum
            if not t0 < t1 < math.inf:             # of durations overflowing
                raise ValueError(f"scenario {self.name}: phase {name} spans [{t0}, {t1}] s: "
                                 "its duration must be positive against its start time, and "
                                 "the scenario's duration finite")

    @cached_property
    def duration(self) -> float:
        """Sum of the phase durations [s], computed once: `reference_at` reads it every step."""
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

    def for_variant(self, variant: Variant) -> Scenario:
        """The scenario as the variant runs it: the phases it performs (those that name no
        variants or name it), and every joint it drives, with the drives the variant pins:
        the scenario's, then the variant's own, whose targets follow its phase_targets (a
        phase it does not name holds the previous target). Joints the scenario already has
        are not added again."""
        if any(phase.variants for phase in self.phases):
            return replace(self, phases=tuple(
                replace(phase, variants=()) for phase in self.phases
                if not phase.variants or variant.name in phase.variants)).for_variant(variant)
        if variant.drives:
            def pinned(joints: tuple[Joint, ...]) -> tuple[Joint, ...]:
                return tuple(replace(j, drive=variant.drives.get(j.name, j.drive))
                             for j in joints)
            return replace(self, joints=pinned(self.joints)).for_variant(
                replace(variant, drives={}, joints=pinned(variant.joints)))
        names = {j.name for j in self.joints}
        extra = [(j, x) for j, x in zip(variant.joints, variant.joint_initial)
                 if j.name not in names]
        if not extra:
            return self
        phases, targets = [], [x for _, x in extra]
        for phase in self.phases:
            changes = variant.phase_targets.get(phase.name, {})
            targets = [changes.get(j.name, x) for (j, _), x in zip(extra, targets)]
            phases.append(replace(phase, target=(*phase.target, *targets)))
        return replace(self, joints=(*self.joints, *(j for j, _ in extra)),
                       initial_angle=(*self.initial_angle, *(x for _, x in extra)),
                       phases=tuple(phases))

    def joint_index(self, joint: int | str) -> int:
        """Index of a joint given by index or name."""
        names = [j.name for j in self.joints]
        if isinstance(joint, str):
            if joint not in names:
                raise ValueError(f"scenario {self.name} has no joint {joint!r}; "
                                 f"choose from {', '.join(names)}")
            return names.index(joint)
        if not 0 <= joint < len(names):
            raise ValueError(f"joint index {joint} is outside [0, {len(names) - 1}]")
        return joint

    def drive_enabled(self, joint: int | str = 0) -> tuple[bool, ...]:
        """Per phase, whether the joint's drive is on: always, unless the joint rests when
        holding (`Joint.rest_when_holding`) and the phase holds its position."""
        j = self.joint_index(joint)
        rests = self.joints[j].rest_when_holding
        return tuple(not (rests and start == end) for _, _, start, end in self._joint_segments[j])

    def reference_segments(self, joint: int | str = 0) -> list[tuple[float, float, float, float]]:
        """(start time, end time [s], start, end position [rad or m]) of one joint per phase."""
        j = self.joint_index(joint)
        out, position = [], self.initial_angle[j]
        for (_, t0, t1), phase in zip(self.phase_times(), self.phases):
            out.append((t0, t1, position, phase.target[j]))
            position = phase.target[j]
        return out

    @cached_property
    def _phase_spans(self) -> tuple[tuple[float, float], ...]:
        """(start, end) of each phase [s], computed once: the sequencer reads it every step."""
        return tuple((t0, t1) for _, t0, t1 in self.phase_times())

    @cached_property
    def _phase_starts(self) -> tuple[float, ...]:
        return tuple(t0 for t0, _ in self._phase_spans)

    @cached_property
    def _joint_segments(self) -> tuple[tuple[tuple[float, float, float, float], ...], ...]:
        """`reference_segments` of every joint, computed once."""
        return tuple(tuple(self.reference_segments(j)) for j in range(len(self.joints)))

    def _phase_at(self, time: float, tolerance: float = 0.0) -> int:
        """Index of the phase that holds time (phases hold [start, end)); -1 before 0. A time
        within tolerance [s] before a phase start counts as that start."""
        return bisect_right(self._phase_starts, time + tolerance) - 1

    def reference_at(self, time: float, tolerance: float = 0.0) -> tuple[float, ...]:
        """Reference position of each joint [rad or m] at a time [s] (tolerance: `_phase_at`)."""
        if time > self.duration:
            return self.phases[-1].target
        k = self._phase_at(time, tolerance)
        if k < 0:
            return self.initial_angle
        out = []
        for segments in self._joint_segments:
            t0, t1, start, end = segments[k]
            out.append(ramp(start, end, "quintic", (time - t0) / (t1 - t0)))
        return tuple(out)

    def input_segments(self, variant: Variant) -> list[dict[str, tuple[Any, Any, str]]]:
        """Per phase, each input as (value at start, value at end, ramp shape).

        The variant's phase inputs replace those of the phases they name, its fixed inputs
        replace the scenario's, and its dropped inputs are left out.
        """
        changes = [{**phase.inputs, **variant.phase_inputs.get(phase.name, {})}
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

    def inputs_at(self, time: float, segments: list[dict[str, tuple[Any, Any, str]]],
                  tolerance: float = 0.0) -> dict[str, float | bool]:
        """Input values at a time [s] (a phase's changes apply from its start; none before 0).

        segments: `input_segments(variant)`, computed once per variant; tolerance: `_phase_at`.
        """
        k = self._phase_at(time, tolerance)
        if k < 0:
            return {n: False if isinstance(end, bool) else 0.0
                    for n, (_, end, _) in segments[0].items()}
        t0, t1 = self._phase_spans[k]
        s = min(max((time - t0) / (t1 - t0), 0.0), 1.0)
        return {n: ramp(start, end, shape, s) for n, (start, end, shape) in segments[k].items()}
