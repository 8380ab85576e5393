"""The built SelfRegulatingBalancer FMU (fmu_src/mechanisms/self_regulating/README.md) stepped
through FMPy.

Expected numbers come from the paper (Franchetti et al. 2021, Table 1 and eqs. 8, 10, 16),
from closed forms derived here, or from conservation laws; never from the model itself.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import (
    FMI_ERROR,
    errors,
    failed_initialisation,
    open_fmu,
    refusal,
    refused_set,
    refused_step,
    run,
    warnings,
)
from fmpy import read_model_description

from harness import cli, registry
from harness.fmu.loader import CoSimFMU, FMICallException

# Paper, Table 1
M, C, W, A, B0, R_CW, R_WIRE, K, G = 3.0, 0.2, 0.35, 0.1, 0.06, 0.035, 0.01, 981.0, 9.81
J_LINK = 0.16  # our default (fmu_src/mechanisms/self_regulating/README.md): m (2 c)^2 / 3
DEG = math.pi / 180.0
ENERGY = ("E_t", "E_kin", "E_cw")
DT = 1e-3


def total_energy(rows: np.ndarray) -> np.ndarray:
    """E_t + E_kin + E_cw per row of a run over ENERGY [J]."""
    return rows.sum(axis=1)


# ---- energy and convergence: no drive, no friction

@pytest.mark.parametrize("unbalance", [
    {"payload": 1.0}, pytest.param({"k": 0.0}, marks=pytest.mark.slow)],   # k = 0: about 4 s
    ids=["payload_1kg", "k_0"])
def test_unbalanced_swing_conserves_energy_and_converges(srb_fmu: Path,
                                                         unbalance: dict[str, float]) -> None:
    """Slider locked, d_link = 0: E_t + E_kin is constant; 1 ms and 10 ms steps agree.

    Bounds: 1e-6 J and 1e-4 rad. RK4 with rate * h <= 0.05 keeps the energy error near 1e-11 J
    at 1 ms; its global error scales with h^4, so the 10 ms run (3 sub-steps of 3.3 ms)
    differs by ~1e-8 to 1e-6 rad: both bounds hold with two orders of magnitude to spare.
    """
    params = {"theta0": 60 * DEG, "omega0": 1.0, "d_link": 0.0, **unbalance}
    with open_fmu(srb_fmu, params) as fmu:
        e0 = sum(fmu.get(ENERGY).values())
        fine = run(fmu, 35_000, DT, ("theta", *ENERGY))
    with open_fmu(srb_fmu, params) as fmu:
        coarse = run(fmu, 3_500, 10 * DT, ("theta",))
    energy = total_energy(fine[:, 1:])
    kinetic = fine[:, 2]
    assert kinetic.max() - kinetic.min() > 1.0  # a real swing: joules move between E_t and E_kin
    assert np.max(np.abs(energy - e0)) < 1e-6
    assert np.max(np.abs(fine[9::10, 0] - coarse[:, 0])) < 1e-4


@pytest.mark.parametrize("m_slider", [0.0, 0.2])
def test_free_slider_with_pulley_conserves_energy(srb_fmu: Path, m_slider: float) -> None:
    """Slider free, pulley turning, d_slider = d_link = 0: E_t + E_kin + E_cw is constant.

    From theta0 = 180 deg with 1 kg payload the slider oscillates without reaching a stop (an
    inelastic stop would lose energy); m_slider > 0 exercises the Coriolis coupling terms.
    """
    params = {"theta0": math.pi, "omega0": 1.0, "d_link": 0.0, "d_slider": 0.0,
              "m_slider": m_slider, "payload": 1.0, "slider_locked": False,
              "pulley_locked": False}
    with open_fmu(srb_fmu, params) as fmu:
        e0 = sum(fmu.get(ENERGY).values())
        rows = run(fmu, 35_000, DT, ("b", "slider_at_stop", *ENERGY))
    b, at_stop, energy = rows[:, 0], rows[:, 1], total_energy(rows[:, 2:])
    assert not at_stop.any() and B0 / 2 < b.min() and b.max() < W
    assert b.max() - b.min() > 5e-3  # the slider moves ...
    assert np.abs(rows[:, 4]).max() > 0.1  # ... and the counterweight's energy takes part
    assert np.max(np.abs(energy - e0)) < 1e-6


# ---- paper numbers and the regulation procedure

def test_calculated_parameters_match_the_paper(srb_fmu: Path) -> None:
    """M0 = 4.5714 kg (eq. 10, a mass; eq. 14's 44.85 is its weight in N); payload_max (eq. 16)."""
    with open_fmu(srb_fmu) as fmu:
        values = fmu.get(["M0", "payload_max"])
    assert values["M0"] == pytest.approx(4.5714, abs=5e-5)  # paper's 4 decimals
    assert values["M0"] * G == pytest.approx(44.85, abs=5e-3)  # eq. 14 as printed, in N
    assert values["payload_max"] == pytest.approx(8.2857, abs=5e-5)


def quintic(start: float, end: float, t0: float, duration: float
            ) -> Callable[[float], tuple[float, float, float]]:
    """Rest-to-rest reference from start to end [rad] over [t0, t0 + duration]: (q, q', q'')."""
    def reference(t: float) -> tuple[float, float, float]:
        s = min(max((t - t0) / duration, 0.0), 1.0)
        shape = s ** 3 * (10 - 15 * s + 6 * s * s)
        rate = 30 * s * s * (1 - s) ** 2 / duration
        accel = 60 * s * (1 - s) * (1 - 2 * s) / duration ** 2
        return start + (end - start) * shape, (end - start) * rate, (end - start) * accel
    return reference


def hold(angle: float) -> Callable[[float], tuple[float, float, float]]:
    """Reference that keeps the link at angle [rad]."""
    return lambda _t: (angle, 0.0, 0.0)


def regulation(mass: float) -> Callable[[float], dict[str, float | bool]]:
    """Inputs of paper Section 3 against time: unlock the pulley (0.1 s), unlock the slider
    (0.2 s), ramp payload and counterweight_added together 0 -> mass [kg] over 3 s, wait 3 s,
    lock the slider (6.2 s), lock the pulley (6.3 s)."""
    def inputs(t: float) -> dict[str, float | bool]:
        added = mass * min(max((t - 0.2) / 3.0, 0.0), 1.0)
        return {"payload": added, "counterweight_added": added,
                "pulley_locked": not 0.1 <= t < 6.3, "slider_locked": not 0.2 <= t < 6.2}
    return inputs


def drive(fmu: CoSimFMU, t0: float, t1: float,
          reference: Callable[[float], tuple[float, float, float]],
          inputs: Callable[[float], Mapping[str, float | bool]],
          names: tuple[str, ...]) -> np.ndarray:
    """Step from t0 to t1 at DT with the scheduled inputs and a drive torque that tracks
    reference (stiff PD, 20 rad/s, plus the model's own tau_gravity as compensation); row k
    holds [time, *names] after step k. The drive only positions the link: the tests assert
    on the mechanism's outputs, not on the drive."""
    rows = []
    state = fmu.get(["theta", "omega", "tau_gravity", "payload"])
    for k in range(round((t1 - t0) / DT)):
        t = t0 + k * DT
        theta_ref, omega_ref, alpha_ref = reference(t)
        J = J_LINK + state["payload"] * W ** 2
        tau = J * (alpha_ref + 400.0 * (theta_ref - state["theta"])
                   + 40.0 * (omega_ref - state["omega"])) - state["tau_gravity"]
        fmu.set({**inputs(t), "tau_drive": tau})
        fmu.step(t, DT)
        state = fmu.get(["theta", "omega", "tau_gravity", "payload", *names])
        rows.append([t + DT, *(state[n] for n in names)])
    return np.array(rows, dtype=float)


def test_regulation_at_180_deg_balances_the_payload(srb_fmu: Path) -> None:
    """The slider settles at b0 + delta_b = 0.095 m (eq. 8: 35 mm for 1 kg); afterwards the link
    is balanced: moving it 180 -> 340 deg leaves E_t constant and balance_error ~ 0."""
    names = ("b", "E_t", "balance_error", "theta", "delta_b")
    with open_fmu(srb_fmu, {"theta0": math.pi}) as fmu:
        settle = drive(fmu, 0.0, 6.4, hold(math.pi), regulation(1.0), names)
        move = drive(fmu, 6.4, 11.4, quintic(math.pi, 340 * DEG, 6.4, 4.0), regulation(1.0),
                     names)
        assert warnings(fmu) == []  # the proper procedure triggers no misuse warning
    b_locked = settle[-1, 1]
    assert abs(b_locked - 0.095) < 1e-4  # eq. 8 within 0.1 mm
    # Table 1's Delta b for 1 kg; 3 s of near-critical slider damping leave < 1 um of ramp lag
    assert settle[-1, 5] == pytest.approx(0.035, abs=1e-5)
    assert move[-1, 4] == pytest.approx(340 * DEG, abs=1e-3)
    # E_t(theta) = const + balance_error cos(theta): constant within 1 mJ over cos -1 -> 0.94
    # means |balance_error| < 0.5 mN m
    assert np.ptp(move[:, 2]) < 1e-3
    assert np.abs(move[:, 3]).max() < 0.01


def test_unregulated_payload_changes_E_t_by_its_weight(srb_fmu: Path) -> None:
    """Counter-check of the test above: 1 kg added with the slider locked at b0 changes E_t by
    payload g w (cos theta_end - cos theta_start) = 6.66 J over the same move."""
    with open_fmu(srb_fmu, {"theta0": math.pi, "payload": 1.0}) as fmu:
        start = fmu.get(["E_t", "theta"])
        move = drive(fmu, 0.0, 5.0, quintic(math.pi, 340 * DEG, 0.0, 4.0),
                     lambda _t: {}, ("E_t", "theta", "balance_error"))
    expected = 1.0 * G * W * (math.cos(move[-1, 2]) - math.cos(start["theta"]))
    assert expected == pytest.approx(6.66, abs=0.01)
    assert move[-1, 1] - start["E_t"] == pytest.approx(expected, abs=1e-9)
    assert move[-1, 3] == pytest.approx(1.0 * G * W, abs=1e-9)


# ---- misuse: modelled, warned about

def test_slider_released_with_pulley_locked_runs_to_b_min(srb_fmu: Path) -> None:
    """At theta = 180 deg a massless slider obeys d_slider b' = -k (b - a cos theta) = -k (b + a):
    b(t) + a = (b0 + a) exp(-k t / d_slider), reaching b_min = 0 at 0.24 s, then stays."""
    d_slider = 500.0
    with open_fmu(srb_fmu, {"theta0": math.pi}) as fmu:
        fmu.set({"slider_locked": False})  # released at t = 0, after initialisation
        rows = run(fmu, 1000, DT, ("b", "slider_at_stop", "theta"))
        logged = warnings(fmu)
    b, at_stop = rows[:, 0], rows[:, 1]
    t = DT * np.arange(1, 1001)
    free = t < 0.2
    np.testing.assert_allclose(b[free], (B0 + A) * np.exp(-K * t[free] / d_slider) - A,
                               rtol=0, atol=1e-9)  # RK4 at rate * h <= 0.05: ~1e-12 m
    assert b[-1] == 0.0 and at_stop[-1] == 1.0 and not at_stop[:200].any()
    t_stop = d_slider / K * math.log((B0 + A) / A)
    assert t[np.argmax(at_stop > 0)] == pytest.approx(t_stop, abs=2 * DT)
    assert rows[-1, 2] == pytest.approx(math.pi, abs=1e-9)  # the link stays put
    assert any("pulley locked" in m for m in logged)
    assert any("end stop b_min" in m for m in logged)


def test_regulation_at_150_deg_settles_at_the_wrong_position(srb_fmu: Path) -> None:
    """Free slider equilibrium with L0 = 0, m_slider = 0: k (b - a cos theta) = (M0 + dm) g R / r,
    so b = a cos theta + (M0 + dm) g R / (r k) = 0.108 m at 150 deg, not 0.095 m."""
    M0 = K * (A + B0) * R_WIRE / (G * R_CW)  # eq. 10
    names = ("b", "theta", "balance_error", "slider_at_stop")
    with open_fmu(srb_fmu, {"theta0": 150 * DEG}) as fmu:
        rows = drive(fmu, 0.0, 6.4, hold(150 * DEG), regulation(1.0), names)
        logged = warnings(fmu)
    theta = rows[-1, 2]
    assert theta == pytest.approx(150 * DEG, abs=1e-4)
    expected = A * math.cos(theta) + (M0 + 1.0) * G * R_CW / (R_WIRE * K)
    assert abs(expected - 0.095) > 0.01
    # 3 s of near-critical slider damping (time constant 0.27 s) leave < 1 um of the ramp lag
    assert rows[-1, 1] == pytest.approx(expected, abs=1e-5)
    assert abs(rows[-1, 3]) > 1.0  # visibly unbalanced: k a (b - 0.095) = 1.3 N m
    assert not rows[:, 4].any()
    # one warning for the regulation, not one per step of the payload ramp
    assert sum("regulating at theta = 150.00 deg" in m for m in logged) == 1


def test_payload_above_capacity_ends_at_b_max(srb_fmu: Path) -> None:
    """10 kg > payload_max = 8.286 kg (Table 1): b0 + 10 w g / (k a) = 0.41 m is beyond
    b_max = w."""
    names = ("b", "slider_at_stop", "balance_error")
    with open_fmu(srb_fmu, {"theta0": math.pi}) as fmu:
        capacity = fmu.get(["payload_max"])["payload_max"]
        rows = drive(fmu, 0.0, 6.4, hold(math.pi), regulation(10.0), names)
        logged = warnings(fmu)
    assert capacity == pytest.approx(8.286, abs=5e-4)  # Table 1, to its three decimals
    before_lock = rows[round(6.1 / DT)]
    assert before_lock[1] == W and before_lock[2] == 1.0
    # stuck at b_max: still (m c + 10 w) g - k a w = 5.886 + 34.335 - 34.335 N m unbalanced
    assert rows[-1, 3] == pytest.approx((M * C + 10.0 * W) * G - K * A * W, abs=1e-9)
    assert any("exceeds payload_max" in m for m in logged)
    assert any("end stop b_max" in m for m in logged)


# ---- real spring and slider mass: the design rule

def with_counterweight(mass: float, added: float) -> Callable[[float], dict[str, float | bool]]:
    """regulation(mass) with `added` [kg] ramped onto the counterweight instead of mass."""
    def inputs(t: float) -> dict[str, float | bool]:
        values = regulation(mass)(t)
        return {**values, "counterweight_added": added * min(max((t - 0.2) / 3.0, 0.0), 1.0)}
    return inputs


def test_real_spring_design_warns_and_names_the_counterweight(srb_fmu: Path) -> None:
    """L0 = 40 mm, m_slider = 0.4 kg: no slider position balances the link, and the counterweight
    added equal to the payload misses the best one; the FMU says so when the slider is locked,
    with the counterweight that reaches the best position. Regulating with that counterweight
    puts the slider there (it still warns: the best residual is above 1 %)."""
    params = {"theta0": math.pi, "L0": 0.04, "m_slider": 0.4}
    with open_fmu(srb_fmu, params) as fmu:
        drive(fmu, 0.0, 6.4, hold(math.pi), regulation(1.0), ("b",))
        logged = [m for m in warnings(fmu) if "cannot balance" in m]
    assert len(logged) == 1
    named = float(logged[0].split("counterweight_added = ")[1].split(" kg")[0])
    best_b = float(logged[0].split("is at b = ")[1].split(" m")[0])
    with open_fmu(srb_fmu, params) as fmu:
        rows = drive(fmu, 0.0, 6.4, hold(math.pi), with_counterweight(1.0, named), ("b",))
        assert [m for m in warnings(fmu) if "cannot balance" in m]
    assert rows[-1, 1] == pytest.approx(best_b, abs=1e-4)


def test_slider_mass_is_balanced_with_the_named_counterweight(srb_fmu: Path) -> None:
    """Ideal spring, m_slider = 0.4 kg: the link balances where (m c + payload w + m_slider b) g
    = k a b, b = (m c + w) g / (k a - m_slider g) = 98.96 mm for 1 kg. M0 holds the slider at
    b_design (the least mean-square residual over the payload range,
    b = (m c g + P/2 (w g - K s)) / K with K = k a - m_slider g, s = g R / (r k), P =
    (b_max - b0) / s: 68.54 mm), so regulating 1 kg with the same mass on the counterweight
    moves the slider Table 1's 35 mm past b_design, to 103.54 mm, and misses the balance; the
    FMU warns and names counterweight_added = k (b - b_design) r / (g R) = 0.8690 kg, with
    which the slider settles at the balance and nothing is reported."""
    m_s = 0.4
    b_1kg = (M * C + W) * G / (K * A - m_s * G)
    stiffness, travel = K * A - m_s * G, G * R_CW / (R_WIRE * K)
    b_design = (M * C * G + (W - B0) / travel / 2 * (W * G - stiffness * travel)) / stiffness
    added = K * (b_1kg - b_design) * R_WIRE / (G * R_CW)
    with open_fmu(srb_fmu, {"theta0": math.pi, "m_slider": m_s}) as fmu:
        assert fmu.get(["b_design"])["b_design"] == pytest.approx(b_design, abs=1e-9)
        missed = drive(fmu, 0.0, 6.4, hold(math.pi), regulation(1.0), ("b",))
        logged = [m for m in warnings(fmu) if "left the link unbalanced" in m]
    assert missed[-1, 1] == pytest.approx(b_design + 0.035, abs=1e-5)
    assert len(logged) == 1 and f"counterweight_added = {added:.4f} kg" in logged[0]
    assert "cannot balance" not in logged[0]
    with open_fmu(srb_fmu, {"theta0": math.pi, "m_slider": m_s}) as fmu:
        rows = drive(fmu, 0.0, 6.4, hold(math.pi), with_counterweight(1.0, added),
                     ("b", "balance_error"))
        assert warnings(fmu) == []
    assert rows[-1, 1] == pytest.approx(b_1kg, abs=1e-5)
    assert abs(rows[-1, 2]) < 1e-3


# ---- Coulomb friction on the slider

def test_slider_friction_leaves_a_dead_band_off_180_deg(srb_fmu: Path) -> None:
    """mu_slider = 0.1. At 150 deg the spring presses the slider on the link with
    F_n = k a sin(theta) = 49 N, so friction holds it up to 4.9 N: moving outwards under the
    counterweight, it stops where the net pull falls to that, mu a sin(theta) = 5.0 mm short
    of the frictionless position, and never moves back (no chattering). At 180 deg F_n = 0 and
    regulation is as exact as without friction."""
    M0 = K * (A + B0) * R_WIRE / (G * R_CW)
    theta = 150 * DEG
    frictionless = A * math.cos(theta) + (M0 + 1.0) * G * R_CW / (R_WIRE * K)
    with open_fmu(srb_fmu, {"theta0": theta, "mu_slider": 0.1}) as fmu:
        rows = drive(fmu, 0.0, 6.4, hold(theta), regulation(1.0), ("b", "F_n"))
    assert rows[-1, 2] == pytest.approx(K * A * math.sin(theta), rel=1e-3)
    assert frictionless - rows[-1, 1] == pytest.approx(0.1 * A * math.sin(theta), abs=2e-5)
    assert np.diff(rows[:, 1]).min() >= 0.0
    with open_fmu(srb_fmu, {"theta0": math.pi, "mu_slider": 0.1}) as fmu:
        rows = drive(fmu, 0.0, 6.4, hold(math.pi), regulation(1.0), ("b",))
    assert abs(rows[-1, 1] - 0.095) < 1e-4


def test_stuck_slider_does_not_creep(srb_fmu: Path) -> None:
    """At 170 deg with no payload the released slider feels k a (1 + cos theta) = 1.49 N out
    of balance, less than the friction limit mu k a sin(theta) = 1.70 N for mu = 0.1: it
    sticks, exactly, with slider and pulley free for a second. Both forces are read from the
    FMU: the pull is the counterweight's k (a + b0) (eq. 10) less the spring's F_t along the
    link, the limit mu F_n."""
    theta = 170 * DEG
    with open_fmu(srb_fmu, {"theta0": theta, "mu_slider": 0.1}) as fmu:
        rows = drive(fmu, 0.0, 1.0, hold(theta),
                     lambda _t: {"slider_locked": False, "pulley_locked": False},
                     ("b", "F_t", "F_n"))
    np.testing.assert_allclose(K * (A + B0) - rows[:, 2], K * A * (1 + math.cos(theta)),
                               rtol=1e-12)
    np.testing.assert_allclose(0.1 * rows[:, 3], 0.1 * K * A * math.sin(theta), rtol=1e-12)
    assert np.all(rows[:, 1] == B0)


# ---- bad input

@pytest.mark.parametrize(("parameters", "name", "allowed"), [
    ({"k": -1.0}, "k", "[0.0, inf)"),
    ({"a": 0.0}, "a", "(0.0, inf)"),
    ({"a": -0.1}, "a", "(0.0, inf)"),
    ({"r": 0.0}, "r", "(0.0, inf)"),
    ({"R": -0.035}, "R", "(0.0, inf)"),
    ({"m": -1.0}, "m", "[0.0, inf)"),
    ({"b0": 0.36}, "b0", "[b_min, b_max] = [0.0, 0.35]"),
    ({"b0": 0.05, "b_min": 0.055}, "b0", "[b_min, b_max] = [0.055, 0.35]"),
    ({"c": math.nan}, "c", "[0.0, inf)"),
], ids=["k<0", "a=0", "a<0", "r=0", "R<0", "m<0", "b0>b_max", "b0<b_min", "c=nan"])
def test_bad_parameter_fails_initialisation(srb_fmu: Path, parameters: dict[str, float],
                                            name: str, allowed: str) -> None:
    """fmi2ExitInitializationMode fails with fmi2Error and a message naming the variable and
    its allowed range."""
    error = failed_initialisation("SelfRegulatingBalancer", parameters)
    assert f"{name} = " in error and allowed in error


@pytest.mark.parametrize(("step_size", "named"), [
    (0.0, "step size"), (-DT, "step size"), (math.nan, "step size"),
], ids=["dt=0", "dt<0", "dt=nan"])
def test_bad_step_size_discards_the_step(srb_fmu: Path, step_size: float, named: str) -> None:
    """fmi2DoStep returns fmi2Discard with an Error message naming the step size; the state is
    untouched and the instance steps on with a good one."""
    with open_fmu(srb_fmu, {"omega0": 1.0}) as fmu:
        before = fmu.get(["theta", "omega"])
        assert named in refused_step(fmu, 0.0, step_size)
        assert fmu.get(["theta", "omega"]) == before
        fmu.step(0.0, DT)
        assert fmu.get(["theta"])["theta"] == pytest.approx(before["theta"] + DT, abs=1e-5)


@pytest.mark.parametrize(("inputs", "named"), [
    ({"tau_drive": math.nan}, "input tau_drive = nan N.m is not a finite number in [-inf, inf]"),
    ({"payload": math.nan}, "input payload = nan kg is not a finite number in [0.0, inf]"),
    ({"payload": math.inf}, "input payload = inf kg is not a finite number in [0.0, inf]"),
    ({"payload": 1.8e308}, "input payload = inf kg is not a finite number in [0.0, inf]"),
    ({"counterweight_added": -math.inf},
     "input counterweight_added = -inf kg is not a finite number in [-inf, inf]"),
    ({"payload": -1.4}, "input payload = -1.4 kg is outside [0.0, inf]"),
    ({"payload": 1e300}, "input payload = 1e+300 kg is beyond the magnitude limit"),
], ids=["tau_drive=nan", "payload=nan", "payload=inf", "payload=1.8e308",
        "counterweight_added=-inf", "payload=-1.4", "payload=1e300"])
def test_bad_input_is_refused_when_set(srb_fmu: Path, inputs: dict[str, float],
                                       named: str) -> None:
    """fmi2SetReal refuses a non-finite, out-of-range or too large input with fmi2Error naming
    the input and its range (accepted, it would put NaN or inf in tau_gravity, E_p and E_kin,
    or end the instance with fmi2Fatal at the next get): the previous value stays (payload
    0.3), the outputs read as before, and a step runs on with the previous value, to the same
    state as an instance never given the bad value."""
    with open_fmu(srb_fmu, {"omega0": 1.0, "payload": 0.3}) as fmu, \
            open_fmu(srb_fmu, {"omega0": 1.0, "payload": 0.3}) as untouched:
        outputs = fmu.names("output")
        before = fmu.get(outputs)
        assert refused_set(fmu, inputs).startswith(named)
        assert fmu.get(outputs) == before and fmu.get(["payload"]) == {"payload": 0.3}
        fmu.step(0.0, DT)
        untouched.step(0.0, DT)
        assert fmu.get(outputs) == untouched.get(outputs)


def test_bad_initial_input_fails_at_set(srb_fmu: Path) -> None:
    """An input start value set in initialisation is checked the same way: refused when set
    (fmi2Error naming it), the value as it was. The instance is then in the error state, as
    after any fmi2Error (FMI 2.0): initialisation is refused too, and after fmi2Reset a new
    one runs with the default value."""
    fmu = CoSimFMU(srb_fmu)
    try:
        fmu.slave.setupExperiment(startTime=0.0)
        fmu.slave.enterInitializationMode()
        with pytest.raises(FMICallException) as failure:
            fmu.set({"payload": -1.0})
        assert failure.value.status == FMI_ERROR
        assert refusal(errors(fmu)[-1], "fmi2SetReal") == (
            "input payload = -1.0 kg is outside [0.0, inf]")
        assert fmu.get(["payload"]) == {"payload": 0.0}
        with pytest.raises(FMICallException):
            fmu.slave.exitInitializationMode()
        fmu.reset()
        fmu.initialize()
        assert fmu.get(["payload"]) == {"payload": 0.0}
    finally:
        fmu.close()


# ---- model description and state

def test_model_description_declares_experiment_and_bounds(srb_fmu: Path) -> None:
    md = read_model_description(str(srb_fmu))
    experiment = md.defaultExperiment
    assert (float(experiment.startTime), float(experiment.stopTime),
            float(experiment.stepSize)) == (0.0, 35.0, 1e-3)
    variables = {v.name: v for v in md.modelVariables}
    for name in ("m", "k", "a", "R", "r", "b0", "d_slider", "payload"):
        assert float(variables[name].min) == 0.0, name
    units = {"theta": "rad", "tau_drive": "N.m", "k": "N/m", "b": "m", "E_t": "J", "M0": "kg"}
    for name, unit in units.items():
        assert variables[name].declaredType.unit == unit, name
    assert variables["M0"].causality == variables["payload_max"].causality == (
        "calculatedParameter")


def test_state_restore_replays_a_regulation_exactly(srb_fmu: Path) -> None:
    """Hidden state is saved: replays of a 10 kg regulation give bit-identical outputs and the
    same warnings. Saved at 1 s, the slider is moving (its position and speed matter) and the
    replay crosses payload_max and reaches b_max; saved at 3.3 s, it rests on b_max with the
    payload above payload_max (the stop flag and the previous inputs decide which warnings
    repeat). The second state also goes through serialisation to bytes and back."""
    schedule = regulation(10.0)
    windows = ((0.0, 1.0), (1.0, 3.3), (3.3, 4.3))
    with open_fmu(srb_fmu, {"theta0": math.pi}) as fmu:
        outputs = tuple(fmu.names("output"))

        def replay(t0: float, t1: float) -> tuple[np.ndarray, list]:
            logged = len(fmu.messages)
            rows = drive(fmu, t0, t1, hold(math.pi), schedule, outputs)
            return rows, fmu.messages[logged:]

        states, first = [], []
        for t0, t1 in windows:
            states.append(fmu.slave.getFMUstate())
            first.append(replay(t0, t1))
        serialized = fmu.slave.serializeFMUstate(states[2])
        again = []
        for state, (t0, t1) in zip(states[1:], windows[1:]):
            fmu.slave.setFMUstate(state)
            again.append(replay(t0, t1))
        fmu.slave.setFMUstate(fmu.slave.deSerializeFMUstate(serialized))
        again.append(replay(*windows[2]))
        for state in states:
            fmu.slave.freeFMUstate(state)
    b = outputs.index("b") + 1
    assert np.ptp(first[1][0][:, b]) > 0.2 and np.all(first[2][0][:, b] == W)
    logged = " | ".join(m.message for m in first[1][1])
    assert "exceeds payload_max" in logged and "end stop b_max" in logged
    for (rows, messages), (expected_rows, expected_messages) in zip(
            again, (first[1], first[2], first[2])):
        np.testing.assert_array_equal(rows, expected_rows)
        assert messages == expected_messages


def test_bench_writes_the_step_cost_table(tmp_path: Path) -> None:
    """`python -m harness bench` (shortened): the floors (pythonfmu's binary and our runtime)
    and every mechanism timed, each ratio its cost over the floor's, and only the final CSVs
    left in the folder (written atomically): the table and its checks. Whether each mechanism's
    step is dearer than the floor's is a timing figure: the bench checks it
    (harness.bench.targets.fmu_step_checks, tests/test_bench.py) and its exit status says
    whether it held, which here only has to agree with checks.csv."""
    status = cli.main(["bench", "--step-count", "2000", "--repeats", "2", "--only", "fmu_step",
                       "--out", str(tmp_path)])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checks.csv", "fmu_step.csv"]
    table = pd.read_csv(tmp_path / "fmu_step.csv")
    assert list(table["model"]) == ["BenchFloor", "BenchFloorRuntime", *registry.mechanisms()]
    floor = table.set_index("model").us_per_step["BenchFloor"]
    assert floor > 0.0
    np.testing.assert_allclose(table.ratio_to_floor, table.us_per_step / floor, rtol=1e-5)
    checks = pd.read_csv(tmp_path / "checks.csv")
    assert list(checks.figure) == [f"{m} ratio_to_floor" for m in registry.mechanisms()]
    assert status == (0 if checks.passed.all() else 1)
    assert cli.main(["bench", "--step-count", "0", "--out", str(tmp_path)]) == 2
    assert cli.main(["bench", "--only", "fmu_steps", "--out", str(tmp_path)]) == 2
