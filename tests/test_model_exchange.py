"""Every mechanism FMU as FMI 2.0 Model Exchange (docs/model_exchange.md), in FMPy and in the
harness's Model Exchange engine.

Tolerances are derived from each integrator's own convergence, measured in the same test:
- FMPy's CVode at a relative tolerance rtol and at rtol / 10: the difference estimates the
  error at rtol (CVode's error scales with its tolerance); Co-Simulation with n and 2 n
  communication steps per input interval: the difference bounds its error (its RK4 sub-steps
  are refined until the ledger meets 1e-9 of the throughput). Both get the same staircase of
  inputs (`harness.fmu.model_exchange`), so over a run Model Exchange and Co-Simulation may
  differ by twice the sum of those estimates' largest values (a factor 2 for the estimates'
  own error), plus 1e-9 of the state's scale for rounding;
- explicit Euler at h and h / 2: first order, its error at h / 2 is about their difference;
- the energy ledger is constant in the exact solution: CVode's run closes it within rtol
  times (1 J plus the energy throughput) per integration interval (the solver restarts at
  every input event), Euler's residual halves with the step;
- the engine against the co-simulation master: the master's drawn energy is first order in
  its communication step (results/bench/convergence.csv), so its error at 1 ms is about its
  change from 2 ms to 1 ms; the engine's, its change from rtol to rtol / 10.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from harness import registry, scenarios
from harness.engines import fmpy_master, fmu_me, reference
from harness.engines.plan import prepare
from harness.engines.result import RunResult
from harness.fmu import build as fmu_build
from harness.fmu import model_exchange as me
from harness.fmu.loader import FMUCallError
from harness.fmu.model_exchange import ModelExchangeFMU

MECHANISMS = registry.mechanisms()

# per mechanism: a scenario variant that drives it through its input sequence, and the end of
# the stretch the fast test runs [s] (the slow test runs the whole scenario)
CASES = {
    "SelfRegulatingBalancer": ("franchetti2021", "self_regulating", 21.0),   # locks, ramps
    "CiupituBalancer": ("ciupitu2018", "parabolic_balanced", 2.0),           # payload ramp
    "RockingCounterweightBalancer": ("ciupitu2018", "parabolic_rocking", 2.0),
    "ActiveSpringBalancer": ("franchetti2021", "active_relocation", 18.0),   # screw moving
    "PrismaticCompensator": ("demian2022", "compensated", 8.0),
}
RTOL = 1e-7
# the input staircase holds every STRIDE-th recorded point of the master's run (50 ms: each
# step of it is an event for the Model Exchange solver, whose cost it sets), and the
# Co-Simulation takes SUBSTEPS steps per interval of it (2 ms); both runs see the same inputs
STRIDE = 5
SUBSTEPS = 25


def test_every_mechanism_has_a_case() -> None:
    assert set(CASES) == set(MECHANISMS)


@pytest.mark.parametrize("model", sorted(MECHANISMS))
def test_one_model_description_offers_both_interfaces(model: str) -> None:
    """validate_fmu finds no problem; ModelExchange beside CoSimulation with one binary,
    needsExecutionTool false in both; the continuous states are the physics' State (each
    with its derivative) and the event indicators its EVENT_INDICATORS."""
    path = fmu_build.fmu_path(model)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    physics = MECHANISMS[model].physics
    assert md.modelExchange.modelIdentifier == md.coSimulation.modelIdentifier == model
    assert not md.modelExchange.needsExecutionTool and not md.coSimulation.needsExecutionTool
    assert [d.variable.derivative.name for d in md.derivatives] == list(physics.State._fields)
    assert [d.variable.name for d in md.derivatives] == [
        f"der({name})" for name in physics.State._fields]
    assert md.numberOfEventIndicators == len(physics.EVENT_INDICATORS)
    units = {v.name: v.unit or (v.declaredType.unit if v.declaredType else None)
             for v in md.modelVariables}
    for d in md.derivatives:
        assert units[d.variable.name] and units[d.variable.derivative.name]


@functools.cache
def master_run(scenario_name: str, variant: str) -> RunResult:
    """The co-simulation run whose efforts drive the open-loop runs (one per variant)."""
    scenario = scenarios.load(scenario_name)
    return fmpy_master.run(prepare(scenario, scenario.variant(variant)))


def staircase_of(model: str, stop: float) -> tuple:
    """(parameters, times, held inputs, FMPy table, state names) of the model's case up to
    stop [s]."""
    scenario_name, variant, _ = CASES[model]
    scenario = scenarios.load(scenario_name)
    run = master_run(scenario_name, variant)
    times = run.series["time"].to_numpy()
    kept = slice(0, int(np.sum(times <= stop + 1e-9)), STRIDE)
    times = times[kept]
    held = me.staircase(scenario, variant, times, {
        name: values[kept] for name, values in me.efforts(run, scenario).items()})
    states = list(MECHANISMS[model].physics.State._fields)
    return run.parameters, times, held, me.signals(times, held), states


def compare(model: str, stop: float) -> dict[str, float]:
    """The agreement of Model Exchange (CVode) with Co-Simulation over the case up to stop,
    against its derived tolerance, and the ledger's residual against its bound: the worst
    ratio of each (at most 1 to pass)."""
    parameters, times, held, table, states = staircase_of(model, stop)
    ledger_terms = list(MECHANISMS[model].ledger)
    output = sorted({*states, *ledger_terms} & {
        v.name for v in read_model_description(str(fmu_build.locate(model))).modelVariables})
    fine, finer = (me.co_simulate(model, parameters, times, held, n, output)
                   for n in (SUBSTEPS, 2 * SUBSTEPS))
    loose, tight = (me.simulate(model, parameters, table, float(times[-1]), output=output,
                                relative_tolerance=rtol) for rtol in (RTOL, RTOL / 10))
    worst_state = 0.0
    for name in set(states) & set(output):
        at = {key: np.interp(times, run["time"], run[name]) for key, run in
              (("loose", loose), ("tight", tight))}
        # over the whole run: pointwise, an estimate may vanish where two runs cross
        estimate = (2.0 * (np.max(np.abs(at["loose"] - at["tight"]))
                           + np.max(np.abs(fine[name] - finer[name])))
                    + 1e-9 * (1.0 + np.max(np.abs(finer[name]))))
        worst_state = max(worst_state,
                          float(np.max(np.abs(at["loose"] - finer[name]))) / estimate)
    ledger = me.ledger(model, loose)
    works = [name for name, sign in MECHANISMS[model].ledger.items() if sign < 0]
    throughput = sum(float(np.max(np.abs(loose[name]))) for name in works) + float(
        np.max(loose["E_loss"]))
    bound = RTOL * (1.0 + throughput) * len(table)
    return {"states": worst_state, "ledger": abs(float(ledger[-1] - ledger[0])) / bound}


@pytest.mark.parametrize("model", sorted(CASES))
def test_model_exchange_agrees_with_co_simulation_and_closes_the_ledger(model: str) -> None:
    ratios = compare(model, CASES[model][2])
    assert ratios["states"] <= 1.0 and ratios["ledger"] <= 1.0, ratios


@pytest.mark.slow
@pytest.mark.parametrize("model", sorted(CASES))
def test_whole_scenarios_agree(model: str) -> None:
    scenario_name, variant, _ = CASES[model]
    ratios = compare(model, scenarios.load(scenario_name).duration)
    assert ratios["states"] <= 1.0 and ratios["ledger"] <= 1.0, ratios


@pytest.mark.parametrize("model", ["PrismaticCompensator", "CiupituBalancer"])
def test_euler_converges_to_co_simulation_with_first_order(model: str) -> None:
    """FMPy's explicit Euler at 1 ms and 0.5 ms over the first second: the error at 0.5 ms is
    within its difference from 1 ms (first order), and the ledger's residual halves."""
    parameters, times, held, table, states = staircase_of(model, 1.0)
    ledger_terms = list(MECHANISMS[model].ledger)
    output = sorted({*states, *ledger_terms} & {
        v.name for v in read_model_description(str(fmu_build.locate(model))).modelVariables})
    reference = me.co_simulate(model, parameters, times, held, SUBSTEPS, output)
    coarse, fine = (me.simulate(model, parameters, table, 1.0, solver="Euler", step_size=h,
                                output=output) for h in (1e-3, 5e-4))
    for name in set(states) & set(output):
        at_coarse = np.interp(times, coarse["time"], coarse[name])
        at_fine = np.interp(times, fine["time"], fine[name])
        error = np.abs(at_fine - reference[name])
        assert np.all(error <= 1.5 * np.abs(at_coarse - at_fine)
                      + 1e-9 * (1.0 + np.abs(reference[name]))), name
    residual = [abs(float(ledger[-1] - ledger[0]))
                for ledger in (me.ledger(model, coarse), me.ledger(model, fine))]
    assert residual[1] <= 0.75 * residual[0], residual


@pytest.mark.parametrize(("model", "parameters", "inputs", "indicator"), [
    # the spring pulls the released slider onto its inner stop (the pulley locked)
    pytest.param("SelfRegulatingBalancer", {"theta0": 3.14159, "m_slider": 0.2},
                 {"slider_locked": False, "pulley_locked": True}, "b",
                 marks=pytest.mark.slow),   # about 5 s; the friction case below stays

    # Coulomb friction: the slider released by the counterweight slides, stops and sticks
    ("SelfRegulatingBalancer", {"theta0": 3.0, "m_slider": 0.2, "mu_slider": 0.3},
     {"slider_locked": False, "pulley_locked": False, "counterweight_added": 0.3}, "b"),
    # the prismatic joint pushed onto its outer stroke limit
    ("PrismaticCompensator", {"q2_0": 0.7}, {"f2": 3.0}, "q2"),
    # the self-locking carriage pushed up, then left: it stops and the screw holds it
    ("ActiveSpringBalancer", {"q_dot0": 0.02}, {}, "q"),
])
def test_state_events_agree_with_co_simulation(model: str, parameters: dict, inputs: dict,
                                               indicator: str) -> None:
    """The events the co-simulation step handles inside itself (end stops, sticking, the
    screw's stop) located by CVode: the state after 1 s agrees with 0.1 ms co-simulation
    steps within the tolerance derived as in the module docstring, and the ledger closes."""
    times = np.linspace(0.0, 1.0, 101)
    held = {name: np.full(len(times), value, dtype=bool if isinstance(value, bool) else float)
            for name, value in inputs.items()}
    physics = MECHANISMS[model].physics
    output = sorted({*(n for n in physics.State._fields if n in {
        v.name for v in read_model_description(str(fmu_build.locate(model))).modelVariables}),
        *MECHANISMS[model].ledger})
    table = me.signals(times, held) if held else None
    fine, finer = (me.co_simulate(model, parameters, times, held, n, output) for n in (100, 200))
    loose, tight = (me.simulate(model, parameters, table, 1.0, output=output,
                                relative_tolerance=rtol) for rtol in (1e-8, 1e-9))
    value = {key: float(np.asarray(run[indicator])[-1]) for key, run in
             (("loose", loose), ("tight", tight), ("fine", fine), ("finer", finer))}
    allowed = 2.0 * (abs(value["loose"] - value["tight"]) + abs(value["fine"] - value["finer"]))
    assert abs(value["loose"] - value["finer"]) <= allowed + 1e-9, value
    # the ledger's residual at rtol 1e-9: at most 1000 steps' worth of the solver's
    # tolerance on the energies stored (their largest term)
    ledger = me.ledger(model, tight)
    scale = 1.0 + max(float(np.max(np.abs(tight[name]))) for name in MECHANISMS[model].ledger)
    assert abs(float(ledger[-1] - ledger[0])) <= 1e3 * 1e-9 * scale, ledger[-1] - ledger[0]


def test_engine_draws_the_energy_of_the_monolithic_reference() -> None:
    """demian2022 compensated: the Model Exchange engine (Radau over the FMU's derivatives) and
    the monolithic reference (Radau over the physics module, no FMU) solve the same ODE, the
    engine at rtol 1e-7, the reference at 1e-9: E_drawn, an integral of that solution, within
    10 rtol of each other (measured 5e-9 relative)."""
    scenario = scenarios.load("demian2022")
    variant = scenario.variant("compensated")
    engine = fmu_me.run(prepare(scenario, variant), rtol=1e-7).metrics["E_drawn"]
    monolithic = reference.run(prepare(scenario, variant)).metrics["E_drawn"]
    assert engine == pytest.approx(monolithic, rel=1e-6)


@pytest.mark.slow   # about 8 s: the engine at two tolerances, the master at two steps
def test_engine_draws_the_energy_of_the_master_within_its_coupling_error() -> None:
    """demian2022 compensated in the Model Exchange engine (scipy's Radau over the FMU and
    the drives' ODE) against the co-simulation master: E_drawn within twice the master's
    first-order error (its change from 2 ms to 1 ms) plus twice the engine's (its change
    from rtol to rtol / 10)."""
    scenario = scenarios.load("demian2022")
    variant = scenario.variant("compensated")
    drawn = {step: fmpy_master.run(prepare(scenario, variant, step)).metrics["E_drawn"]
             for step in (1e-3, 2e-3)}
    engine = {rtol: fmu_me.run(prepare(scenario, variant), rtol=rtol).metrics["E_drawn"]
              for rtol in (1e-7, 1e-8)}
    allowed = 2.0 * (abs(drawn[2e-3] - drawn[1e-3]) + abs(engine[1e-7] - engine[1e-8]))
    assert abs(engine[1e-8] - drawn[1e-3]) <= allowed, (engine, drawn)


def test_an_fmu_error_in_a_block_is_the_one_raised_not_the_refused_terminate() -> None:
    """A state refused (W_drive = inf) puts the instance in its error state, where
    fmi2Terminate is refused too: leaving the block raises the FMU's first refusal, with its
    own message, and the refused terminate only as a note."""
    with pytest.raises(FMUCallError, match="fmi2SetContinuousStates.*not finite") as failure:
        with ModelExchangeFMU(fmu_build.locate("SelfRegulatingBalancer")) as fmu:
            x = fmu.initialize({}, {}, 1.0)
            fmu.evaluate(0.0, np.full(len(x), np.inf), {})
    assert any("fmi2Terminate" in note for note in failure.value.__notes__)
