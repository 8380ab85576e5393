"""ActiveSpringBalancer FMU (Ciupitu 2018 Fig. 8), exercised through FMPy: balance against
the closed form, the energy ledger with the drives off and on, the self-locking carriage,
state save/restore across a payload change, and bad input. Independent numbers only: the
closed forms are restated here, not taken from `fmu_src.mechanisms.active_spring.physics`."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping

import pytest
from conftest import (
    LEDGER,
    failed_initialisation,
    ledger_residual,
    refused_set,
    warnings,
)
from fmpy import read_model_description

from harness.fmu.build import fmu_path
from harness.fmu.loader import CoSimFMU

MODEL = "ActiveSpringBalancer"
G, M, C, J_LINK, W, X1A, K, Y_B0 = 9.81, 3.0, 0.2, 0.16, 0.35, 0.06, 981.0, 0.1
DT = 1e-3


@pytest.fixture(scope="module")
def fmu() -> Iterator[CoSimFMU]:
    with CoSimFMU(fmu_path(MODEL)) as instance:
        yield instance


def start(fmu: CoSimFMU, values: Mapping[str, float]) -> None:
    """Reset to the defaults; initialise with these parameters and input start values."""
    fmu.reset()
    fmu.initialize(values)


def balancing_travel(payload: float) -> float:
    """q that puts B at (m c + payload w) g / (k x1A), the zero-free-length balance [m]."""
    return (M * C + payload * W) * G / (K * X1A) - Y_B0


@pytest.mark.parametrize("payload", [0.0, 1.0, 3.0])
def test_balanced_link_rests_at_every_angle(fmu: CoSimFMU, payload: float) -> None:
    """B at the closed-form balance: tau_gravity = balance_error = 0 at any angle, and the
    undriven link stays where it is put (1 s)."""
    for theta in (0.0, 0.7, math.pi / 2, 2.5, math.pi, 5.0):
        start(fmu, {"theta0": theta, "q0": balancing_travel(payload), "payload": payload})
        out = fmu.get(["tau_gravity", "balance_error", "Y_B"])
        assert abs(out["tau_gravity"]) < 1e-12 and abs(out["balance_error"]) < 1e-12
        assert out["Y_B"] == pytest.approx((M * C + payload * W) * G / (K * X1A), rel=1e-15)
        for n in range(1000):
            fmu.step(n * DT, DT)
        assert fmu.get(["theta"])["theta"] == pytest.approx(theta, abs=1e-12)


def test_unbalanced_torque_and_spring_outputs_match_the_geometry(fmu: CoSimFMU) -> None:
    """Zero-free-length spring with B off its balance: tau_gravity = [(m c + payload w) g -
    k x1A Y_B] sin(theta); l_s = |B - A|, F_s = k l_s, F_q = -k (Y_B - x1A cos(theta))."""
    theta, q, payload = 2.2, 0.03, 0.5
    start(fmu, {"theta0": theta, "q0": q, "payload": payload})
    out = fmu.get(["tau_gravity", "l_s", "F_s", "F_q"])
    Y_B = Y_B0 + q
    length = math.hypot(X1A * math.sin(theta), Y_B - X1A * math.cos(theta))
    assert out["tau_gravity"] == pytest.approx(
        ((M * C + payload * W) * G - K * X1A * Y_B) * math.sin(theta), rel=1e-12)
    assert out["l_s"] == pytest.approx(length, rel=1e-14)
    assert out["F_s"] == pytest.approx(K * length, rel=1e-14)
    assert out["F_q"] == pytest.approx(-K * (Y_B - X1A * math.cos(theta)), rel=1e-12)


def simulate(fmu: CoSimFMU, values: Mapping[str, float],
             schedule: list[tuple[float, Mapping[str, float]]], stop: float
             ) -> tuple[float, dict[str, float]]:
    """Largest drift of the ledger residual [J] and the final outputs; schedule: (time, inputs
    set from then on)."""
    start(fmu, values)
    names = [*LEDGER[MODEL], "theta", "q"]
    reference, drift = ledger_residual(MODEL, fmu.get(names)), 0.0
    pending = list(schedule)
    for n in range(round(stop / DT)):
        while pending and pending[0][0] <= n * DT + 1e-12:
            fmu.set(pending.pop(0)[1])
        fmu.step(n * DT, DT)
        out = fmu.get(names)
        drift = max(drift, abs(ledger_residual(MODEL, out) - reference))
    return drift, out


PAYLOAD_CHANGES = [(0.5, {"payload": 1.2}), (1.5, {"payload": 0.3})]
REAL_SPRING = {"F_s0": 20.0, "l_s0": 0.05, "X_B": -0.02}
IDEAL = {"mu": 0.0}   # the screw's lossless limits
# Tr 10x2 (lead 2 mm, pitch diameter 9 mm) on bronze, mu = 0.1, 15 deg flanks, the default
TR10X2_ETA_F = math.tan(math.atan(0.002 / (math.pi * 0.009))) / math.tan(
    math.atan(0.002 / (math.pi * 0.009)) + math.atan(0.1 / math.cos(math.radians(15.0))))
SCREWS = {"ideal_self_locking": IDEAL, "lossless_back_drivable": {**IDEAL, "self_locking": False},
          "tr10x2": {}, "back_drivable_friction": {"mu": 0.03, "self_locking": False}}


@pytest.mark.parametrize("screw", SCREWS.values(), ids=SCREWS.keys())
@pytest.mark.parametrize("spring", [{}, REAL_SPRING], ids=["zero_free_length", "real"])
def test_energy_ledger_closes_with_the_drives_off(fmu: CoSimFMU, spring: dict,
                                                  screw: dict) -> None:
    """Drives off, an unbalanced swinging link with dampers, a carriage launched upwards (on a
    self-locking screw it stops and stays, on a back-drivable one it bounces on the spring),
    payloads joining and leaving: the residual stays constant to 1e-9 J; nothing is booked to
    the drives."""
    drift, out = simulate(fmu, {**spring, **screw, "theta0": 1.0, "omega0": 2.0,
                                "q_dot0": 0.05}, PAYLOAD_CHANGES, 2.5)
    assert drift < 1e-9
    assert out["W_drive"] == 0.0 and out["W_adjust"] == 0.0
    assert out["E_loss"] > 0.1 and out["E_added"] != 0.0
    # held where it stopped / pulled down
    assert (out["q"] > 0.0) == screw.get("self_locking", True)


@pytest.mark.parametrize("screw, lift, lower", [(IDEAL, 120.0, -2.0), ({}, 300.0, -80.0)],
                         ids=["ideal", "tr10x2"])
def test_energy_ledger_closes_with_the_drives_on(fmu: CoSimFMU, screw: dict, lift: float,
                                                 lower: float) -> None:
    """Both drives pushing, the self-locking carriage raised against the spring, then lowered
    (the Tr 10x2 needs 1 / eta_f = 2.5 times the ideal screw's push to raise, and a push to
    lower): residual within 1e-9 J; the actuator's work is counted in W_adjust."""
    drift, out = simulate(fmu, {**REAL_SPRING, **screw, "theta0": 2.0},
                          [(0.0, {"tau_drive": 0.3, "F_adjust": lift}), *PAYLOAD_CHANGES,
                           (2.0, {"F_adjust": lower})], 2.5)
    assert drift < 1e-9
    assert abs(out["W_drive"]) > 0.01 and out["W_adjust"] > 0.1


def test_self_locking_carriage_holds_without_the_actuator(fmu: CoSimFMU) -> None:
    """F_adjust = 0: the spring pulls on the carriage (F_q far from 0) and the unbalanced link
    swings, yet q does not move: the screw holds the load, F_lock = m_q g - F_q."""
    start(fmu, {"theta0": 1.0, "payload": 2.0})
    for n in range(500):
        fmu.step(n * DT, DT)
    out = fmu.get(["q", "q_dot", "F_q", "F_lock", "W_adjust", "theta", "m_q"])
    assert out["q"] == 0.0 and out["q_dot"] == 0.0 and out["W_adjust"] == 0.0
    assert abs(out["F_q"]) > 10.0 and abs(out["theta"] - 1.0) > 0.1
    assert out["F_lock"] == pytest.approx(out["m_q"] * G - out["F_q"], rel=1e-15)


@pytest.mark.parametrize("screw, eta_f", [(IDEAL, 1.0), ({}, TR10X2_ETA_F)],
                         ids=["ideal", "tr10x2"])
@pytest.mark.parametrize("theta, cost", [(0.0, 4.2442), (math.pi, 11.1112)])
def test_regulation_costs_the_spring_energy_and_holds(fmu: CoSimFMU, theta: float,
                                                      cost: float, screw: dict,
                                                      eta_f: float) -> None:
    """Regulating for 1 kg at rest at the upright or hanging link: a P law on q (with the
    load through the screw, (m_q g - F_q) / eta_f, fed forward) raises B by the closed-form
    58.3 mm; released, the screw holds it. The actuator's work beyond what is dissipated
    (dampers and the screw's friction) is the energy stored, 1/2 k (Y'^2 - Y^2) - k x1A
    cos(theta) dY + m_q g dY: 4.24 J upright, 11.11 J hanging."""
    start(fmu, {**screw, "theta0": theta})
    fmu.set({"payload": 1.0})
    target = balancing_travel(1.0)
    for n in range(1000):
        out = fmu.get(["q", "F_q"])
        fmu.set({"F_adjust": (0.5 * G - out["F_q"]) / eta_f + 2000.0 * (target - out["q"])})
        fmu.step(n * DT, DT)
    fmu.set({"F_adjust": 0.0})
    for n in range(1000, 1200):
        fmu.step(n * DT, DT)
    out = fmu.get(["q", "q_dot", "W_adjust", "E_loss", "balance_error", "theta"])
    assert out["q"] == pytest.approx(target, abs=1e-7) and out["q_dot"] == 0.0
    dY = out["q"]
    stored = (0.5 * K * ((Y_B0 + dY) ** 2 - Y_B0 ** 2) - K * X1A * math.cos(theta) * dY
              + 0.5 * G * dY)
    assert out["W_adjust"] - out["E_loss"] == pytest.approx(stored, abs=1e-9)
    assert stored == pytest.approx(cost, abs=1e-3)
    assert abs(out["balance_error"]) < 1e-5 and out["theta"] == theta   # k x1A 1e-7 m


def test_state_restore_replays_a_payload_change_exactly(fmu: CoSimFMU) -> None:
    """The state saved before a payload change (the held payload is hidden state) replays to
    bit-identical outputs, also through serialisation."""
    start(fmu, {"theta0": 1.0, "omega0": 1.0})
    outputs = fmu.names("output")

    def replay() -> list[dict]:
        fmu.set({"payload": 1.0, "F_adjust": 0.5})
        rows = []
        for n in range(100):
            fmu.step(n * DT, DT)
            rows.append(fmu.get(outputs))
        return rows

    saved = fmu.slave.getFMUstate()
    serialized = fmu.slave.serializeFMUstate(saved)
    first = replay()
    fmu.slave.setFMUstate(saved)
    fmu.set({"payload": 0.0})
    assert replay() == first
    fmu.slave.setFMUstate(fmu.slave.deSerializeFMUstate(serialized))
    assert replay() == first
    fmu.slave.freeFMUstate(saved)
    assert first[-1]["E_added"] != 0.0


def test_compressed_spring_is_reported_once_per_spell(fmu: CoSimFMU) -> None:
    """Misuse the model allows: a spring with free length 0.3 m on a geometry where l_s stays
    below 0.17 m pushes (F_s < 0). One warning when F_s turns negative; it comes again only
    after the spring has been in tension in between (the carriage raised, then lowered)."""
    start(fmu, {"l_s0": 0.3, "F_s0": 0.0, "theta0": 0.5, "d_link": 5.0})
    earlier = len(warnings(fmu))    # the instance's log holds the earlier tests' messages
    steps = iter(range(1000))       # the communication points n DT, n = 0, 1, ...
    for n in itertools.islice(steps, 200):
        fmu.step(n * DT, DT)
    assert len(warnings(fmu)) == earlier + 1 and "spring in compression" in warnings(fmu)[-1]
    for force in (200.0, -200.0):   # B up to l_s > 0.3 m, then back down
        fmu.set({"F_adjust": force})
        for n in itertools.islice(steps, 200):
            fmu.step(n * DT, DT)
        fmu.set({"F_adjust": 0.0})
        for n in itertools.islice(steps, 200):
            fmu.step(n * DT, DT)
    assert len(warnings(fmu)) == earlier + 2


@pytest.mark.parametrize(("inputs", "named"), [
    ({"payload": -1.0}, "input payload = -1.0 kg is outside [0.0, inf]"),
    ({"payload": math.nan}, "input payload = nan kg is not a finite number in [0.0, inf]"),
    ({"F_adjust": math.inf}, "input F_adjust = inf N is not a finite number in [-inf, inf]"),
    ({"tau_drive": math.nan}, "input tau_drive = nan N.m is not a finite number in [-inf, inf]")])
def test_bad_input_is_refused_when_set(fmu: CoSimFMU, inputs: dict[str, float],
                                       named: str) -> None:
    """fmi2SetReal refuses the input with fmi2Error naming it and its range (it used to be
    accepted and the next step discarded); the previous value stays and the instance steps on
    with it (1 rad/s carries theta DT further)."""
    start(fmu, {"omega0": 1.0})
    before = fmu.get(["theta", "q"])
    assert refused_set(fmu, inputs) == named
    assert fmu.get(["theta", "q"]) == before
    fmu.step(0.0, DT)
    assert fmu.get(["theta"])["theta"] == pytest.approx(before["theta"] + DT, abs=1e-5)


def test_model_description_declares_units_and_bounds() -> None:
    variables = {v.name: v for v in read_model_description(str(fmu_path(MODEL))).modelVariables}
    units = {"theta": "rad", "q": "m", "F_adjust": "N", "F_q": "N", "k": "N/m",
             "W_adjust": "J", "balance_error": "N.m", "d_q": "N.s/m"}
    for name, unit in units.items():
        assert variables[name].declaredType.unit == unit, name
    assert float(variables["payload"].min) == 0.0 and float(variables["m_q"].min) == 0.0
    assert all(variables[name].description for name in variables)


def test_invalid_parameter_is_reported() -> None:
    """A parameter out of range fails initialisation with fmi2Error and a message naming it
    and its range; so does a self_locking the screw's friction contradicts (Tr 10x2 with
    mu = 0.05: friction angle 2.97 deg < lead angle 4.05 deg)."""
    assert "k = 0.0 N/m is outside (0.0, inf)" in failed_initialisation(MODEL, {"k": 0.0})
    assert "mu = 0.6 1 is outside [0.0, 0.5]" in failed_initialisation(MODEL, {"mu": 0.6})
    assert "self_locking = true contradicts the screw" in failed_initialisation(
        MODEL, {"mu": 0.05})
