"""PrismaticCompensator FMU (fmu_src/mechanisms/prismatic/README.md), exercised through FMPy.

Static efforts are checked against eqs. 3.1 and 3.3 and the residuals
fmu_src/mechanisms/prismatic/README.md states, computed here independently of
`fmu_src.mechanisms.prismatic.physics`. Energy: E_grav + E_springs + E_kin
- W_drive - W_worm + E_loss - E_added must stay constant.

With the drives off the arm leaves the paper's workspace (below the horizontal the k1 wire is
slack and the balanced revolute joint is neutral) and the slider runs into its end stops:
these runs check the energy bookkeeping, not the workspace.
The runs with constant drive efforts stay within q1 in [0, 0.7] rad and q2 in [0, 0.3] m.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping

import pytest
from conftest import failed_initialisation, ledger_residual

from fmu_src.mechanisms.prismatic import physics as prismatic
from harness.fmu.build import fmu_path
from harness.fmu.loader import CoSimFMU

G = 9.81
LC1, LS0, M1, M2 = 0.5, 0.25, 1.0, 0.5
A, B, C, D, R = 0.4, 0.125, 0.4, 0.5, 0.15
RHO = B / LS0
Q1_GRID = [0.1 * i for i in range(8)]      # 0 .. 0.7 rad
Q2_GRID = [0.05 * j for j in range(7)]     # 0 .. 0.3 m
ENERGY_TERMS = ("E_grav", "E_springs", "E_kin", "W_drive", "W_worm", "E_friction", "E_loss",
                "E_added")
MODES = {
    "uncompensated": {"compensated": False},
    "self_locking": {"compensated": True, "self_locking": True},
    "back_drivable": {"compensated": True, "self_locking": False},
}


@pytest.fixture(scope="module")
def fmu() -> Iterator[CoSimFMU]:
    with CoSimFMU(fmu_path("PrismaticCompensator")) as instance:
        yield instance


def start(fmu: CoSimFMU, parameters: Mapping[str, float | bool]) -> None:
    """Reset the instance to its defaults and initialise it with the given parameters."""
    fmu.reset()
    fmu.initialize(parameters)


def static_efforts(fmu: CoSimFMU, mode: str, q1: float, q2: float) -> tuple[float, float]:
    start(fmu, {**MODES[mode], "q1_0": q1, "q2_0": q2})
    out = fmu.get(["tau1_gravity_residual", "f2_gravity_residual"])
    return out["tau1_gravity_residual"], out["f2_gravity_residual"]


def simulate(fmu: CoSimFMU, parameters: Mapping[str, float | bool],
             inputs: Mapping[str, float], stop: float = 10.0, dt: float = 1e-3
             ) -> tuple[float, dict[str, tuple[float, float]], dict[str, float]]:
    """Largest energy-balance drift [J], ranges of q1 and q2, and the final outputs."""
    start(fmu, parameters)
    fmu.set(inputs)
    names = [*ENERGY_TERMS, "q1", "q2"]
    out = fmu.get(names)
    reference, drift = ledger_residual("PrismaticCompensator", out), 0.0
    ranges = {q: (out[q], out[q]) for q in ("q1", "q2")}
    for n in range(round(stop / dt)):
        fmu.step(n * dt, dt)
        out = fmu.get(names)
        drift = max(drift, abs(ledger_residual("PrismaticCompensator", out) - reference))
        ranges = {q: (min(lo, out[q]), max(hi, out[q])) for q, (lo, hi) in ranges.items()}
    return drift, ranges, out


def test_design_values_and_table1(fmu: CoSimFMU) -> None:
    start(fmu, {})
    used = fmu.get(["k1_used", "k2_used", "k3_used", "rho_used", "J1"])
    assert used["k1_used"] == pytest.approx(M2 * G / (2 * R), rel=1e-14)          # eq. 3.6
    assert used["k2_used"] == pytest.approx(LC1 * M1 * G / (C * D), rel=1e-14)    # eq. 3.13
    assert used["k3_used"] == pytest.approx(M2 * G * LS0 / (A * B), rel=1e-14)    # eq. 3.15
    assert used["rho_used"] == pytest.approx(RHO, rel=1e-14)                      # eq. 3.17
    assert used["J1"] == pytest.approx(M1 / 12 + M1 * LC1 ** 2, rel=1e-14)
    start(fmu, {"design_springs": False})
    used = fmu.get(["k1_used", "k2_used", "k3_used", "rho_used"])
    assert used == {"k1_used": 16.33, "k2_used": 24.5, "k3_used": 24.5, "rho_used": 0.5}


def test_uncompensated_efforts_are_eqs_3_1_and_3_3(fmu: CoSimFMU) -> None:
    for q1 in Q1_GRID:
        for q2 in Q2_GRID:
            tau1, f2 = static_efforts(fmu, "uncompensated", q1, q2)
            assert tau1 == pytest.approx((LC1 * M1 + (LS0 + q2) * M2) * G * math.cos(q1),
                                         abs=1e-9)
            assert f2 == pytest.approx(M2 * G * math.sin(q1), abs=1e-9)


def test_self_locking_residuals(fmu: CoSimFMU) -> None:
    """Only the k1 reaction on q1 remains, 1/2 m2 g r sin q1 cos q1; q2 is balanced."""
    for q1 in Q1_GRID:
        for q2 in Q2_GRID:
            tau1, f2 = static_efforts(fmu, "self_locking", q1, q2)
            assert tau1 == pytest.approx(0.5 * M2 * G * R * math.sin(q1) * math.cos(q1),
                                         abs=1e-9)
            assert f2 == pytest.approx(0.0, abs=1e-9)


def test_back_drivable_residuals(fmu: CoSimFMU) -> None:
    """Spring k3 also loads q2: residual m2 g ((b + q*)/a - sin q1)."""
    for q1 in Q1_GRID:
        for q2 in Q2_GRID:
            tau1, f2 = static_efforts(fmu, "back_drivable", q1, q2)
            assert tau1 == pytest.approx(0.5 * M2 * G * R * math.sin(q1) * math.cos(q1),
                                         abs=1e-9)
            assert f2 == pytest.approx(M2 * G * ((B + RHO * q2) / A - math.sin(q1)), abs=1e-9)


@pytest.mark.parametrize("mode, initial", [
    ("uncompensated", {"q1_0": 0.5, "q2_0": 0.1}),
    ("self_locking", {"q1_0": 0.6, "q2_0": 0.1, "q2_dot_0": 0.05}),
    ("back_drivable", {"q1_0": 0.6, "q2_0": 0.1}),
])
def test_energy_balance_drives_off(fmu: CoSimFMU, mode: str,
                                   initial: dict[str, float]) -> None:
    drift, ranges, out = simulate(fmu, {**MODES[mode], **initial, "d1": 0.0, "d2": 0.0},
                                  {"tau1": 0.0, "f2": 0.0})
    assert drift < 1e-6
    assert out["W_drive"] == 0.0 and out["E_friction"] == 0.0
    assert ranges["q1"][1] - ranges["q1"][0] > 0.5 and ranges["q2"][1] - ranges["q2"][0] > 0.3
    if mode == "uncompensated":
        assert out["W_worm"] == 0.0 and out["E_springs"] == 0.0
    assert out["E_added"] == 0.0


def test_slider_falls_onto_its_end_stop(fmu: CoSimFMU) -> None:
    """Uncompensated arm held vertical (q1 = pi/2: gravity has no moment about O), drives off:
    m2 falls along the link with acceleration g from q2 = 0.3 m onto q2_min = -ls0 and stays
    there. The inelastic stop dissipates its kinetic energy, m2 g (0.3 m + ls0) = 2.698 J,
    and q1 does not move (the stop's impulse acts along the link). It lands at
    sqrt(2 (0.3 m + ls0) / g) = 0.3349 s: at 0.334 s it is still falling freely."""
    parameters = {**MODES["uncompensated"], "q1_0": math.pi / 2, "q2_0": 0.3}
    _, _, falling = simulate(fmu, parameters, {"tau1": 0.0, "f2": 0.0}, stop=0.334)
    # q2 = 0.3 m - g t^2 / 2, which RK4 integrates exactly (to rounding): 2.8 mm above the stop
    assert falling["q2"] == pytest.approx(0.3 - 0.5 * G * 0.334 ** 2, abs=1e-9)
    drift, ranges, out = simulate(fmu, parameters, {"tau1": 0.0, "f2": 0.0}, stop=1.0)
    fall = 0.3 + LS0
    assert ranges["q2"] == (-LS0, 0.3) and out["q2"] == -LS0
    assert out["E_loss"] == pytest.approx(M2 * G * fall, rel=1e-9)
    assert out["E_friction"] == 0.0
    assert out["q1"] == pytest.approx(math.pi / 2, abs=1e-12)
    assert drift < 1e-9


def test_stroke_limits_are_checked() -> None:
    """q2_0 outside [q2_min, q2_max] is refused at initialisation, naming the variables."""
    with pytest.raises(ValueError, match=r"q2_0 = 0.8 m is outside \[q2_min, q2_max\]"):
        prismatic.validate(prismatic.Parameters(q2_0=0.8))
    with pytest.raises(ValueError, match="q2_min = 0.5 m must be below q2_max = 0.4 m"):
        prismatic.validate(prismatic.Parameters(q2_min=0.5, q2_max=0.4))


@pytest.mark.parametrize("mode, initial, inputs", [
    ("self_locking", {"q1_0": 0.1, "q2_0": 0.1}, {"tau1": 0.1, "f2": -0.001}),
    ("back_drivable", {"q1_0": 0.2, "q2_0": 0.14}, {"tau1": 0.1, "f2": 1.0}),
])
@pytest.mark.parametrize("friction", [{"d1": 0.0, "d2": 0.0}, {"d1": 0.05, "d2": 0.5}])
@pytest.mark.parametrize("rotors", [{}, {"J_drive1": 0.04, "m_drive2": 0.08}])
def test_energy_balance_with_drives(fmu: CoSimFMU, mode: str, initial: dict[str, float],
                                    inputs: dict[str, float], friction: dict[str, float],
                                    rotors: dict[str, float]) -> None:
    """Constant drive efforts keep the arm in the workspace; W_drive and W_worm both count,
    and the drives' rotors' kinetic energy is part of E_kin."""
    drift, ranges, out = simulate(fmu, {**MODES[mode], **initial, **friction, **rotors},
                                  inputs)
    assert drift < 1e-6
    assert 0.0 <= ranges["q1"][0] and ranges["q1"][1] <= 0.7
    assert 0.0 <= ranges["q2"][0] and ranges["q2"][1] <= 0.3
    assert abs(out["W_drive"]) > 1e-3 and abs(out["W_worm"]) > 1e-2
    assert (out["E_friction"] > 1e-3) == (friction["d1"] > 0.0)


@pytest.mark.parametrize("rotors", [{"J_drive1": 0.0, "m_drive2": 0.0},
                                    {"J_drive1": 0.05, "m_drive2": 0.2}])
def test_drive_inertias_add_to_the_joint_inertias(fmu: CoSimFMU,
                                                  rotors: dict[str, float]) -> None:
    """From rest at q1 = q2 = 0, where the self-locking compensator leaves no residual, the
    efforts accelerate the joints by tau1 / (J1 + J_drive1 + m2 ls0^2) and
    f2 / (m2 + m_drive2); E_kin holds the rotors' energy."""
    start(fmu, {**MODES["self_locking"], **rotors})
    tau1, f2, t = 0.1, 0.1, 0.01
    fmu.set({"tau1": tau1, "f2": f2})
    for n in range(10):
        fmu.step(n * 1e-3, 1e-3)
    out = fmu.get(["q1", "q2", "q1_dot", "q2_dot", "E_kin"])
    inertia_1 = M1 / 12 + M1 * LC1 ** 2 + rotors["J_drive1"] + M2 * LS0 ** 2
    mass_2 = M2 + rotors["m_drive2"]
    # over 10 ms the arm moves 1e-5 rad: the residual efforts it meets are 1e-5 of the inputs
    assert out["q1"] == pytest.approx(0.5 * tau1 / inertia_1 * t ** 2, rel=1e-3)
    assert out["q2"] == pytest.approx(0.5 * f2 / mass_2 * t ** 2, rel=1e-3)
    lc2 = LS0 + out["q2"]
    expected = (0.5 * (M1 / 12 + M1 * LC1 ** 2 + rotors["J_drive1"] + M2 * lc2 ** 2)
                * out["q1_dot"] ** 2 + 0.5 * mass_2 * out["q2_dot"] ** 2)
    assert out["E_kin"] == pytest.approx(expected, rel=1e-12)


def test_state_get_set_restores_parameters_and_motion(fmu: CoSimFMU) -> None:
    start(fmu, {"self_locking": False, "q1_0": 0.3, "q2_0": 0.1})
    fmu.set({"tau1": 0.1, "f2": 0.5})
    for n in range(100):
        fmu.step(n * 1e-3, 1e-3)
    saved = fmu.slave.getFMUstate()
    names = ["q1", "q2", "W_worm", "f2_gravity_residual"]

    def run() -> dict[str, float]:
        for n in range(100, 200):
            fmu.step(n * 1e-3, 1e-3)
        return fmu.get(names)

    first = run()
    fmu.slave.setFMUstate(saved)
    assert run() == first
    fmu.slave.freeFMUstate(saved)


def test_invalid_parameter_is_reported() -> None:
    """A parameter out of range fails initialisation with fmi2Error and a message naming it
    and its range."""
    message = failed_initialisation("PrismaticCompensator", {"m2": 0.0})
    assert "m2 = 0.0 kg is outside (0.0, inf)" in message


def real_spring_potential(q1: float, q2: float, free_length: float) -> float:
    """V = E_grav + E_springs with springs k2 and k3 of this free length, from the anchor
    coordinates (C = (0, c), D = d u, A = (0, a), B = e u), independently of the module."""
    k1, k2, k3 = M2 * G / (2 * R), LC1 * M1 * G / (C * D), M2 * G * LS0 / (A * B)
    u = (math.cos(q1), math.sin(q1))
    e = B + RHO * q2
    l2 = math.hypot(D * u[0], D * u[1] - C)
    l3 = math.hypot(e * u[0], e * u[1] - A)
    return ((M1 * LC1 + M2 * (LS0 + q2)) * G * u[1] + 0.5 * k1 * (R * max(u[1], 0.0)) ** 2
            + 0.5 * k2 * (l2 - free_length) ** 2 + 0.5 * k3 * (l3 - free_length) ** 2)


@pytest.mark.parametrize("q1, q2", [(0.1, 0.0), (0.35, 0.15), (0.7, 0.3)])
def test_real_springs_load_the_joints_with_their_energy_gradient(fmu: CoSimFMU, q1: float,
                                                                 q2: float) -> None:
    """With a free length L0 the springs' energy is 1/2 k (l - L0)^2: the residuals are its
    gradient (back-drivable: k3 loads q2 too, less the k1 wire's 2T), and the arm the design
    equations balance exactly with ideal springs is left unbalanced on q1."""
    free_length, h = 0.02, 1e-6
    start(fmu, {**MODES["back_drivable"], "L0": free_length, "q1_0": q1, "q2_0": q2})
    out = fmu.get(["tau1_gravity_residual", "f2_gravity_residual", "T_wire", "E_springs"])
    dV_dq1 = (real_spring_potential(q1 + h, q2, free_length)
              - real_spring_potential(q1 - h, q2, free_length)) / (2 * h)
    dV_dq2 = (real_spring_potential(q1, q2 + h, free_length)
              - real_spring_potential(q1, q2 - h, free_length)) / (2 * h)
    assert out["tau1_gravity_residual"] == pytest.approx(dV_dq1, abs=1e-7)
    assert out["f2_gravity_residual"] == pytest.approx(dV_dq2 - 2 * out["T_wire"], abs=1e-7)
    ideal_residual = static_efforts(fmu, "back_drivable", q1, q2)[0]
    assert abs(dV_dq1 - ideal_residual) > 1e-3  # the free length costs balance


def test_energy_balance_with_real_springs(fmu: CoSimFMU) -> None:
    drift, ranges, out = simulate(fmu, {**MODES["back_drivable"], "L0": 0.02, "q1_0": 0.2,
                                        "q2_0": 0.14, "d1": 0.05, "d2": 0.5},
                                  {"tau1": 0.1, "f2": 1.0})
    assert drift < 1e-6
    assert out["E_friction"] > 1e-3 and ranges["q1"][1] - ranges["q1"][0] > 0.05
