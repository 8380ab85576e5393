"""Scenario files: the standard-library core (fmu_src.units.sequencer.scenario) and the
harness's vectorised
evaluation give the same signals, the expected values come out at known instants, bad files
are rejected with clear messages, and the ScenarioSequencer FMU plays a scenario as the
harness does."""

from __future__ import annotations

import gc
import math
import subprocess
import sys
import time
import zipfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import play_sequencer
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from fmu_src.units.sequencer import scenario as core
from fmu_src.units.sequencer.ScenarioSequencer import EMBEDDED_MODULE
from harness import scenarios
from harness.drive import motor as drive
from harness.engines.plan import enabled_steps
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU
from harness.scenarios import RAMP_SHAPES

SHIPPED = [(name, variant) for name in scenarios.available()
           for variant in scenarios.load(name).variants]


def sample_times(scenario: scenarios.Scenario) -> np.ndarray:
    """2001 times over and beyond the task, plus every phase boundary exactly [s]."""
    boundaries = [t for _, t0, t1 in scenario.phase_times() for t in (t0, t1)]
    return np.unique(np.concatenate([np.linspace(-0.5, scenario.duration + 0.5, 2001),
                                     boundaries, np.arange(0.0, scenario.duration, 1e-3)]))


@pytest.mark.parametrize("name, variant", SHIPPED)
def test_core_scalar_evaluation_equals_harness_vectorised(name: str, variant: str) -> None:
    scenario = scenarios.load(name)
    times = sample_times(scenario)
    references = np.array([scenario.reference_at(float(t)) for t in times])
    for j in range(len(scenario.joints)):
        np.testing.assert_allclose(references[:, j], scenario.reference(times, j),
                                   rtol=0.0, atol=1e-12)
    segments = scenario.input_segments(scenario.variant(variant))
    scalar = [scenario.inputs_at(float(t), segments) for t in times]
    for input_name, signal in scenario.inputs(times, scenario.variant(variant)).items():
        values = np.array([row[input_name] for row in scalar])
        if signal.dtype == bool:
            assert values.dtype == bool and np.array_equal(values, signal), input_name
        else:
            np.testing.assert_allclose(values, signal, rtol=0.0, atol=1e-12,
                                       err_msg=input_name)


def test_franchetti_values_at_known_instants() -> None:
    """Phase II (4-14 s) moves 60 -> 180 deg: half way at 9 s (the quintic is 1/2 at s = 1/2);
    phase III (14-17 s) ramps the payload linearly to 1 kg with the pulley free."""
    scenario = scenarios.load("franchetti2021")
    assert scenario.reference_at(9.0) == pytest.approx((math.radians(120.0),), abs=1e-15)
    assert scenario.reference_at(40.0) == (math.radians(340.0),)
    assert scenario.reference_at(-1.0) == (math.radians(60.0),)
    segments = scenario.input_segments(scenario.variant("self_regulating"))
    assert scenario.inputs_at(15.5, segments) == {
        "slider_locked": False, "pulley_locked": False, "payload": 0.5,
        "counterweight_added": 0.5}
    assert scenario.inputs_at(33.0, segments)["slider_locked"] is True
    unregulated = scenario.input_segments(scenario.variant("unregulated"))
    assert scenario.inputs_at(15.5, unregulated)["counterweight_added"] == 0.0


def test_ciupitu_payload_follows_the_angle() -> None:
    """quintic_ease_out at the middle of the down stroke: ease_out(quintic(1/2)) = 3/4."""
    scenario = scenarios.load("ciupitu2018")
    segments = scenario.input_segments(scenario.variant("parabolic_balanced"))
    payload_max = 4.0 / 9.81
    assert scenario.inputs_at(11.0, segments)["payload"] == pytest.approx(0.75 * payload_max,
                                                                         rel=1e-12)


def test_demian_joints_and_targets() -> None:
    scenario = scenarios.load("demian2022")
    q1, q2 = scenario.joints
    assert (q1.kind, q1.motor, q1.effort) == ("revolute", "geared", "tau1")
    assert (q2.kind, q2.motor, q2.effort, q2.unit) == ("prismatic", "lead_screw", "f2", "m")
    assert q2.hold_effort(1.5) == 1.5                       # a static effort, held as it is
    assert scenario.joints[0].name == "q1" and scenario.duration == 8.0
    assert scenario.reference_at(1.5) == pytest.approx((0.35, 0.15), abs=1e-15)
    assert scenario.reference_at(3.5) == (0.7, 0.3)
    assert scenario.reference_at(5.5) == pytest.approx((0.35, 0.15), abs=1e-15)
    assert scenario.reference_at(8.0) == (0.0, 0.0)
    assert scenario.baselines == dict.fromkeys(scenario.variants, "uncompensated")
    assert scenario.variant("uncompensated").parameters == {"compensated": False}


def test_a_variant_drives_joints_of_its_own() -> None:
    """franchetti2021's active_relocation: the link, then the carriage q, which holds 0 until
    phase III takes it to 58.3 mm (a quintic: half way at 15.5 s) and holds that after."""
    scenario = scenarios.load("franchetti2021")
    variant = scenario.variant("active_relocation")
    assert scenario.for_variant(scenario.variant("self_regulating")) is scenario
    resolved = scenario.for_variant(variant)
    assert [j.name for j in resolved.joints] == ["theta", "q"]
    assert resolved.joints[1].motor == "trapezoidal_screw" and resolved.joints[1].unit == "m"
    assert resolved.for_variant(variant) is resolved      # resolving twice adds nothing
    q_bal = 0.35 * 9.81 / (981.0 * 0.06)                  # payload w g / (k x1A) for 1 kg
    assert resolved.reference_at(9.0) == (pytest.approx(math.radians(120.0)), 0.0)
    assert resolved.reference_at(15.5) == pytest.approx((math.pi, q_bal / 2), abs=1e-15)
    assert resolved.reference_at(30.0) == pytest.approx((math.radians(340.0), q_bal),
                                                        abs=1e-15)
    # the payload follows q's quintic, so the link stays balanced on the way
    segments = scenario.input_segments(variant)
    assert scenario.inputs_at(15.5, segments) == {"payload": 0.5}
    assert scenario.inputs_at(14.3, segments)["payload"] == pytest.approx(
        resolved.reference_at(14.3)[1] / q_bal, rel=1e-12)


def test_default_joint_holds_the_negative_load() -> None:
    (joint,) = scenarios.load("franchetti2021").joints
    assert (joint.position, joint.static_output, joint.static_is_load) == (
        "theta", "tau_gravity", True)
    assert joint.hold_effort(2.0) == -2.0


def test_joint_table_renames_the_default_joint(tmp_path: Path) -> None:
    path = tmp_path / "renamed.toml"
    path.write_text(FRANCHETTI.replace('baseline = "unbalanced"', 'baseline = "unbalanced"\n'
                                       '[joint]\nstatic_effort = "holding_torque"\n'
                                       'motor = "lead_screw"', 1))
    (joint,) = scenarios.load(path).joints
    assert (joint.static_output, joint.static_is_load, joint.motor) == (
        "holding_torque", False, "lead_screw")
    assert joint.position == "theta" and joint.hold_effort(2.0) == 2.0


def test_motor_names_are_the_harness_drives() -> None:
    assert tuple(drive.MOTORS) == core.MOTORS


def test_sweep_paths_keep_working() -> None:
    """A sweep sets one number as a one-joint scenario's target; two joints need two."""
    franchetti = scenarios.load("franchetti2021")
    phase = replace(franchetti.phases[1], target=math.pi)
    assert phase.target == (math.pi,)
    moved = replace(franchetti, phases=(franchetti.phases[0], phase, *franchetti.phases[2:]))
    assert isinstance(moved, scenarios.Scenario)
    assert moved.reference(np.array([14.0]))[0] == math.pi
    demian = scenarios.load("demian2022")
    with pytest.raises(ValueError, match="1 phase out targets for 2 joint"):
        replace(demian, phases=(replace(demian.phases[0], target=0.5), *demian.phases[1:]))


DEMIAN = (scenarios.SCENARIO_DIR / "demian2022.toml").read_text()
FRANCHETTI = (scenarios.SCENARIO_DIR / "franchetti2021.toml").read_text()


@pytest.mark.parametrize("text, message", [
    (DEMIAN.replace('targets = { q1 = 0.7, q2 = 0.3 }', "target_deg = 40.0"),
     "phase out: target_deg is for a scenario with one revolute joint"),
    (DEMIAN.replace('targets = { q1 = 0.7, q2 = 0.3 }', "targets = { q1 = 0.7, q3 = 0.3 }"),
     "phase out: targets name no joint q3"),
    (DEMIAN.replace('effort = "f2"\n', ""), r"joint q2 needs .* \(missing or doubled: effort\)"),
    (DEMIAN.replace('effort = "f2"\n', 'effort = "f2"\nstatic_load = "f2_gravity"\n'),
     "joint q2 needs .*missing or doubled: static_effort, static_load"),
    (DEMIAN.replace('kind = "prismatic"', 'kind = "helical"'),
     "joint q2: kind = 'helical' is not one of revolute, prismatic"),
    (DEMIAN.replace('motor = "lead_screw"', 'motor = "hydraulic"'),
     "joint q2: motor = 'hydraulic' is not one of geared, lead_screw"),
    (DEMIAN.replace('motor = "lead_screw"', 'motr = "lead_screw"'),
     "joint q2: unknown key.* motr"),
    (DEMIAN.replace("initial = 0.0            # m", 'initial = "zero"'),
     "joint q2: initial = 'zero' is not a finite number"),
    (DEMIAN.replace("duration = 3.0\ntargets = { q1 = 0.7", "duration = 0.0\ntargets = { q1 = 0.7"),
     r"phase out: duration = 0.0 s is outside \(0, inf\)"),
    (FRANCHETTI.replace("initial_angle_deg = 60.0", ""), "initial_angle_deg is missing"),
    (FRANCHETTI.replace("target_deg = 180.0\n", "target_deg = 180.0\ntargt = 1\n", 1),
     "phase II move: unknown key.* targt"),
    (FRANCHETTI.replace('baseline = "unbalanced"', 'baseline = "balanced"'),
     "baseline balanced names no variant; choose from self_regulating"),
    (FRANCHETTI.replace("[variants.active_relocation.joints.q]",
                        "[variants.active_relocation.joints.theta]"),
     "variant active_relocation joints theta: the scenario has joints of these names"),
    (FRANCHETTI.replace('phase_targets = { "III regulate" = { q',
                        'phase_targets = { "III regulat" = { q'),
     "variant active_relocation phase_targets names no phase III regulat"),
    (FRANCHETTI.replace('phase_targets = { "III regulate" = { q',
                        'phase_targets = { "III regulate" = { theta'),
     "variant active_relocation phase_targets III regulate: targets name no joint theta"),
    (FRANCHETTI.replace('static_effort = "F_hold"', ""),
     r"joint q needs .*static_effort, static_load"),
    (FRANCHETTI.replace('source = "Franchetti et al. 2021"', "source = 2021"),
     "source = 2021 must be a string"),
])
def test_bad_files_are_rejected_with_clear_messages(tmp_path: Path, text: str,
                                                    message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"bad.toml: {message}"):
        scenarios.load(path)


# ---- many phases: loading and playing take time linear in the number of phases -------
def many_phases(path: Path, count: int) -> Path:
    """A scenario of `count` 10 ms phases: targets, ramps of every shape and a Boolean that
    steps, so that every part of the evaluation sees every phase."""
    shapes = list(scenarios.RAMP_SHAPES)
    phases = "".join(
        f'[[phases]]\nname = "p{i}"\nduration = 0.01\ntarget_deg = {i % 7 * 10}\n'
        f'inputs = {{ payload = {{ ramp = {i % 3}.0, shape = "{shapes[i % len(shapes)]}" }}, '
        f"slider_locked = {'true' if i % 2 else 'false'} }}\n" for i in range(count))
    path.write_text('name = "many"\nmodel = "SelfRegulatingBalancer"\ninitial_angle_deg = 5.0\n'
                    f"[variants.a]\n{phases}")
    return path


def test_phase_limit_and_many_phases_load_and_play(tmp_path: Path) -> None:
    """MAX_PHASES phases load and evaluate over the whole run (every 1 ms step), the
    vectorised evaluation agreeing with the scalar one; one more phase is refused naming the
    limit. (That this is linear in the phases is timed in the slow test below, not here: a
    wall-time bound in `make test` fails on a loaded machine.)"""
    scenario = scenarios.load(many_phases(tmp_path / "many.toml", core.MAX_PHASES))
    times = np.arange(round(scenario.duration / 1e-3) + 1) * 1e-3
    reference = scenario.reference(times)
    inputs = scenario.inputs(times, scenario.variant("a"))
    assert len(scenario.phases) == core.MAX_PHASES and len(times) == 100_001
    picked = times[::997]  # the vectorised evaluation is the core's scalar one
    segments = scenario.input_segments(scenario.variant("a"))
    np.testing.assert_allclose([scenario.reference_at(float(t))[0] for t in picked],
                               reference[::997], rtol=0.0, atol=1e-12)
    scalar = [scenario.inputs_at(float(t), segments) for t in picked]
    np.testing.assert_allclose([row["payload"] for row in scalar], inputs["payload"][::997],
                               rtol=0.0, atol=1e-12)
    assert [row["slider_locked"] for row in scalar] == list(inputs["slider_locked"][::997])
    with pytest.raises(ValueError, match="many.toml: phases: 10,001 \\[\\[phases\\]\\] tables, "
                                         "more than 10,000"):
        scenarios.load(many_phases(tmp_path / "many.toml", core.MAX_PHASES + 1))


def _best_time(action: Callable[[], object], repeats: int = 3) -> float:
    """The shortest of `repeats` wall times of action() [s], without the garbage collector
    (whose full collections make any allocation-heavy work look superlinear)."""
    best = math.inf
    gc.disable()
    try:
        for _ in range(repeats):
            start = time.perf_counter()
            action()
            best = min(best, time.perf_counter() - start)
    finally:
        gc.enable()
    return best


@pytest.mark.slow
def test_loading_and_playing_scale_linearly_with_the_phases(tmp_path: Path) -> None:
    """16 times the phases take about 16 times as long (at most 40; quadratic was 256) to
    load, to evaluate vectorised and to play step by step as the sequencer does."""
    def cost(count: int) -> float:
        path = many_phases(tmp_path / f"many{count}.toml", count)
        scenario = scenarios.load(path)
        variant = scenario.variant("a")
        times = np.arange(round(scenario.duration / 1e-3)) * 1e-3
        segments = scenario.input_segments(variant)

        def play() -> None:
            scenarios.load(path)
            scenario.reference(times)
            scenario.inputs(times, variant)
            for t in times[::10]:
                scenario.reference_at(float(t), 1e-6)
                scenario.inputs_at(float(t), segments, 1e-6)
        return _best_time(play)

    assert cost(core.MAX_PHASES) < 40.0 * cost(core.MAX_PHASES // 16)


# ---- the ScenarioSequencer FMU -------------------------------------------------------------
SEQUENCER_STEP = 1.0 / 64.0  # [s], a binary fraction: every phase boundary is a step time


@pytest.fixture(scope="module")
def sequencer() -> Path:
    return fmu_build.fmu_path("ScenarioSequencer")


def start_sequencer(fmu: CoSimFMU, variant: str) -> None:
    """Initialise with the String parameter `variant`."""
    fmu.initialize({"variant": variant})


def test_embedded_scenario_is_the_file(sequencer: Path) -> None:
    """The default sequencer FMU carries the scenario module generated from franchetti2021."""
    with zipfile.ZipFile(sequencer) as archive:
        source = archive.read(f"resources/{'/'.join(EMBEDDED_MODULE)}").decode()
    module: dict[str, object] = {}
    exec(source, module)
    assert module["NAME"] == "franchetti2021"
    assert module["TOML"] == (scenarios.SCENARIO_DIR / "franchetti2021.toml").read_text()
    assert source == scenarios.embedded_source("franchetti2021")


def test_sequencer_model_description(sequencer: Path) -> None:
    assert validate_fmu(str(sequencer)) == []
    md = read_model_description(str(sequencer))
    variables = {v.name: v for v in md.modelVariables}
    variant = variables["variant"]
    assert (variant.type, variant.causality, variant.start) == ("String", "parameter",
                                                                "self_regulating")
    # the references of every variant's joints (active_relocation's carriage q too)
    assert [v.name for v in md.modelVariables if v.causality == "output"] == [
        "theta_ref", "theta_enable", "q_ref", "q_enable", "slider_locked", "pulley_locked",
        "payload", "counterweight_added"]
    assert variables["theta_ref"].declaredType.unit == "rad"
    assert variables["q_ref"].declaredType.unit == "m"
    assert variables["slider_locked"].type == "Boolean"
    assert variables["slider_locked"].variability == "discrete"
    # the Real inputs carry the units of the mechanism's inputs they feed
    mechanism = {v.name: v for v in read_model_description(
        str(fmu_build.fmu_path("SelfRegulatingBalancer"))).modelVariables}
    for name in ("payload", "counterweight_added"):
        assert variables[name].declaredType.unit == mechanism[name].declaredType.unit == "kg"


@pytest.mark.parametrize("variant", list(scenarios.load("franchetti2021").variants))
def test_sequencer_plays_the_scenario_as_the_harness(sequencer: Path, variant: str) -> None:
    scenario = scenarios.load("franchetti2021")
    n = round(scenario.duration / SEQUENCER_STEP)
    times = np.arange(n + 1) * SEQUENCER_STEP
    with CoSimFMU(sequencer, variant) as fmu:
        played = play_sequencer(fmu, variant, n, SEQUENCER_STEP)
    resolved = scenario.for_variant(scenario.variant(variant))
    np.testing.assert_allclose(played["theta_ref"], resolved.reference(times, "theta"),
                               rtol=0.0, atol=1e-12)
    # the carriage's reference where the variant drives it, else 0
    q = resolved.reference(times, "q") if len(resolved.joints) > 1 else np.zeros(n + 1)
    np.testing.assert_allclose(played["q_ref"], q, rtol=0.0, atol=1e-12)
    # whether each joint's drive is on over the step from each time, else on
    for j, joint in enumerate(scenario.for_variant(scenario.variant("active_relocation")).joints):
        on = (np.array(enabled_steps(resolved, j, np.append(times, times[-1] + SEQUENCER_STEP)))
              if joint.name in [jt.name for jt in resolved.joints] else np.ones(n + 1, bool))
        assert np.array_equal(played[f"{joint.position}_enable"], on), joint.name
    inputs = scenario.inputs(times, scenario.variant(variant))
    for name in [n for n in list(played) if not n.endswith(("_ref", "_enable"))]:
        if name not in inputs:  # dropped by the variant: stays at its default
            assert not played[name].any(), name
        elif inputs[name].dtype == bool:
            assert np.array_equal(played[name], inputs[name]), name
        else:
            np.testing.assert_allclose(played[name], inputs[name], rtol=0.0, atol=1e-12,
                                       err_msg=name)


def test_sequencer_state_restore_replays(sequencer: Path) -> None:
    with CoSimFMU(sequencer, "state") as fmu:
        start_sequencer(fmu, "unregulated")
        outputs = fmu.names("output")
        dt = SEQUENCER_STEP
        for k in range(800):  # to 12.5 s, in phase II
            fmu.step(k * dt, dt)
        state = fmu.slave.getFMUstate()

        def replay() -> list[dict]:
            rows = []
            for k in range(800, 1200):  # across phases III and IV
                fmu.step(k * dt, dt)
                rows.append(fmu.get(outputs))
            return rows

        first = replay()
        fmu.slave.setFMUstate(state)
        assert replay() == first
        fmu.slave.freeFMUstate(state)


UNKNOWN_VARIANT_SCRIPT = """
import os, sys
from harness.fmu.loader import CoSimFMU, FMICallException
with CoSimFMU(sys.argv[1], "unknown") as fmu:
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    fmu.slave.setString(fmu.references(["variant"]), ["self_regulated"])
    try:
        fmu.slave.exitInitializationMode()
    except FMICallException as error:
        fmu.fatal = error.status == 4  # fmi2Fatal: close() must not call the FMU again
        print({3: "error", 4: "fatal"}.get(error.status, error.status))
    print(*(m.message for m in fmu.messages if m.status == "Error"), sep="\\n", flush=True)
os._exit(0)
"""


def test_sequencer_rejects_an_unknown_variant(sequencer: Path) -> None:
    """fmi2Error with the message naming the choices (in a child process, as any FMU
    failure test that may end a process)."""
    result = subprocess.run([sys.executable, "-c", UNKNOWN_VARIANT_SCRIPT, str(sequencer)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "error"
    assert any("no variant 'self_regulated'; choose from self_regulating, unregulated, "
               "unbalanced, ciupitu" in line for line in lines[1:])


# ---- phases some variants perform alone, drives a variant pins (issue 33) -----------------
# a hold at 60 deg (2 s), a phase only `regulating` performs (to 180 deg in 4 s, ramping the
# payload to 1 kg with the slider free) and a move to 120 deg (3 s) with the payload 0.5 kg
THREE_PHASES = """name = "three"
model = "SelfRegulatingBalancer"
initial_angle_deg = 60.0

[[phases]]
name = "hold"
duration = 2.0
target_deg = 60.0
inputs = { payload = 0.0, slider_locked = true }

[[phases]]
name = "to posture"
duration = 4.0
target_deg = 180.0
variants = ["regulating"]
inputs = { payload = { ramp = 1.0 }, slider_locked = false }

[[phases]]
name = "move"
duration = 3.0
target_deg = 120.0
inputs = { payload = 0.5, slider_locked = true }

[variants.regulating]
[variants.plain]
"""


def test_a_phase_named_for_one_variant_is_left_out_of_the_others(tmp_path: Path) -> None:
    """`plain` skips `to posture`: 2 phases over 2 + 3 s, its move from where it stands (60
    deg) to 120 deg, half way (90 deg) at 3.5 s as a quintic is 1/2 at s = 1/2; `regulating`
    performs all 3 over 9 s and moves from 180 deg to 120 deg, 150 deg at 7.5 s. Each plays
    the inputs of the phases it performs."""
    path = tmp_path / "three.toml"
    path.write_text(THREE_PHASES)
    scenario = scenarios.load(path)
    assert scenario.duration == 9.0  # every phase, as written
    plain = scenario.for_variant(scenario.variant("plain"))
    regulating = scenario.for_variant(scenario.variant("regulating"))
    assert [p.name for p in plain.phases] == ["hold", "move"] and plain.duration == 5.0
    assert [p.name for p in regulating.phases] == ["hold", "to posture", "move"]
    assert regulating.duration == 9.0
    assert all(p.variants == () for p in (*plain.phases, *regulating.phases))
    deg = math.radians
    assert plain.reference_segments() == [(0.0, 2.0, deg(60.0), deg(60.0)),
                                          (2.0, 5.0, deg(60.0), deg(120.0))]
    assert plain.reference_at(3.5) == pytest.approx((deg(90.0),), abs=1e-15)
    assert regulating.reference_segments()[2] == (6.0, 9.0, deg(180.0), deg(120.0))
    assert regulating.reference_at(7.5) == pytest.approx((deg(150.0),), abs=1e-15)
    at = plain.inputs_at(3.5, plain.input_segments(scenario.variant("plain")))
    assert at == {"payload": 0.5, "slider_locked": True}
    at = regulating.inputs_at(4.0, regulating.input_segments(scenario.variant("regulating")))
    assert at == {"payload": 0.5, "slider_locked": False}  # half the linear ramp to 1 kg


@pytest.mark.parametrize("performers, message", [
    ('"regulating"', r"variants = 'regulating' must be a non-empty list"),
    ("[]", r"variants = \[\] must be a non-empty list"),
    ("[1]", r"variants = \[1\] must be a non-empty list"),
    ('["regulating", "nobody"]', "variants names no variant nobody"),
])
def test_a_phase_naming_variants_wrongly_is_refused(tmp_path: Path, performers: str,
                                                    message: str) -> None:
    """One ValueError naming the file, the phase and the variants to choose from."""
    path = tmp_path / "bad.toml"
    path.write_text(THREE_PHASES.replace('variants = ["regulating"]',
                                         f"variants = {performers}"))
    with pytest.raises(ValueError, match=f"^bad.toml: phase to posture: {message}") as error:
        scenarios.load(path)
    assert str(error.value).endswith("choose from regulating, plain")
    assert "\n" not in str(error.value)


PINNED = {"motor": "RE25", "gearhead": "GP32C", "ratio": 246.0}


def test_a_variant_pins_the_drives_of_its_joints(tmp_path: Path) -> None:
    """franchetti2021 with ciupitu's link and active_relocation's carriage q pinned: those
    joints of those variants carry the pins (as a joint's `drive` = sorted (key, value)s), the
    other variants' joints none; a joint the variant does not have is refused by name."""
    path = tmp_path / "pinned.toml"
    pins = ('drives = { theta = { motor = "RE25", gearhead = "GP32C", ratio = 246.0 } }\n'
            '[variants.active_relocation.drives.q]\nmotor = "RE25"\ngearhead = "GP32C"\n'
            "ratio = 3.7\n")
    # the first line goes to the end of [variants.ciupitu], the table before
    path.write_text(FRANCHETTI.replace("[variants.active_relocation]\n",
                                       pins + "[variants.active_relocation]\n", 1))
    scenario = scenarios.load(path)
    ciupitu = scenario.for_variant(scenario.variant("ciupitu"))
    assert ciupitu.joints[0].drive == tuple(sorted(PINNED.items()))
    active = scenario.for_variant(scenario.variant("active_relocation"))
    assert [(j.name, dict(j.drive)) for j in active.joints] == [
        ("theta", {}), ("q", {"motor": "RE25", "gearhead": "GP32C", "ratio": 3.7})]
    for name in ("self_regulating", "unregulated", "unbalanced"):
        assert scenario.for_variant(scenario.variant(name)).joints[0].drive == (), name
    assert scenario.joints[0].drive == ()  # the scenario's own joint is not pinned
    path.write_text(path.read_text().replace("drives = { theta", "drives = { phi"))
    with pytest.raises(ValueError, match="^pinned.toml: variant ciupitu drives names no "
                                         "joint phi; choose from theta$"):
        scenarios.load(path)


def test_the_sequencer_plays_each_variant_its_own_phases(tmp_path: Path) -> None:
    """A ScenarioSequencer built for THREE_PHASES plays, for each variant, the references and
    inputs of the scenario resolved for it (to 1e-12: the same quintic and ramp formulas), so
    `plain` plays the move's inputs in its move (payload 0.5 kg), not those of the phase it
    skips."""
    path = tmp_path / "three.toml"
    path.write_text(THREE_PHASES)
    fmu_path = fmu_build.fmu_path("ScenarioSequencer", tmp_path / "fmus",
                                  sequencer_scenario=path)
    scenario = scenarios.load(path)
    for name in scenario.variants:
        variant = scenario.variant(name)
        resolved = scenario.for_variant(variant)
        n = round(resolved.duration / SEQUENCER_STEP)
        times = np.arange(n + 1) * SEQUENCER_STEP
        with CoSimFMU(fmu_path, name) as fmu:
            played = play_sequencer(fmu, name, n, SEQUENCER_STEP)
        np.testing.assert_allclose(played["theta_ref"], resolved.reference(times), rtol=0.0,
                                   atol=1e-12, err_msg=name)
        inputs = resolved.inputs(times, variant)
        np.testing.assert_allclose(played["payload"], inputs["payload"], rtol=0.0, atol=1e-12,
                                   err_msg=name)
        assert np.array_equal(played["slider_locked"], inputs["slider_locked"]), name
    assert played["payload"][-1] == 0.5  # `plain`, the last one, ends its move with 0.5 kg


def test_a_variant_that_performs_no_phase_is_refused(tmp_path: Path) -> None:
    """Every phase names `regulating`: `plain` would run a scenario without phases, so the
    file is refused where it is read, naming the variant (not a traceback at its run)."""
    path = tmp_path / "idle.toml"
    path.write_text(THREE_PHASES.replace('variants = ["regulating"]\n', "")
                    .replace("[[phases]]\n", '[[phases]]\nvariants = ["regulating"]\n'))
    assert THREE_PHASES.count("[[phases]]") == path.read_text().count('["regulating"]') == 3
    with pytest.raises(ValueError, match="^idle.toml: variant plain performs no phase"):
        scenarios.load(path)


def test_after_a_phase_some_variants_skip_each_phase_gives_its_targets(tmp_path: Path) -> None:
    """A phase without a target holds the previous one, which after `to posture` is 180 deg
    for `regulating` and 60 deg for `plain`: the move without its target is refused (it took
    180 deg from the file's order, moving `plain` there in a phase that names no target)."""
    path = tmp_path / "held.toml"
    path.write_text(THREE_PHASES.replace("target_deg = 120.0\n", ""))
    with pytest.raises(ValueError, match="^held.toml: phase move gives no target for theta: "
                                         "after phase to posture, which only some variants"):
        scenarios.load(path)


def test_no_ramp_shape_overshoots_its_end() -> None:
    """The quintic rounds to up to 1 + 6 ulp at s just below 1 (8750 of the 20000 floats
    below 1 tried here): a ramp to 0 through it ended at -5.6e-17 kg of payload, which the
    FMUs refuse (a ciupitu2018 study task). Every shape stays in [0, 1], and a ramp to 0
    ends at 0 or above; where the quintic is at most 1 the shapes give what it gives."""
    s = np.nextafter(1.0, 0.0) - np.arange(20000) * 2.0 ** -53
    assert (core.quintic(s) > 1.0).any()   # the rounding this guards against
    for name, shape in RAMP_SHAPES.items():
        values = shape(s)
        assert ((values >= 0.0) & (values <= 1.0)).all(), name
        assert all(core.ramp(0.25, 0.0, name, float(x)) >= 0.0 for x in s[::97]), name
    inside = np.random.default_rng(1).uniform(0.0, 1.0, 1000)
    assert (RAMP_SHAPES["quintic"](inside) == np.minimum(core.quintic(inside), 1.0)).all()
