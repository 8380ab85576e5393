"""The energy ledger's bound under random inputs at the extremes and random step sizes
(issue 22): at every communication point the residual (tests/conftest.py ledger_residual, the
registration's ledger) stays within ledger_accuracy (default 1e-9) times the energy
throughput so far, the sum of |change| of every work and of E_added over the steps, plus
1e-12 J (FLOORS: more where work-free motion meets only the rounding allowance). Through
the pure physics modules (as the FMU steps them: switch_inputs, then advance), so that each
run is short; fixed seeds.
"""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import pytest
from conftest import LEDGER, ledger_residual

from fmu_src.parameters import DomainError
from harness import registry

MECHANISMS = registry.mechanisms()


def extreme(rng: random.Random, magnitude: float) -> float:
    """+-magnitude, or 0, at random."""
    return rng.choice((-magnitude, 0.0, magnitude))


def active_spring_inputs(rng: random.Random) -> dict[str, Any]:
    return {"tau_drive": extreme(rng, 50.0), "F_adjust": extreme(rng, 800.0),
            "payload": rng.choice((0.0, 5.0))}


# per case (a mechanism, or "mechanism[variant]" for more of its parameters): parameters and
# the inputs of a step, each at an extreme of what the mechanism is built for (efforts at
# full scale or zero, masses none or full, locks random). The active spring's screw: the
# default Tr 10x2 with friction, a back-drivable screw with friction and the lossless limits.
CASES: dict[str, tuple[dict[str, Any], Callable[[random.Random], dict[str, Any]]]] = {
    "SelfRegulatingBalancer": ({"m_slider": 0.2, "L0": 0.01}, lambda rng: {
        "tau_drive": extreme(rng, 50.0), "payload": rng.choice((0.0, 5.0)),
        "counterweight_added": rng.choice((0.0, 5.0)),
        "slider_locked": rng.random() < 0.5, "pulley_locked": rng.random() < 0.5}),
    "ActiveSpringBalancer": ({}, active_spring_inputs),
    "ActiveSpringBalancer[back_drivable_screw]": ({"mu": 0.03, "self_locking": False},
                                                  active_spring_inputs),
    "ActiveSpringBalancer[ideal_self_locking_screw]": ({"mu": 0.0}, active_spring_inputs),
    "ActiveSpringBalancer[lossless_back_drivable_screw]": (
        {"mu": 0.0, "self_locking": False}, active_spring_inputs),
    "CiupituBalancer": ({}, lambda rng: {
        "tau_drive": extreme(rng, 50.0), "payload": rng.choice((0.0, 5.0))}),
    "RockingCounterweightBalancer": ({}, lambda rng: {
        "tau_drive": extreme(rng, 50.0), "payload": rng.choice((0.0, 5.0))}),
    "PrismaticCompensator": ({"design_springs": False}, lambda rng: {
        "tau1": extreme(rng, 200.0), "f2": extreme(rng, 800.0)}),
}


# The bound's floor [J] where it is not 1e-12 J: a back-drivable carriage moves with no work
# done (the spring pulls it), so only the ledger's rounding allowance bounds such a step,
# 8 eps (n + 2) times its ~20 J of terms: 2e-12 J over 10 ms (50 sub-steps).
FLOORS = {"ActiveSpringBalancer[back_drivable_screw]": 1e-11,
          "ActiveSpringBalancer[lossless_back_drivable_screw]": 1e-11}


def mechanism(case: str) -> str:
    """The mechanism (FMU model) of a case of CASES."""
    return case.split("[")[0]


def random_steps(case: str, steps: int, seed: int) -> Iterator[tuple[dict[str, Any], float]]:
    """(inputs, dt) of a random run: the case's extreme inputs, dt from 0.1 ms to 32 ms
    (log-uniform)."""
    rng = random.Random(seed)
    for _ in range(steps):
        yield CASES[case][1](rng), 10.0 ** rng.uniform(-4.0, -1.5)


def worst_ratio_over(case: str, parameters: dict[str, Any],
                     steps: Iterable[tuple[dict[str, Any], float]], accuracy: float = 1e-9
                     ) -> tuple[float, int]:
    """The largest residual / (accuracy * throughput + floor) over a run of (inputs, dt)
    steps, and the number of steps refused (fmi2Discard: the state kept); the floor 1e-12 J
    or the case's FLOORS."""
    model, floor = mechanism(case), FLOORS.get(case, 1e-12)
    physics = MECHANISMS[model].physics
    p = dataclasses.replace(physics.Parameters(), **parameters)
    u, s = physics.Inputs(), physics.initial_state(p)
    flows = [name for name, sign in LEDGER[model].items() if sign < 0]  # works, E_added
    out = physics.outputs(p, u, s)._asdict()
    start, throughput, worst, refused = ledger_residual(model, out), 0.0, 0.0, 0
    for inputs, dt in steps:
        new_inputs = physics.Inputs(**inputs)
        try:
            new = physics.advance(p, new_inputs, physics.switch_inputs(p, u, new_inputs, s), dt)
        except DomainError:
            refused += 1
            continue
        u, s = new_inputs, new
        after = physics.outputs(p, u, s)._asdict()
        throughput += sum(abs(after[name] - out[name]) for name in flows)
        out = after
        residual = abs(ledger_residual(model, out) - start)
        worst = max(worst, residual / (accuracy * throughput + floor))
    return worst, refused


def worst_bound_ratio(case: str, parameters: dict[str, Any], steps: int, seed: int,
                      accuracy: float = 1e-9) -> tuple[float, int]:
    """worst_ratio_over a random run of the case's extreme inputs (random_steps)."""
    return worst_ratio_over(case, parameters, random_steps(case, steps, seed), accuracy)


@pytest.mark.parametrize("case", sorted(CASES))
def test_ledger_stays_within_its_bound_under_random_extremes(case: str) -> None:
    """Before the ledger's control of the sub-steps the active spring (F_adjust +-800 N)
    reached 1.6 times the bound and the prismatic compensator without designed springs 160
    times."""
    worst, refused = worst_bound_ratio(case, CASES[case][0], 400, 22)
    assert worst <= 1.0 and refused < 40


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_tighter_ledger_accuracy_tightens_the_bound(case: str) -> None:
    """ledger_accuracy is a parameter: 1e-10 keeps the residual within 1e-10 of the throughput
    (plus 1e-12 J), and a smaller residual than the default accuracy leaves on the same run."""
    parameters = CASES[case][0]
    loose = worst_bound_ratio(case, parameters, 150, 7, 1e-10)[0]
    tight, refused = worst_bound_ratio(case, {**parameters, "ledger_accuracy": 1e-10}, 150, 7,
                                       1e-10)
    assert tight <= 1.0 and refused < 15
    assert tight < loose


def test_every_mechanism_declares_ledger_accuracy_with_its_default() -> None:
    for model in {mechanism(case) for case in CASES}:
        field = next(f for f in dataclasses.fields(MECHANISMS[model].physics.Parameters)
                     if f.name == "ledger_accuracy")
        assert field.default == 1e-9 and field.metadata["unit"] == "1"
        assert field.metadata["min"] > 0.0 and field.metadata["description"]


@pytest.mark.parametrize("case", sorted(CASES))
def test_ledger_terms_are_the_registrations_ledger(case: str) -> None:
    """The quantity the sub-step control holds (physics.ledger_terms) is the registration's
    ledger over the outputs, along a random run."""
    model = mechanism(case)
    physics = MECHANISMS[model].physics
    p = dataclasses.replace(physics.Parameters(), **CASES[case][0])
    rng = random.Random(3)
    u, s = physics.Inputs(), physics.initial_state(p)
    for _ in range(50):
        new_inputs = physics.Inputs(**CASES[case][1](rng))
        s = physics.advance(p, new_inputs, physics.switch_inputs(p, u, new_inputs, s), 2e-3)
        u = new_inputs
        terms = physics.ledger_terms(p, u, s)
        expected = ledger_residual(model, physics.outputs(p, u, s)._asdict())
        assert sum(terms) == pytest.approx(expected, rel=1e-12, abs=1e-12 * sum(map(abs, terms)))
