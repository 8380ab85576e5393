"""The energy ledger's bound under random inputs at the extremes and random step sizes
(issue 22): at every communication point the residual (tests/conftest.py ledger_residual, the
registration's ledger) stays within `ledger_bound`: ledger_accuracy (default 1e-9) times the
energy throughput so far, the sum of |change| of every work and of E_added over the steps,
plus the ledger's rounding (docs/energy_ledger.md). Through the pure physics modules (as the
FMU steps them: switch_inputs, then advance), so that each run is short; fixed seeds.
"""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Callable, Iterable, Iterator
from functools import partial
from typing import Any

import pytest
from conftest import LEDGER, ledger_residual

from fmu_src.integration import LEDGER_ROUNDING, accepted_substeps, substep_rounding_scale
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


def mechanism(case: str) -> str:
    """The mechanism (FMU model) of a case of CASES."""
    return case.split("[")[0]


def random_steps(case: str, steps: int, seed: int) -> Iterator[tuple[dict[str, Any], float]]:
    """(inputs, dt) of a random run: the case's extreme inputs, dt from 0.1 ms to 32 ms
    (log-uniform)."""
    rng = random.Random(seed)
    for _ in range(steps):
        yield CASES[case][1](rng), 10.0 ** rng.uniform(-4.0, -1.5)


def magnitude(physics: Any, p: Any, u: Any, s: Any) -> float:
    """The sum of |term| of the ledger [J] (physics.ledger_terms)."""
    return sum(map(abs, physics.ledger_terms(p, u, s)))


def worst_ratio_over(case: str, parameters: dict[str, Any],
                     steps: Iterable[tuple[dict[str, Any], float]], accuracy: float = 1e-9
                     ) -> tuple[float, int]:
    """The largest residual / bound over a run of (inputs, dt) steps, and the number of steps
    refused (fmi2Discard: the state kept). The bound (docs/energy_ledger.md) is accuracy
    times the throughput plus LEDGER_ROUNDING times: the sum of |term| at the start and at
    the end of the run (the residual's own evaluation), before and after each step's input
    events (their booking), after the events and at the step's end, and n times the rounding
    scale of a sub-step at the step's end (integration.substep_rounding_scale)."""
    model = mechanism(case)
    physics = MECHANISMS[model].physics
    p = dataclasses.replace(physics.Parameters(), **parameters)
    u, s = physics.Inputs(), physics.initial_state(p)
    flows = [name for name, sign in LEDGER[model].items() if sign < 0]  # works, E_added
    cumulative = physics.State._fields.index("W_drive")   # the energies from W_drive on
    out = physics.outputs(p, u, s)._asdict()
    start, start_magnitude = ledger_residual(model, out), magnitude(physics, p, u, s)
    throughput, rounding, worst, refused = 0.0, 0.0, 0.0, 0
    for inputs, dt in steps:
        new_inputs = physics.Inputs(**inputs)
        switched = physics.switch_inputs(p, u, new_inputs, s)
        try:
            new = physics.advance(p, new_inputs, switched, dt)
        except DomainError:
            refused += 1
            continue
        n = accepted_substeps(new)
        assert n is not None, "a step not under the ledger's control"
        switched_magnitude = magnitude(physics, p, new_inputs, switched)
        end_magnitude = magnitude(physics, p, new_inputs, new)
        scale = substep_rounding_scale(partial(physics.ledger_terms, p, new_inputs), new,
                                       sum(physics.ledger_terms(p, new_inputs, new)),
                                       cumulative)
        rounding += (magnitude(physics, p, u, s) + 2.0 * switched_magnitude + end_magnitude
                     + n * scale)
        u, s = new_inputs, new
        after = physics.outputs(p, u, s)._asdict()
        throughput += sum(abs(after[name] - out[name]) for name in flows)
        out = after
        residual = abs(ledger_residual(model, out) - start)
        bound = accuracy * throughput + LEDGER_ROUNDING * (
            rounding + start_magnitude + end_magnitude)
        worst = max(worst, residual / bound)
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
    (plus the rounding), and a smaller residual than the default accuracy leaves on the same
    run."""
    parameters = CASES[case][0]
    loose = worst_bound_ratio(case, parameters, 150, 2, 1e-10)[0]
    tight, refused = worst_bound_ratio(case, {**parameters, "ledger_accuracy": 1e-10}, 150, 2,
                                       1e-10)
    assert tight <= 1.0 and refused < 15
    assert tight < loose


def test_an_undriven_step_after_a_carriage_push_meets_the_bound() -> None:
    """The deep fuzz's counterexample (on the ideal self-locking screw, mu = 0, the default
    when it was found): a 0.1 ms push of the carriage (F_adjust 200 N), then an undriven
    10 ms step in which the self-locking carriage stops. That step has no
    throughput, and its error (the stop is located to first order in the sub-step, checked:
    above 1e-10 J at 64 sub-steps) was let through by a rounding allowance that grew with n
    times the stored energies (7 J): 3.9e-12 J, 3.1 times the bound."""
    steps = [({"tau_drive": -12.5, "F_adjust": 200.0, "payload": 0.0}, 1e-4),
             ({"tau_drive": 0.0, "F_adjust": 0.0, "payload": 0.0}, 0.01)]
    physics = MECHANISMS["ActiveSpringBalancer"].physics
    p, u = physics.Parameters(mu=0.0), physics.Inputs(**steps[1][0])
    pushed = physics.advance(p, physics.Inputs(**steps[0][0]), physics.initial_state(p), 1e-4)
    coarse = physics._integrate(p, u, pushed, 0.01, 64, physics._payload_terms(p, 0.0)[2])
    assert coarse.q_dot == 0.0 < pushed.q_dot
    assert abs(sum(physics.ledger_terms(p, u, coarse))
               - sum(physics.ledger_terms(p, u, pushed))) > 1e-10
    worst, refused = worst_ratio_over("ActiveSpringBalancer[ideal_self_locking_screw]",
                                      {"mu": 0.0}, steps)
    assert worst <= 1.0 and refused == 0


@pytest.mark.parametrize("case", sorted(CASES))
def test_outputs_kept_from_the_ledger_are_the_outputs(case: str) -> None:
    """The outputs a step's end evaluation kept for its state and inputs (the ledger's terms
    and the outputs computed once) are, bit for bit, those computed afresh (another inputs
    object of the same values), along a random run."""
    model = mechanism(case)
    physics = MECHANISMS[model].physics
    p = dataclasses.replace(physics.Parameters(), **CASES[case][0])
    rng = random.Random(5)
    u, s = physics.Inputs(), physics.initial_state(p)
    for _ in range(30):
        new_inputs = physics.Inputs(**CASES[case][1](rng))
        s = physics.advance(p, new_inputs, physics.switch_inputs(p, u, new_inputs, s), 2e-3)
        u = new_inputs
        kept = physics.outputs(p, u, s)
        assert kept == physics.outputs(p, physics.Inputs(*u), s)
        assert tuple(physics.ledger_terms(p, u, s)) == tuple(
            physics.ledger_terms(p, physics.Inputs(*u), s))


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
