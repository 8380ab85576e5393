"""The franchetti2021 co-simulation against physics that does not depend on the trajectory,
against the monolithic solve_ivp reference, and against the committed summary; the
active_relocation variants (two drives; the Tr 10x2 screw with friction and its lossless
limit) against the closed-form balance and the spring's energy through the screw."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import (
    assert_reproduces_committed_series,
    assert_reproduces_committed_summary,
    fair_run,
)

from fmu_src.mechanisms.active_spring import physics as active_spring
from fmu_src.mechanisms.self_regulating.physics import Parameters
from harness import scenarios
from harness.drive.motor import MOTORS, MotorParameters
from harness.engines.result import RunResult
from harness.run import results

SCENARIO = scenarios.load("franchetti2021")
VARIANTS = ("self_regulating", "unregulated", "unbalanced")
RELOCATION = "active_relocation"    # the link's drive and the carriage's (joints theta, q)
LOSSLESS = "active_relocation_lossless_screw"   # the same on the screw's lossless limit
TABLE1 = Parameters()
ACTIVE = active_spring.Parameters()
# the default Tr 10x2 (lead 2 mm, pitch diameter 9 mm, mu = 0.1, 15 deg flanks): eta_f = 0.403
LEAD_ANGLE = math.atan(0.002 / (math.pi * 0.009))
TR10X2_ETA_F = math.tan(LEAD_ANGLE) / math.tan(
    LEAD_ANGLE + math.atan(0.1 / math.cos(math.radians(15.0))))
MOTOR = MotorParameters()


@pytest.fixture(scope="module")
def runs() -> dict[str, RunResult]:
    return {v: fair_run(SCENARIO, v)
            for v in (*VARIANTS, RELOCATION, LOSSLESS)}


def friction_loss(run: RunResult, start: float, end: float) -> float:
    """Pivot friction work d_link omega^2 over [start, end] from the 100 Hz series [J]."""
    window = run.series[(run.series.time >= start) & (run.series.time <= end)]
    return TABLE1.d_link * float(np.trapezoid(window.omega ** 2, window.time))


def test_unregulated_phase_v_work_is_the_payload_lift(runs: dict[str, RunResult]) -> None:
    # the spring still balances the link, so the drive lifts only the payload between the
    # phase's end points as the run reached them: payload w g (cos theta(30 s) - cos
    # theta(20 s)), 6.66 J from 180 to 340 deg, plus the pivot friction
    run = runs["unregulated"]
    at = run.series.set_index("time").theta
    lift = 1.0 * TABLE1.w * TABLE1.g * (math.cos(at[30.0]) - math.cos(at[20.0]))
    assert lift == pytest.approx(6.66, abs=0.01)
    expected = lift + friction_loss(run, 20.0, 30.0)
    assert run.phase_work["V move"] == pytest.approx(expected, rel=0.01)


def test_unbalanced_task_work_is_the_potential_energy_change(
        runs: dict[str, RunResult]) -> None:
    # W = (m c + payload w) g cos(theta) at the end minus at the start, less the potential
    # energy the payload brought when it was put on at theta = pi (no drive work), plus friction
    run = runs["unbalanced"]
    g, mc, w = TABLE1.g, TABLE1.m * TABLE1.c, TABLE1.w
    start = mc * g * math.cos(math.radians(60))
    end = (mc + 1.0 * w) * g * math.cos(math.radians(340))
    placed = 1.0 * w * g * math.cos(math.pi)
    expected = end - start - placed + friction_loss(run, 0.0, 35.0)
    assert run.metrics["W_link"] == pytest.approx(expected, rel=0.01)


def test_self_regulation_saves_the_drive_energy(runs: dict[str, RunResult]) -> None:
    drawn = {v: runs[v].metrics["E_drawn"] for v in VARIANTS}
    assert drawn["self_regulating"] < 0.05 * drawn["unregulated"]
    assert drawn["unbalanced"] > drawn["unregulated"]


@pytest.mark.parametrize("variant", VARIANTS)
def test_tracking_without_saturation(runs: dict[str, RunResult], variant: str) -> None:
    m = runs[variant].metrics
    # the design's loop, S(s) = s^2 (s + alpha) / (s + omega_c)^3 with omega_c = 25 rad/s and
    # alpha = 67.3 1/s, leaves 0.019 deg rms on this reference, what the self-regulating link
    # shows; the payload's unbalance (unregulated) and the link's gravity (unbalanced),
    # disturbances to the loop, raise it to 0.024 and 0.033 deg
    assert math.degrees(m["track_err_rms"]) < 0.05
    assert m["V_peak"] < MOTOR.V_supply


@pytest.mark.parametrize("variant, drive", [(v, "") for v in VARIANTS] + [
    (RELOCATION, "_theta"), (RELOCATION, "_q"), (LOSSLESS, "_q")])
def test_energy_balance(runs: dict[str, RunResult], variant: str, drive: str) -> None:
    # per drive: electrical energy in = armature losses + work on the joint + magnetic energy
    # left (eta = 1); the tolerance covers the joint's travel within a step against the held
    # speed the back-EMF sees
    m = runs[variant].metrics
    assert MOTOR.eta == MOTORS["trapezoidal_screw"].eta == 1.0
    assert m[f"E_in{drive}"] == pytest.approx(
        m[f"E_copper{drive}"] + m[f"W_link{drive}"] + m[f"E_inductor{drive}"],
        rel=0.005, abs=1e-4)


def test_regulation_settles_at_the_paper_position(runs: dict[str, RunResult]) -> None:
    # eq. 8: delta b = payload w g / (k a) = 35 mm for 1 kg; locked at t = 20 s
    series = runs["self_regulating"].series
    locked = series[series.time >= 20.0]
    assert locked.delta_b.iloc[0] == pytest.approx(0.035, abs=1e-4)
    assert locked.balance_error.abs().max() < 0.01
    assert np.ptp(locked.E_t) < 1e-3


def balancing_height(payload: float) -> float:
    """Y_B [m] that balances the link with the payload: (m c + payload w) g / (k x1A)."""
    return (ACTIVE.m * ACTIVE.c + payload * ACTIVE.w) * ACTIVE.g / (ACTIVE.k * ACTIVE.x1A)


@pytest.mark.parametrize("variant, lag", [(RELOCATION, 0.03), (LOSSLESS, 0.02)])
def test_active_relocation_reaches_the_closed_form_height(
        runs: dict[str, RunResult], variant: str, lag: float) -> None:
    # 1 kg at w = 0.35 m: Y_B 0.1 -> 0.1583 m, reached at the end of phase III (17 s); the
    # link stays balanced on the way (the payload follows q's quintic) and after it. From
    # 17 s the screw, self-locking, holds the carriage where the regulation left it (within
    # 30 um of the target, 0.05 % of the travel) and its drive rests: no current at all.
    # While the payload ramps, balance_error = k x1A (q_ref - q), the anchor's lag: within
    # 0.02 N m (0.34 mm) of the payload's 3.43 N m on the lossless screw, 0.03 N m (0.51 mm)
    # through the Tr 10x2, which multiplies the load the PI meets by 1 / eta_f = 2.5.
    series = runs[variant].series
    assert balancing_height(0.0) == pytest.approx(ACTIVE.Y_B0, rel=1e-12)
    regulating = series[(series.time >= 14.0) & (series.time <= 17.0)]
    assert regulating.Y_B.iloc[-1] == pytest.approx(balancing_height(1.0), abs=3e-5)
    assert regulating.balance_error.abs().max() < lag
    held = series[series.time >= 17.0]
    assert np.ptp(held.Y_B) < 1e-12      # the screw holds
    assert held.balance_error.abs().max() < 0.01
    assert (held.i_q == 0.0).all()       # and its drive rests


@pytest.mark.parametrize("variant, eta_f", [(RELOCATION, TR10X2_ETA_F), (LOSSLESS, 1.0)])
def test_active_relocation_work_is_the_spring_energy(runs: dict[str, RunResult],
                                                     variant: str, eta_f: float) -> None:
    # at theta = 180 deg the spring runs from A, x1A below O, to B: l_s = Y_B + x1A, so
    # raising B stores 1/2 k ((Y_B' + x1A)^2 - (Y_B + x1A)^2) = 10.83 J; the drive also lifts
    # the carriage (m_q g dY), both through the screw (1 / eta_f times), and pays the
    # carriage's damper, d_q times the integral of q_dot^2: 27.75 J on the Tr 10x2, 11.28 J
    # on the lossless screw
    run = runs[variant]
    series = run.series
    start, end = ACTIVE.Y_B0 + ACTIVE.x1A, balancing_height(1.0) + ACTIVE.x1A
    spring = 0.5 * ACTIVE.k * (end ** 2 - start ** 2)
    assert spring == pytest.approx(10.83, abs=0.005)
    lift = ACTIVE.m_q * ACTIVE.g * (end - start)
    damper = ACTIVE.d_q * float(np.trapezoid(series.q_dot ** 2, series.time))
    work = run.metrics["W_link_q"]
    assert series.W_adjust.iloc[-1] == pytest.approx(work, rel=1e-9)
    assert work == pytest.approx((spring + lift) / eta_f + damper, rel=0.005)
    assert ACTIVE.eta_forward == pytest.approx(TR10X2_ETA_F, rel=1e-12)


def test_active_relocation_draws_for_both_drives(runs: dict[str, RunResult]) -> None:
    table = results.summary(runs.values(), SCENARIO.baselines).set_index("variant")
    active = table.loc[RELOCATION]
    assert active.E_drawn == pytest.approx(active.E_drawn_theta + active.E_drawn_q, rel=1e-12)
    assert active.W_adjust == pytest.approx(active.W_link_q, rel=1e-12)
    for variant in VARIANTS:    # one drive: its metrics are also the link's columns
        assert table.loc[variant, "E_drawn_theta"] == table.loc[variant, "E_drawn"]
        assert np.isnan(table.loc[variant, "W_adjust"])
    # both keep the link balanced throughout, so the link's drives draw alike; the carriage's
    # drive pays the spring energy (and its copper losses), which self-regulation takes from
    # the counterweight
    assert active.E_drawn_theta == pytest.approx(table.loc["self_regulating", "E_drawn"],
                                                 rel=0.05)
    assert active.E_drawn_q > active.W_adjust > 10.83


@pytest.fixture(scope="module")
def monolithic() -> dict[str, RunResult]:
    return {v: fair_run(SCENARIO, v, engine="reference") for v in VARIANTS}


# about 9 s: the monolithic reference of every variant (demian2022's runs in make test)
@pytest.mark.slow
@pytest.mark.parametrize("variant", VARIANTS)
def test_cosimulation_matches_monolithic_reference(
        runs: dict[str, RunResult], monolithic: dict[str, RunResult],
        variant: str) -> None:
    for name in ("E_in", "E_drawn", "E_copper", "E_mech"):
        ref = monolithic[variant].metrics[name]
        # 0.5 % of the metric, or 0.5 % of this variant's drawn energy when the metric is
        # a small difference (the self-regulating link's net E_in is near zero)
        tolerance = 0.005 * max(abs(ref), runs[variant].metrics["E_drawn"])
        assert runs[variant].metrics[name] == pytest.approx(ref, abs=tolerance), name


@pytest.mark.slow   # with the monolithic reference, and a run at 4 ms
def test_cosimulation_error_shrinks_with_the_step(
        runs: dict[str, RunResult], monolithic: dict[str, RunResult]
) -> None:
    variant = "unbalanced"
    coarse = fair_run(SCENARIO, variant, step_size=4e-3)
    ref = monolithic[variant].metrics["E_copper"]
    error_fine = abs(runs[variant].metrics["E_copper"] - ref)
    error_coarse = abs(coarse.metrics["E_copper"] - ref)
    assert error_fine < error_coarse


def test_rerun_reproduces_committed_summary(runs: dict[str, RunResult]) -> None:
    assert_reproduces_committed_summary(SCENARIO, runs.values())


@pytest.mark.parametrize("variant", VARIANTS)
def test_rerun_reproduces_committed_series(runs: dict[str, RunResult],
                                           variant: str) -> None:
    assert_reproduces_committed_series(SCENARIO, runs[variant],
                                       ["theta", "b", "E_t", "tau_drive", "i", "E_drawn"])
