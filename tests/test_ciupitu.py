"""Ciupitu 2018 passive translational counterweight: static example command and FMU.

Reference values here are computed independently of fmu_src.mechanisms.ciupitu.physics:
closed-form stroke energies, the counterweight position from the bar/arm intersection (a
quadratic in OB), and derivatives of energies by complex-step differentiation. """

from __future__ import annotations

import cmath
import json
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fmpy.validation import validate_fmu
from scipy.integrate import quad

from fmu_src.mechanisms.ciupitu import example as paper_example
from fmu_src.mechanisms.ciupitu import physics as ciupitu
from harness import cli
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU, FMICallException

ROOT = Path(__file__).resolve().parent.parent
G = 9.81


def example(*options: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "harness", "ciupitu-example", *options],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)


def example_json(*options: str) -> dict[str, float]:
    done = example("--json", *options)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


# ---- static example through the command ------------------------------------------------
def test_paper_numbers() -> None:
    r = example_json()
    assert round(r["eps_parabolic"], 6) == 0.973446
    assert round(r["eps_linear"], 6) == 0.632031
    assert round(r["max_abs_Mu_parabolic"], 3) == 0.828
    assert abs(r["phi_max_Mu_parabolic"]) < 0.15            # near the horizontal
    assert round(r["max_abs_Mu_linear"], 1) == 1.4
    assert abs(r["phi_max_Mu_linear"] + 0.5) < 0.05


def closed_form_eps(Gmax: float, OP: float, G2: float, OA: float, AB: float) -> dict[str, float]:
    """Net-work eps over the stroke, in closed form.

    With x = pi/2 - phi: integral of G_pv OP cos(phi) is Gmax OP (1 + 4/pi^2) (parabolic) and
    Gmax OP (linear); integral of OB cos(phi), with u = sin(phi) and a^2 = AB^2 - OA^2, is
    AB + a^2/OA asinh(OA/a).
    """
    a2 = AB * AB - OA * OA
    E_cw = G2 * (AB + a2 / OA * math.asinh(OA / math.sqrt(a2)))
    E_u = {"parabolic": Gmax * OP * (1.0 + 4.0 / math.pi ** 2), "linear": Gmax * OP}
    return {law: 1.0 - abs(E_cw - e) / e for law, e in E_u.items()}


def test_closed_form_matches_paper_data() -> None:
    eps = closed_form_eps(4.0, 2.0, 3.0, 1.0, 2.0)
    assert round(eps["parabolic"], 6) == 0.973446
    assert round(eps["linear"], 6) == 0.632031


def test_options_change_the_data() -> None:
    data = dict(Gmax=6.0, OP=1.2, G2=2.5, OA=0.5, AB=1.5)
    r = example_json(*(f"--{k}={v}" for k, v in data.items()))
    for law, eps in closed_form_eps(**data).items():
        assert r[f"eps_{law}"] == pytest.approx(eps, abs=1e-9)
    phi = np.linspace(-np.pi / 2, np.pi / 2, 1_000_001)
    s = (np.pi / 2 - phi) / (2 * np.pi)
    OB = -data["OA"] * np.sin(phi) + np.sqrt(data["OA"] ** 2 * np.sin(phi) ** 2
                                             + data["AB"] ** 2 - data["OA"] ** 2)
    for law, G_pv in (("parabolic", 4 * s * (1 - s)), ("linear", 2 * s)):
        Mu = np.abs((data["G2"] * OB - data["Gmax"] * G_pv * data["OP"]) * np.cos(phi))
        assert r[f"max_abs_Mu_{law}"] == pytest.approx(Mu.max(), abs=1e-9)
        assert r[f"phi_max_Mu_{law}"] == pytest.approx(phi[Mu.argmax()], abs=1e-5)


def test_eps_with_the_bar_beside_the_papers() -> None:
    """`<law>_with_bar` counts the bar's moment, as the rocking counterweight's M_u does: the
    counterweight then returns G2 times the rise of B over a stroke, 2 AB G2, so
    E_b = |2 AB G2 - E_u| (0.932601 and 0.5 for the paper's data); max |M_u + M_bar| from a
    dense grid of M_bar = G2 (dOB/dphi) sin(phi) with dOB/dphi by differences."""
    r = example_json()
    assert round(r["eps_parabolic_with_bar"], 6) == 0.932601
    assert r["eps_linear_with_bar"] == pytest.approx(0.5, abs=1e-12)
    assert round(r["eps_parabolic"], 6) == 0.973446       # the paper's, still beside it
    data = dict(Gmax=6.0, OP=1.2, G2=2.5, OA=0.5, AB=1.5)
    r = example_json(*(f"--{k}={v}" for k, v in data.items()))
    E_u = {"parabolic": data["Gmax"] * data["OP"] * (1.0 + 4.0 / math.pi ** 2),
           "linear": data["Gmax"] * data["OP"]}
    phi = np.linspace(-np.pi / 2, np.pi / 2, 1_000_001)
    s = (np.pi / 2 - phi) / (2 * np.pi)
    OB = -data["OA"] * np.sin(phi) + np.sqrt(data["OA"] ** 2 * np.sin(phi) ** 2
                                             + data["AB"] ** 2 - data["OA"] ** 2)
    M_bar = data["G2"] * np.gradient(OB, phi) * np.sin(phi)
    for law, G_pv in (("parabolic", 4 * s * (1 - s)), ("linear", 2 * s)):
        E_b = abs(2.0 * data["AB"] * data["G2"] - E_u[law])
        assert r[f"eps_{law}_with_bar"] == pytest.approx(1.0 - E_b / E_u[law], abs=1e-9)
        Mu = np.abs((data["G2"] * OB - data["Gmax"] * G_pv * data["OP"]) * np.cos(phi) + M_bar)
        assert r[f"max_abs_Mu_{law}_with_bar"] == pytest.approx(Mu.max(), abs=1e-6)


def test_bad_data_exits_non_zero() -> None:
    done = example("--json", "--AB=1", "--OA=1")
    assert done.returncode != 0 and done.stdout == ""
    assert done.stderr.startswith("error: option --AB = 1.0 m must be above OA = 1.0 m")


@pytest.mark.parametrize("option, words", [
    ("--G2=-1", ("--G2", "[0.0, inf)")),
    ("--Gmax=nan", ("--Gmax", "finite")),
    ("--OP=0", ("--OP", "(0.0, inf)")),
    ("--AB=0.5", ("--AB", "OA")),
])
def test_bad_data_message(option: str, words: tuple[str, ...],
                          capsys: pytest.CaptureFixture[str]) -> None:
    """Same command in-process (faster): one-line error naming the option and its range."""
    assert cli.main(["ciupitu-example", "--json", option]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1
    for word in words:
        assert word in captured.err


def test_bar_reaction_changes_the_stroke_energy() -> None:
    """The FMU's torque -dE_p/dtheta includes the bar's reaction that the paper's M_b omits:
    over a stroke the counterweight then gives back 2 AB G2 (the rise of B times G2)."""
    params = paper_example.paper_example_parameters()
    for law, eps in (("parabolic", 0.9326006587), ("linear", 0.5)):
        def Q(phi: float, law: str = law) -> float:    # generalised force along phi
            payload = 4.0 * paper_example.PAYLOAD_LAWS[law](paper_example.stroke_fraction(phi)) / G
            return -ciupitu.tau_gravity(params, payload, np.pi / 2 - phi)
        E_u = paper_example.stroke(paper_example.ExampleData(), law).E_u
        E_b = abs(quad(Q, -np.pi / 2, np.pi / 2, epsabs=1e-12)[0])
        assert 1.0 - E_b / E_u == pytest.approx(eps, abs=1e-9)


# ---- the FMU -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fmu_file() -> Path:
    return fmu_build.fmu_path("CiupituBalancer")


def test_fmu_is_valid(fmu_file: Path) -> None:
    assert validate_fmu(str(fmu_file)) == []


def counterweight(OA: float, AB: float, theta: complex) -> tuple[complex, complex]:
    """Position (x, y) of B = -r e at distance AB from A = (0, OA):
    r^2 + 2 OA r cos(theta) + OA^2 - AB^2 = 0."""
    r = -OA * cmath.cos(theta) + cmath.sqrt((OA * cmath.cos(theta)) ** 2 + AB ** 2 - OA ** 2)
    return r * cmath.sin(theta), -r * cmath.cos(theta)


def potential(p: dict[str, float], payload: float, theta: complex) -> complex:
    _, y_B = counterweight(p["OA"], p["AB"], theta)
    return p["g"] * ((p["m"] * p["c"] + payload * p["w"] - p["m_fixed_cw"] * p["c_fixed_cw"])
                     * cmath.cos(theta) + p["m2"] * y_B)


def d_dtheta(f: Callable[[complex], Any], theta: float, h: float = 1e-20) -> Any:
    """Complex-step derivative of a real-analytic function, scalar or tuple (exact to rounding)."""
    value = f(theta + 1j * h)
    return tuple(v.imag / h for v in value) if isinstance(value, tuple) else value.imag / h


PARAMS = dict(m=3.0, c=0.2, J_link=0.16, w=0.35, m2=0.9, OA=0.15, AB=0.32, m_fixed_cw=5.0,
              c_fixed_cw=0.1, d_link=0.0, g=G, J_drive=0.01)


@pytest.mark.parametrize("theta0", [-2.5, -0.4, 0.0, 0.3, math.pi / 2, 2.2, math.pi, 4.0])
def test_fmu_static_moments(fmu_file: Path, theta0: float) -> None:
    payload = 0.7
    p = PARAMS
    with CoSimFMU(fmu_file) as fmu:
        fmu.initialize({**p, "theta0": theta0, "omega0": 0.0, "payload": payload})
        out = fmu.get(["OB", "M_g", "M_b", "M_u", "M_bar", "tau_gravity", "E_p", "E_kin"])
    phi = math.pi / 2 - theta0
    x_B, y_B = counterweight(p["OA"], p["AB"], theta0)
    OB = math.hypot(x_B.real, y_B.real)
    M_g = -payload * G * p["w"] * math.cos(phi)
    M_b = p["m2"] * G * OB * math.cos(phi)
    tau = -d_dtheta(lambda t: potential(p, payload, t), theta0)
    expected = dict(OB=OB, M_g=M_g, M_b=M_b, M_u=M_g + M_b, tau_gravity=tau,
                    E_p=potential(p, payload, theta0).real, E_kin=0.0)
    for name, value in expected.items():
        assert out[name] == pytest.approx(value, abs=1e-9), name
    # tau_gravity = -(M_u + M_bar + (m_fixed_cw c_fixed_cw - m c) g cos(phi))
    M_link = (p["m_fixed_cw"] * p["c_fixed_cw"] - p["m"] * p["c"]) * G * math.cos(phi)
    assert out["M_bar"] == pytest.approx(-tau - M_g - M_b - M_link, abs=1e-9)


def test_fmu_kinetic_energy(fmu_file: Path) -> None:
    """E_kin = 1/2 omega^2 (J_link + payload w^2 + m_fixed_cw c_fixed_cw^2 + J_drive)
    + 1/2 m2 |v_B|^2."""
    p, payload, theta0, omega0 = PARAMS, 0.4, 0.8, 2.5
    with CoSimFMU(fmu_file) as fmu:
        fmu.initialize({**p, "theta0": theta0, "omega0": omega0, "payload": payload})
        E_kin = fmu.get(["E_kin"])["E_kin"]
    dx, dy = d_dtheta(lambda t: counterweight(p["OA"], p["AB"], t), theta0)
    J_rigid = p["J_link"] + payload * p["w"] ** 2 + p["m_fixed_cw"] * p["c_fixed_cw"] ** 2 \
        + p["J_drive"]
    expected = 0.5 * omega0 ** 2 * (J_rigid + p["m2"] * (dx * dx + dy * dy))
    assert E_kin == pytest.approx(expected, abs=1e-9)


def test_fmu_conserves_energy(fmu_file: Path) -> None:
    """Drive off, no friction, constant payload: E_p + E_kin stays constant over 20 s.

    With E_p and E_kin checked independently above, conservation for a motion that sweeps
    the whole circle (so J(theta) varies) pins the equation of motion, dJ/dtheta term included.
    """
    p, dt, n = PARAMS, 1e-3, 20_000
    with CoSimFMU(fmu_file) as fmu:
        fmu.initialize({**p, "theta0": 0.5, "omega0": 2.5, "payload": 1.0})
        energy, theta, omega = [], [], []
        for k in range(n):
            out = fmu.get(["E_p", "E_kin", "theta", "omega"])
            energy.append(out["E_p"] + out["E_kin"])
            theta.append(out["theta"])
            omega.append(out["omega"])
            fmu.step(k * dt, dt)
    assert max(theta) - min(theta) > 4 * math.pi            # several full turns
    assert max(omega) - min(omega) > 1.0                    # speed varies with the angle
    assert max(energy) - min(energy) < 1e-6


def test_fmu_rejects_bad_parameters(fmu_file: Path) -> None:
    with CoSimFMU(fmu_file) as fmu:
        with pytest.raises(FMICallException):
            fmu.initialize({"OA": 0.3, "AB": 0.3})
        assert any(m.status == "Error" and "AB = 0.3" in m.message and "OA" in m.message
                   for m in fmu.messages)


def test_counterweight_slide_friction_dissipates_d_cw_times_its_speed_squared() -> None:
    """d_cw acts on the counterweight's sliding speed dOB/dt (here by central difference of
    eq. 13 along the motion): the dissipated power is d_cw (dOB/dt)^2 and it brakes the arm by
    that power over omega; with the arm at rest nothing is lost."""
    p = ciupitu.Parameters(d_link=0.0, d_cw=3.0)
    free = ciupitu.Parameters(d_link=0.0)
    theta, omega, h = 1.1, 0.7, 1e-6

    def OB(angle: float) -> float:
        phi = math.pi / 2 - angle
        return math.sqrt(p.AB ** 2 - (p.OA * math.cos(phi)) ** 2) - p.OA * math.sin(phi)

    slide_speed = (OB(theta + omega * h) - OB(theta - omega * h)) / (2 * h)
    s = ciupitu.State(theta, omega)
    rates = ciupitu.derivatives(p, ciupitu.Inputs(), s)
    J = ciupitu.inertia(p, 0.0, theta)[0]
    assert rates.E_loss == pytest.approx(3.0 * slide_speed ** 2, rel=1e-8)
    braking = (ciupitu.derivatives(free, ciupitu.Inputs(), s).omega - rates.omega) * J * omega
    assert braking == pytest.approx(3.0 * slide_speed ** 2, rel=1e-8)
    assert ciupitu.derivatives(p, ciupitu.Inputs(), ciupitu.State(theta, 0.0)).E_loss == 0.0


@pytest.mark.parametrize("kw", [{}, {"OA": 0.0}, {"d_cw": 2.0, "J_drive": 0.3, "OA": 0.3}])
def test_rk4_stage_is_the_arm_terms_written_out(kw: dict[str, float]) -> None:
    """The RK4 stage (`_arm_rates`) writes _arm_terms out for speed: it must give the numbers
    of the Lagrange equation over _arm_terms bit for bit, with the terms computed afresh or
    kept from the last _arm_terms (same theta and payload objects), and must not take kept
    terms of another payload or angle."""
    def expected(payload: float, tau: float, theta: float, omega: float) -> tuple[float, float]:
        _, _, _, J, dJ, damping, gravity = ciupitu._arm_terms(
            ciupitu.Parameters(**kw), payload, theta)   # fresh parameters: nothing kept
        return ((tau + gravity - damping * omega - 0.5 * dJ * omega * omega) / J,
                damping * omega * omega)

    for theta in (-0.0, 0.3, 1.0, math.pi / 2, 2.5, -4.0, 11.0):
        for omega, payload, tau in ((0.0, 0.0, 0.0), (1.7, 0.4, -2.0), (-3.1, 1.3, 0.5)):
            want = [x.hex() for x in expected(payload, tau, theta, omega)]
            p = ciupitu.Parameters(**kw)
            assert [x.hex() for x in ciupitu._arm_rates(p, payload, tau)(theta, omega)] == want
            ciupitu._arm_terms(p, payload, theta)     # kept: the stage takes them
            assert [x.hex() for x in ciupitu._arm_rates(p, payload, tau)(theta, omega)] == want
            other_payload = payload + 0.25            # kept terms of another payload
            ciupitu._arm_terms(p, other_payload, theta)
            assert [x.hex() for x in ciupitu._arm_rates(p, payload, tau)(theta, omega)] == want
            ciupitu._arm_terms(p, payload, theta + 0.5)  # and of another angle
            assert [x.hex() for x in ciupitu._arm_rates(p, payload, tau)(theta, omega)] == want
