"""The DcMotorDrive and PositionController FMUs are the harness's drive and controller:
stepped by FMPy with the same inputs they give what harness.drive.motor.sampled_motor and
harness.drive.controller.discrete_pid give (python-control c2d there, closed forms in the FMUs, so
agreement to rounding, not bit for bit), also when the step size changes; chained
Gauss-Seidel with a mechanism FMU they reproduce the harness's loop; plus the exact copper
loss, voltage saturation, defaults and misuse.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import failed_initialisation, open_fmu, refused_set
from fmpy import read_model_description

from fmu_src.mechanisms.self_regulating import physics as self_regulating
from fmu_src.units.controller.PositionController import ControllerParameters
from fmu_src.units.drive.dc_motor import STUCK_SPEED, step_energies, stuck_mode_effort
from fmu_src.units.sequencer.scenario import Joint
from harness.drive.controller import design_pid, discrete_pid, discretise
from harness.drive.metrics import drive_metrics
from harness.drive.motor import MotorParameters, sampled_motor
from harness.drive.trace import DriveTrace, SampledDrive
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

MOTOR = MotorParameters()
JOINT = Joint("theta", "theta", "omega", "tau_drive", "theta0", "J_link", "d_link", "J_drive",
              "tau_gravity", True)
LINK = self_regulating.Parameters()
GAINS = design_pid(MOTOR, LINK.J_link + MOTOR.J_drive, LINK.d_link)
DT = 1e-3


@pytest.fixture(scope="module")
def motor_fmu() -> Path:
    return fmu_build.fmu_path("DcMotorDrive")


@pytest.fixture(scope="module")
def controller_fmu() -> Path:
    return fmu_build.fmu_path("PositionController")


def drive_fmu(fmu: CoSimFMU, inputs: Mapping[str, Sequence[float]], steps: Sequence[float],
              outputs: Sequence[str]) -> np.ndarray:
    """Step k: set the k-th value of every input, doStep(t_k, steps[k]); row k holds the
    outputs after it."""
    rows, t = np.empty((len(steps), len(outputs))), 0.0
    for k, dt in enumerate(steps):
        fmu.set({name: values[k] for name, values in inputs.items()})
        fmu.step(t, dt)
        t += dt
        rows[k] = list(fmu.get(outputs).values())
    return rows


def test_motor_fmu_gives_the_harness_sampled_motor(motor_fmu: Path) -> None:
    """Voltage and speed sequences within the limits (steps, ramps, noise), from a current
    that holds a load: tau_drive and i as harness.drive.motor.sampled_motor to rounding, E_in,
    E_drawn and E_copper as harness.drive.metrics sums them from the drive's trace."""
    rng = np.random.default_rng(6)
    n, i0 = 3000, 1.5
    t = np.arange(n) * DT
    voltage = np.clip(np.where(t < 1.0, 12.0 * np.sign(np.sin(7.0 * t)), -6.0)
                      + rng.normal(0.0, 3.0, n), -MOTOR.V_supply, MOTOR.V_supply)
    omega = 4.0 * np.sin(2.0 * t) + rng.normal(0.0, 0.5, n)
    drive = sampled_motor(MOTOR, DT, current=i0)
    starts, steps = [], []
    for v, w in zip(voltage, omega):
        starts.append(drive.current)
        steps.append(drive.step(v, w))
    starts.append(drive.current)
    current, torque = np.array(steps).T
    with open_fmu(motor_fmu, {"i0": i0}) as fmu:
        out = drive_fmu(fmu, {"V": voltage, "omega": omega}, [DT] * n,
                        ["tau_drive", "i", "E_in", "E_drawn", "E_copper"])
    assert np.ptp(torque) > 50.0 and (current < 0).any()  # motoring and regenerating
    np.testing.assert_allclose(out[:, 0], torque, rtol=0, atol=1e-12 * np.abs(torque).max())
    np.testing.assert_allclose(out[:, 1], current, rtol=0, atol=1e-12 * np.abs(current).max())
    power = voltage * current
    assert out[-1, 2] == pytest.approx(power.sum() * DT, rel=1e-11)
    assert out[-1, 3] == pytest.approx(np.maximum(power, 0.0).sum() * DT, rel=1e-11)
    still = np.zeros(n + 1)
    speed = np.append(omega, 0.0)
    trace = DriveTrace(JOINT, MOTOR, DT, voltage, current, torque, np.array(starts), still,
                       speed, still)
    expected = drive_metrics(trace)
    for column, name in enumerate(("E_in", "E_drawn", "E_copper"), start=2):
        assert out[-1, column] == pytest.approx(expected[name], rel=1e-11), name


def test_motor_fmu_with_a_lossy_gear_and_rests_gives_the_harness_sampled_motor(
        motor_fmu: Path) -> None:
    """A lossy transmission (eta 0.7, eta_back 0.6) and the drive switched off and on: the
    FMU's tau_drive and i are the harness's SampledMotor's, and its E_gear and E_copper the
    sums of step_energies, to rounding."""
    rng = np.random.default_rng(11)
    n, i0 = 2000, 1.0
    lossy = replace(MOTOR, eta=0.7, eta_back=0.6)
    voltage = rng.uniform(-MOTOR.V_supply, MOTOR.V_supply, n)
    omega = rng.choice([0.0, 0.002, -0.002, 3.0, -3.0], n)
    enabled = (np.arange(n) // 150) % 4 != 3
    drive = sampled_motor(lossy, DT, current=i0)
    expected, gear, copper = [], 0.0, 0.0
    for v, w, on in zip(voltage, omega, enabled):
        start = drive.current
        current, effort = drive.step(v, w, bool(on))
        e = step_energies(lossy, DT, v if on else 0.0, w, start, current, effort, 0.0, on)
        gear, copper = gear + e.E_gear, copper + e.E_copper
        expected.append((effort, current))
    with open_fmu(motor_fmu, {"i0": i0, "eta": 0.7, "eta_back": 0.6}) as fmu:
        out = drive_fmu(fmu, {"V": voltage, "omega": omega, "enable": enabled}, [DT] * n,
                        ["tau_drive", "i", "E_gear", "E_copper"])
    torque, current = np.array(expected).T
    assert (out[~enabled, :2] == 0.0).all() and gear > 0.0
    np.testing.assert_allclose(out[:, 0], torque, rtol=0, atol=1e-12 * np.abs(torque).max())
    np.testing.assert_allclose(out[:, 1], current, rtol=0, atol=1e-12 * np.abs(current).max())
    assert (out[-1, 2], out[-1, 3]) == pytest.approx((gear, copper), rel=1e-11)


def test_motor_fmu_given_the_joints_inertia_holds_the_stuck_mode_as_the_harness(
        motor_fmu: Path) -> None:
    """With J_joint set, speeds in and around the lossy transmission's blend and the drive
    switched off and on: tau_drive is the harness's stuck_mode_effort (from the step before
    while the drive was on), which in the blend is not the effort at the start speed; an FMU
    state taken mid-run and set again replays the same efforts."""
    rng = np.random.default_rng(12)
    n, i0, inertia = 600, 0.5, 0.08
    lossy = replace(MOTOR, eta=0.7, eta_back=0.6)
    edge = STUCK_SPEED / lossy.N
    voltage = rng.uniform(-2.0, 2.0, n)
    omega = rng.choice([0.0, 0.3 * edge, -0.7 * edge, 2.0 * edge], n)
    enabled = (np.arange(n) // 100) % 3 != 2
    drive, expected, explicit, previous = sampled_motor(lossy, DT, current=i0), [], [], None
    for v, w, on in zip(voltage, omega, enabled):
        current, effort = drive.step(v, w, bool(on))
        explicit.append(effort)
        if on:
            effort = stuck_mode_effort(lossy, current, w, effort, inertia, DT, previous)
        previous = (w, effort, DT) if on else None
        expected.append(effort)
    assert np.abs(np.subtract(expected, explicit)).max() > 0.01 * np.abs(expected).max()

    def run(fmu: CoSimFMU, steps: range) -> list[float]:
        out = []
        for k in steps:
            fmu.set({"V": voltage[k], "omega": omega[k], "enable": bool(enabled[k])})
            fmu.step(k * DT, DT)
            out.append(fmu.get(["tau_drive"])["tau_drive"])
        return out

    start = {"i0": i0, "eta": 0.7, "eta_back": 0.6, "J_joint": inertia}
    with open_fmu(motor_fmu, start) as fmu:
        first = run(fmu, range(n // 2))
        taken = fmu.slave.getFMUstate()
        try:
            rest = run(fmu, range(n // 2, n))
            fmu.slave.setFMUstate(taken)
            again = run(fmu, range(n // 2, n))
        finally:
            fmu.slave.freeFMUstate(taken)
    np.testing.assert_allclose(first + rest, expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())
    assert again == rest


def test_motor_fmu_recomputes_the_hold_when_the_step_size_changes(motor_fmu: Path) -> None:
    steps = [1e-3] * 20 + [2.5e-4] * 40 + [4e-3] * 10 + [1e-3] * 20
    voltage = np.linspace(-10.0, 20.0, len(steps))
    omega = np.linspace(3.0, -2.0, len(steps))
    expected, current = [], 0.0
    for dt, v, w in zip(steps, voltage, omega):
        drive = sampled_motor(MOTOR, dt, current=current)  # control.c2d at this step size
        expected.append(drive.step(v, w)[0])
        current = drive.current
    with open_fmu(motor_fmu) as fmu:
        out = drive_fmu(fmu, {"V": voltage, "omega": omega}, steps, ["i"])
    np.testing.assert_allclose(out[:, 0], expected, rtol=0, atol=1e-12 * max(map(abs, expected)))


@pytest.mark.parametrize("dt", [1e-4, 1e-3])
def test_motor_copper_loss_of_a_voltage_step_is_exact(motor_fmu: Path, dt: float) -> None:
    """Blocked rotor, 2 V from rest: i(t) = I (1 - exp(-t/tau)), tau = L_a/R_a, I = V/R_a,
    so R_a integral of i^2 = R_a I^2 (t - 2 tau (1 - e^-t/tau) + tau/2 (1 - e^-2t/tau)) at any
    step size, and E_in = E_copper + L_a i(t)^2 / 2."""
    volts, t_end = 2.0, 2e-3  # ~10 armature time constants: the transient still matters
    n = round(t_end / dt)
    with open_fmu(motor_fmu, {"V": volts}) as fmu:
        e_in, e_copper = drive_fmu(fmu, {}, [dt] * n, ["E_in", "E_copper"])[-1]
    tau, final = MOTOR.L_a / MOTOR.R_a, volts / MOTOR.R_a
    copper = MOTOR.R_a * final ** 2 * (t_end - 2 * tau * (1 - math.exp(-t_end / tau))
                                       + tau / 2 * (1 - math.exp(-2 * t_end / tau)))
    i_end = final * (1 - math.exp(-t_end / tau))
    assert e_copper == pytest.approx(copper, rel=1e-11)
    assert e_in == pytest.approx(copper + 0.5 * MOTOR.L_a * i_end ** 2, rel=1e-11)


def test_motor_voltage_saturates_at_V_supply(motor_fmu: Path) -> None:
    names = ["tau_drive", "i", "P_elec"]
    voltage = [30.0] * 5 + [-100.0] * 5
    with open_fmu(motor_fmu) as fmu:
        over = drive_fmu(fmu, {"V": voltage}, [DT] * 10, names)
    with open_fmu(motor_fmu) as fmu:
        limited = drive_fmu(fmu, {"V": np.clip(voltage, -24.0, 24.0)}, [DT] * 10, names)
    np.testing.assert_array_equal(over, limited)
    np.testing.assert_array_equal(over[:, 2], np.clip(voltage, -24.0, 24.0) * over[:, 1])


def test_motor_starts_from_its_initial_current(motor_fmu: Path) -> None:
    """At initialisation: i = i0, tau_drive = eta N K_t i0 (2.87 N m/A), E_* = 0, and the
    calculated J_drive = J_rotor N^2."""
    names = ["i", "tau_drive", "P_elec", "E_in", "E_drawn", "E_copper", "J_drive"]
    with open_fmu(motor_fmu, {"i0": 2.0, "V": 5.0}) as fmu:
        values = fmu.get(names)
    assert values == pytest.approx({"i": 2.0, "tau_drive": 2.0 * 111 * 0.0259, "P_elec": 10.0,
                                    "E_in": 0.0, "E_drawn": 0.0, "E_copper": 0.0,
                                    "J_drive": 33.5e-7 * 111 ** 2}, rel=1e-15)


def test_controller_fmu_gives_the_harness_discrete_pid(controller_fmu: Path) -> None:
    """A reference step with a lagging, noisy measured angle (the output saturates and
    recovers), from a preset integrator: V as harness.drive.controller.discrete_pid to rounding."""
    rng = np.random.default_rng(7)
    n, integral0 = 2000, 3.0
    t = np.arange(n) * DT
    reference = np.where(t < 0.2, 0.1, 0.6)
    theta = 0.1 + 0.5 * np.clip((t - 0.2) / 0.6, 0.0, 1.0) + rng.normal(0.0, 1e-3, n)
    pid = discrete_pid(GAINS, DT, MOTOR.V_supply)
    pid.reset(reference[0] - theta[0], integral=integral0)
    expected = np.array([(pid.update(r - q), pid.saturated) for r, q in zip(reference, theta)])
    start = {"integral0": integral0, "theta_ref": reference[0], "theta": theta[0]}
    with open_fmu(controller_fmu, start) as fmu:
        out = drive_fmu(fmu, {"theta_ref": reference, "theta": theta}, [DT] * n,
                        ["V", "saturated"])
    assert expected[:, 1].any() and not expected[:, 1].all()
    np.testing.assert_allclose(out[:, 0], expected[:, 0], rtol=0, atol=1e-12 * MOTOR.V_supply)
    np.testing.assert_array_equal(out[:, 1], expected[:, 1])


def test_controller_fmu_rests_and_restarts_as_the_harness_drive(controller_fmu: Path) -> None:
    """Switched off for 300 steps and on again: V = 0 while off, and over the whole sequence
    the voltages of the harness's SampledDrive (which holds, then restarts with the integral
    reset and no derivative kick), to rounding."""
    rng = np.random.default_rng(8)
    n = 1200
    reference = np.full(n + 1, 0.3)
    theta = 0.3 + rng.normal(0.0, 2e-3, n)
    enabled = (np.arange(n) < 400) | (np.arange(n) >= 700)
    pid = discrete_pid(GAINS, DT, MOTOR.V_supply)
    pid.reset(reference[0] - theta[0], integral=2.0)
    drive = SampledDrive(pid, sampled_motor(MOTOR, DT), reference.tolist(), enabled.tolist())
    for k in range(n):
        drive.step(k, theta[k], 0.0)
    start = {"integral0": 2.0, "theta_ref": reference[0], "theta": theta[0]}
    with open_fmu(controller_fmu, start) as fmu:
        out = drive_fmu(fmu, {"theta_ref": reference[:n], "theta": theta, "enable": enabled},
                        [DT] * n, ["V"])[:, 0]
    assert (out[~enabled] == 0.0).all() and (out[enabled] != 0.0).all()
    np.testing.assert_allclose(out, drive.voltage, rtol=0, atol=1e-12 * MOTOR.V_supply)


def test_controller_fmu_recomputes_its_coefficients_when_the_step_size_changes(
        controller_fmu: Path) -> None:
    steps = [1e-3] * 20 + [2.5e-4] * 40 + [4e-3] * 10
    error = 0.05 * np.sin(np.arange(len(steps)) / 7.0)
    pid = discrete_pid(GAINS, DT, MOTOR.V_supply)
    pid.reset(0.0)
    expected = []
    for dt, e in zip(steps, error):
        pid.coefficients = discretise(GAINS, dt)  # control.c2d at this step size
        expected.append(pid.update(e))
    with open_fmu(controller_fmu) as fmu:
        out = drive_fmu(fmu, {"theta_ref": error}, steps, ["V"])
    np.testing.assert_allclose(out[:, 0], expected, rtol=0, atol=1e-12 * MOTOR.V_supply)


def test_controller_output_before_the_first_step_is_its_output_at_rest(
        controller_fmu: Path) -> None:
    with open_fmu(controller_fmu, {"theta_ref": 0.1, "integral0": 2.0}) as fmu:
        assert fmu.get(["V", "saturated"]) == {"V": pytest.approx(GAINS.Kp * 0.1 + 2.0),
                                               "saturated": False}
    with open_fmu(controller_fmu, {"theta_ref": -1.0}) as fmu:
        assert fmu.get(["V", "saturated"]) == {"V": -MOTOR.V_supply, "saturated": True}


def test_controller_defaults_are_the_harness_design(controller_fmu: Path) -> None:
    """The literal default gains are design_pid for the default motor and the default
    SelfRegulatingBalancer link (J_link + J_rotor N^2, d_link); the limit is the motor's."""
    defaults = ControllerParameters()
    assert (defaults.Kp, defaults.Ki, defaults.Kd, defaults.T_f) == pytest.approx(
        tuple(GAINS), rel=1e-14)
    assert defaults.V_supply == MOTOR.V_supply
    start = {v.name: float(v.start)
             for v in read_model_description(str(controller_fmu)).modelVariables
             if v.causality == "parameter"}
    assert (start["Kp"], start["Ki"], start["Kd"], start["T_f"], start["V_supply"]) == (
        pytest.approx((*GAINS, MOTOR.V_supply), rel=1e-15))


def test_drive_and_controller_fmus_chained_reproduce_the_harness_loop(
        srb_fmu: Path, motor_fmu: Path, controller_fmu: Path) -> None:
    """The harness's loop (harness.engines.fmpy_master): V = PID(theta_ref - theta), drive
    step with V and omega held, mechanism step with its effort, from equilibrium (a 0.5 kg
    payload on the locked balancer, held by the drive). Stepping controller, drive and
    mechanism FMUs in that order (Gauss-Seidel) gives the same trajectory."""
    n, theta0, theta1 = 1500, 2.0, 2.5
    t = np.arange(n) * DT
    s = np.clip(t / 1.0, 0.0, 1.0)  # a 1 s quintic move, then hold
    reference = theta0 + (theta1 - theta0) * s ** 3 * (10.0 - 15.0 * s + 6.0 * s ** 2)
    setup = {"theta0": theta0, "J_drive": MOTOR.J_drive, "payload": 0.5}
    with (open_fmu(srb_fmu, setup, "harness") as link_a,
          open_fmu(srb_fmu, setup, "fmus") as link_b):
        hold = -link_a.get(["tau_gravity"])["tau_gravity"] / MOTOR.torque_per_amp
        assert abs(hold) > 0.1
        pid = discrete_pid(GAINS, DT, MOTOR.V_supply)
        pid.reset(reference[0] - theta0, integral=hold * MOTOR.R_a)
        drive = sampled_motor(MOTOR, DT, current=hold)
        with (open_fmu(controller_fmu, {"integral0": hold * MOTOR.R_a, "theta": theta0,
                                        "theta_ref": reference[0]}) as controller,
              open_fmu(motor_fmu, {"i0": hold}) as motor):
            rows = np.empty((n, 2, 3))  # step, loop, (V, tau_drive, theta)
            state_a = state_b = (theta0, 0.0)
            for k in range(n):
                v = pid.update(reference[k] - state_a[0])
                tau = drive.step(v, state_a[1])[1]
                link_a.set({"tau_drive": tau})
                link_a.step(t[k], DT)
                state_a = tuple(link_a.get(["theta", "omega"]).values())

                controller.set({"theta_ref": reference[k], "theta": state_b[0]})
                controller.step(t[k], DT)
                motor.set({"V": controller.get(["V"])["V"], "omega": state_b[1]})
                motor.step(t[k], DT)
                link_b.set({"tau_drive": motor.get(["tau_drive"])["tau_drive"]})
                link_b.step(t[k], DT)
                state_b = tuple(link_b.get(["theta", "omega"]).values())
                rows[k] = [(v, tau, state_a[0]),
                           (controller.get(["V"])["V"], motor.get(["tau_drive"])["tau_drive"],
                            state_b[0])]
    assert abs(rows[-1, 0, 2] - theta1) < 1e-3  # the loop tracks the move
    for column, scale in enumerate((MOTOR.V_supply, 10.0, math.pi)):
        np.testing.assert_allclose(rows[:, 1, column], rows[:, 0, column], rtol=0,
                                   atol=1e-12 * scale)


# ---- misuse

@pytest.mark.parametrize(("model", "parameters", "message"), [
    ("DcMotorDrive", {"R_a": -1.0}, "R_a = -1.0 Ohm is outside (0.0, inf)"),
    ("DcMotorDrive", {"eta": 1.5}, "eta = 1.5 1 is outside (0.0, 1.0]"),
    ("DcMotorDrive", {"i0": math.nan}, "i0 = nan A is not a finite number in (-inf, inf)"),
    ("PositionController", {"T_f": 0.0}, "T_f = 0.0 s is outside (0.0, inf)"),
    ("PositionController", {"Kp": -1.0}, "Kp = -1.0 V/rad is outside [0.0, inf)"),
], ids=["R_a<0", "eta>1", "i0=nan", "T_f=0", "Kp<0"])
def test_bad_parameter_fails_initialisation_naming_it(model: str, parameters: dict[str, float],
                                                      message: str) -> None:
    assert failed_initialisation(model, parameters) == f"invalid parameter: {message}"


@pytest.mark.parametrize(("model", "inputs", "named"), [
    ("DcMotorDrive", {"V": math.nan}, "input V = nan V is not a finite number in [-inf, inf]"),
    ("DcMotorDrive", {"omega": math.inf},
     "input omega = inf rad/s is not a finite number in [-inf, inf]"),
    ("PositionController", {"theta": math.nan},
     "input theta = nan rad is not a finite number in [-inf, inf]"),
], ids=["V=nan", "omega=inf", "theta=nan"])
def test_bad_input_is_refused_when_set(model: str, inputs: dict[str, float], named: str) -> None:
    """fmi2SetReal refuses a non-finite input naming the input and its range (accepted, it
    would make the next step fail), keeps the previous value, and a step then runs with that
    value (the same outputs as an instance never given the bad value)."""
    with open_fmu(fmu_build.fmu_path(model)) as fmu, \
            open_fmu(fmu_build.fmu_path(model)) as untouched:
        outputs = fmu.names("output")
        assert refused_set(fmu, inputs) == named
        fmu.step(0.0, DT)
        untouched.step(0.0, DT)
        assert fmu.get(outputs) == untouched.get(outputs)
