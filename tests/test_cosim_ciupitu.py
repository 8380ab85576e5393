"""Ciupitu's counterweight in co-simulation: the ciupitu2018 rocking cycle against the energy
of the FMU's Lagrangian model in closed form, and the ciupitu variant of franchetti2021 (its
design, its drive energy, the monolithic reference).

Expected values are computed here from the paper's data and the quintic reference, not with
fmu_src.ciupitu or the harness's scenario functions.
"""

from __future__ import annotations

import math

import pytest
from conftest import assert_reproduces_committed_series, assert_reproduces_committed_summary
from scipy.integrate import quad

from harness import ciupitu_design, master, reference, results, scenarios
from harness.drive import MotorParameters

MOTOR = MotorParameters()
G = 9.81
CYCLE = scenarios.load("ciupitu2018")
CYCLE_VARIANTS = ("parabolic_balanced", "parabolic_unbalanced", "linear_balanced",
                  "linear_unbalanced")
STROKES = {"down": 1.0, "up": -1.0}     # phase -> direction of the arm (theta 0 -> pi: down)
# the paper's data (Ciupitu 2018, Section 4)
G_MAX, OP, G2, OA, AB = 4.0, 2.0, 3.0, 1.0, 2.0
FRANCHETTI = scenarios.load("franchetti2021")


def test_cycle_holds_the_paper_data() -> None:
    p = CYCLE.parameters
    for variant in ("parabolic_balanced", "linear_balanced"):
        bar = CYCLE.variant(variant).parameters
        assert (p["w"], p["m2"] * G, bar["OA"], bar["AB"]) == pytest.approx((OP, G2, OA, AB))
    assert p["m"] * p["c"] == pytest.approx(p["m_fixed_cw"] * p["c_fixed_cw"])  # arm balanced
    down = next(phase for phase in CYCLE.phases if phase.name == "down")
    assert down.inputs["payload"].target * G == pytest.approx(G_MAX)


@pytest.fixture(scope="module")
def cycle() -> dict[str, master.RunResult]:
    return {v: master.run(CYCLE, CYCLE.variant(v)) for v in CYCLE_VARIANTS}


def stroke_work(variant: str, direction: float) -> float:
    """Drive work over one stroke of the FMU's Lagrangian model along the reference [J].

    With sigma = theta/pi the payload is G_MAX/g times sigma (2 - sigma) (parabolic) or sigma
    (linear) on both strokes, and theta = pi q(t/T) down, pi (1 - q) up, with the quintic q.
    - gravity: the payload's net work, Gmax OP (1 + 4/pi^2) or Gmax OP, and the rise of the
      counterweight B by 2 AB (eq. 13 at phi = +-pi/2): W = direction (2 AB G2 - E_u);
    - pivot friction d integral omega^2 dt = d pi^2 (10/7) / T;
    - the payload's mass joins from rest on the way down (the arm's angular momentum is
      conserved, the kinetic energy this costs is lost) and leaves with its own speed on the
      way up (taking its kinetic energy): either way the drive supplies 1/2 OP^2 integral
      |dpayload/dt| omega^2 dt = 1/2 OP^2 pi^2/T^2 integral of |payload'(q)| q'^3 dtau more.
    """
    law, counterweight = variant.split("_")
    T = next(phase.duration for phase in CYCLE.phases if phase.name == "down")
    E_u = G_MAX * OP * ((1.0 + 4.0 / math.pi ** 2) if law == "parabolic" else 1.0)
    gravity = direction * ((2.0 * AB * G2 if counterweight == "balanced" else 0.0) - E_u)
    friction = CYCLE.parameters["d_link"] * math.pi ** 2 * (10.0 / 7.0) / T

    def rate(tau: float) -> float:                 # q'(tau) of q = 10 tau^3 - 15 tau^4 + 6 tau^5
        return 30.0 * tau ** 2 * (1.0 - tau) ** 2

    def slope(sigma: float) -> float:              # d payload / d sigma [kg]
        return G_MAX / G * (2.0 * (1.0 - sigma) if law == "parabolic" else 1.0)

    def q(tau: float) -> float:
        return tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau ** 2)

    mass_change = quad(lambda tau: slope(q(tau)) * rate(tau) ** 3, 0.0, 1.0)[0]
    return gravity + friction + 0.5 * OP ** 2 * math.pi ** 2 / T ** 2 * mass_change


@pytest.mark.parametrize("variant", CYCLE_VARIANTS)
def test_stroke_work_is_the_lagrangian_energy(cycle: dict[str, master.RunResult],
                                              variant: str) -> None:
    for stroke, direction in STROKES.items():
        expected = stroke_work(variant, direction)
        assert cycle[variant].phase_work[stroke] == pytest.approx(expected, abs=2e-3), stroke


def static_eps(law: str) -> float:
    """eps = 1 - |2 AB G2 - E_u| / E_u of one stroke: the static model with the bar's
    moment M_bar (the paper's M_b alone gives 0.973446 and 0.632031)."""
    E_u = G_MAX * OP * ((1.0 + 4.0 / math.pi ** 2) if law == "parabolic" else 1.0)
    return 1.0 - abs(2.0 * AB * G2 - E_u) / E_u


@pytest.mark.parametrize("law, value", [("parabolic", 0.9326007), ("linear", 0.5)])
def test_eps_on_work_approaches_the_static_value(cycle: dict[str, master.RunResult], law: str,
                                                 value: float) -> None:
    assert static_eps(law) == pytest.approx(value, abs=1e-7)
    table = results.summary(cycle.values(), CYCLE.baselines).set_index("variant")
    balanced, unbalanced = f"{law}_balanced", f"{law}_unbalanced"
    # W_phases sums |stroke work|: friction and the payload's mass change (the same kinetic
    # energy on both strokes) cancel between the strokes, leaving the static value
    expected = 1.0 - (sum(abs(stroke_work(balanced, d)) for d in STROKES.values())
                      / sum(abs(stroke_work(unbalanced, d)) for d in STROKES.values()))
    assert table.eps_W[balanced] == pytest.approx(expected, abs=1e-3)
    assert table.eps_W[balanced] == pytest.approx(static_eps(law), abs=0.01)
    # eps on E_drawn is against the same law's unbalanced run
    drawn = table.E_drawn
    assert table.eps[balanced] == pytest.approx(1.0 - drawn[balanced] / drawn[unbalanced])
    assert table.eps[unbalanced] == 0.0


@pytest.mark.parametrize("variant", CYCLE_VARIANTS)
def test_cycle_tracking_without_saturation(cycle: dict[str, master.RunResult],
                                           variant: str) -> None:
    m = cycle[variant].metrics
    assert math.degrees(m["track_err_rms"]) < 0.5
    assert m["V_peak"] < MOTOR.V_supply


def assert_matches_reference(run: master.RunResult, ref: reference.ReferenceResult) -> None:
    """Energy metrics within 0.5 % (of the metric, or of E_drawn for a small difference)."""
    for name in ("E_in", "E_drawn", "E_copper", "E_mech"):
        tolerance = 0.005 * max(abs(ref.metrics[name]), run.metrics["E_drawn"])
        assert run.metrics[name] == pytest.approx(ref.metrics[name], abs=tolerance), name


def test_cycle_matches_monolithic_reference(cycle: dict[str, master.RunResult]) -> None:
    variant = "parabolic_balanced"
    assert_matches_reference(cycle[variant], reference.simulate(CYCLE, CYCLE.variant(variant)))


# ---- the ciupitu variant of franchetti2021 -----------------------------------------------
@pytest.fixture(scope="module")
def objective() -> ciupitu_design.TaskEnergy:
    return ciupitu_design.task_energy()


@pytest.fixture(scope="module")
def chosen(objective: ciupitu_design.TaskEnergy) -> ciupitu_design.Design:
    return ciupitu_design.design(objective)


def test_scenario_holds_the_design(chosen: ciupitu_design.Design) -> None:
    p = FRANCHETTI.variant("ciupitu").parameters
    assert p["m2"] == pytest.approx(chosen.m2, rel=1e-4)
    assert p["OA"] == pytest.approx(chosen.OA, abs=1e-5)
    assert p["AB"] == chosen.AB == 0.35


def test_design_is_a_local_optimum(chosen: ciupitu_design.Design,
                                   objective: ciupitu_design.TaskEnergy) -> None:
    design = {"m2": chosen.m2, "OA": chosen.OA, "AB": chosen.AB}
    best = objective(**design)
    assert best == pytest.approx(chosen.E_drawn, rel=1e-9)
    for name, value in design.items():
        # +-5 %; OA sits on its bound 0, so it moves to 5 % of AB (the feasible side)
        for moved in ((0.05 * chosen.AB,) if value == 0.0 else (0.95 * value, 1.05 * value)):
            assert objective(**(design | {name: moved})) > best, (name, moved)


@pytest.fixture(scope="module")
def franchetti() -> dict[str, master.RunResult]:
    return {v: master.run(FRANCHETTI, FRANCHETTI.variant(v)) for v in ("ciupitu", "unbalanced")}


def test_ciupitu_saves_drive_energy(franchetti: dict[str, master.RunResult],
                                    chosen: ciupitu_design.Design) -> None:
    m = franchetti["ciupitu"].metrics
    assert m["E_drawn"] < 0.2 * franchetti["unbalanced"].metrics["E_drawn"]
    # the design's prediction (perfect tracking, no inductance) is what the drive draws
    assert m["E_drawn"] == pytest.approx(chosen.E_drawn, rel=0.005)
    assert math.degrees(m["track_err_rms"]) < 0.5
    assert m["V_peak"] < MOTOR.V_supply


def test_franchetti_ciupitu_matches_monolithic_reference(
        franchetti: dict[str, master.RunResult]) -> None:
    assert_matches_reference(franchetti["ciupitu"],
                             reference.simulate(FRANCHETTI, FRANCHETTI.variant("ciupitu")))


def test_rerun_reproduces_committed_results(cycle: dict[str, master.RunResult],
                                            franchetti: dict[str, master.RunResult]) -> None:
    assert_reproduces_committed_summary(CYCLE, cycle.values())
    for run in cycle.values():
        assert_reproduces_committed_series(CYCLE, run, ["theta", "payload", "tau_drive", "E_drawn"])
    assert_reproduces_committed_summary(FRANCHETTI, franchetti.values())
    assert_reproduces_committed_series(FRANCHETTI, franchetti["ciupitu"],
                                       ["theta", "OB", "tau_drive", "E_drawn"])
