"""One mechanism interface (docs/adding_a_mechanism.md): every physics module meets
`fmu_src.mechanism.Physics`, no harness module names a mechanism but through the
registrations, and a mechanism added as its own two files is found, built, documented and
wired by the harness without any other edit."""

from __future__ import annotations

import ast
import inspect
import math
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from conftest import open_fmu, run
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from fmu_src import mechanism
from fmu_src.mechanisms.prismatic import physics as prismatic
from harness import registry, scenarios
from harness.bench import steps as bench_steps
from harness.engines import reference
from harness.engines.plan import physics_module, prepare
from harness.fmu import build as fmu_build
from harness.fmu import docs as fmu_docs
from harness.fmu import osp

HARNESS = Path(registry.__file__).resolve().parent
# the harness's room of the mechanisms' own design tools, which may name their mechanism
DESIGN_TOOLS = HARNESS / "design"
SCRATCH = Path(__file__).resolve().parent / "data" / "scratch_mechanism"
SCRATCH_MODEL = "ScratchPendulum"
POSITIONAL = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)


def protocol_problems(physics: Any) -> list[str]:
    """How a physics module falls short of mechanism.Physics: a missing attribute, or a
    function that does not take the protocol's arguments in its order (further arguments
    must be optional)."""
    problems = [f"no {name}" for name in mechanism.Physics.__annotations__
                if not hasattr(physics, name)]
    for name, member in vars(mechanism.Physics).items():
        if not inspect.isfunction(member) or name.startswith("_"):
            continue
        expected = list(inspect.signature(member).parameters.values())[1:]  # without self
        function = getattr(physics, name, None)
        if not callable(function):
            problems.append(f"no function {name}")
            continue
        actual = list(inspect.signature(function).parameters.values())
        if (len(actual) < len(expected)
                or any(a.kind not in POSITIONAL or (a.default is a.empty) != (e.default is e.empty)
                       for a, e in zip(actual, expected))
                or any(a.default is a.empty for a in actual[len(expected):])):
            problems.append(f"{name}{inspect.signature(function)} does not take "
                            f"({', '.join(str(e) for e in expected)})")
    return problems


MECHANISMS = registry.mechanisms()


@pytest.mark.parametrize("model", MECHANISMS)
def test_every_physics_module_meets_the_protocol(model: str) -> None:
    assert protocol_problems(MECHANISMS[model].physics) == []


def test_the_protocol_check_refuses_a_drifted_signature() -> None:
    """The signatures the modules had drifted to: characteristic_rate(p, s) and
    derivatives(p, u, s, direction) with direction required."""
    def rate_without_inputs(p: Any, s: Any) -> float:
        return 1.0

    def derivatives_with_a_required_extra(p: Any, u: Any, s: Any, direction: float) -> Any:
        return s

    assert protocol_problems(prismatic) == []
    drifted = SimpleNamespace(**vars(prismatic))
    drifted.characteristic_rate = rate_without_inputs
    drifted.derivatives = derivatives_with_a_required_extra
    del drifted.EVENT_INPUTS
    problems = protocol_problems(drifted)
    assert problems[0] == "no EVENT_INPUTS"
    assert [p.split("(")[0] for p in problems[1:]] == ["derivatives", "characteristic_rate"]


def _signed_sum(ledger: dict[str, int], values: Any) -> float:
    return sum(sign * getattr(values, name) for name, sign in ledger.items())


@pytest.mark.parametrize("model", MECHANISMS)
def test_every_physics_module_behaves_as_the_protocol_says(model: str) -> None:
    """From the registration's moving run: derivatives is a State, the rate positive, advance
    and switch_inputs give States, the ledger's terms are outputs and their signed sum stays
    constant (1e-9 of the work moved) over 0.5 s while the mechanism moves."""
    found = MECHANISMS[model]
    physics = found.physics
    p = physics.Parameters(**found.moving_run.parameters)
    physics.validate(p)
    u = physics.Inputs(**{k: v for k, v in found.moving_run.inputs.items()
                          if k in physics.Inputs._fields})
    assert set(physics.EVENT_INPUTS) <= set(physics.Inputs._fields)
    s = physics.initial_state(p)
    assert type(physics.derivatives(p, u, s)) is physics.State
    rate = physics.characteristic_rate(p, u, s)
    assert math.isfinite(rate) and rate > 0.0
    assert type(physics.switch_inputs(p, u, u, s)) is physics.State
    assert set(found.ledger) <= set(physics.Outputs._fields) and found.ledger
    start = physics.outputs(p, u, s)
    for _ in range(500):
        s = physics.advance(p, u, s, 1e-3)
    assert type(s) is physics.State
    end = physics.outputs(p, u, s)
    moved = sum(abs(getattr(end, n) - getattr(start, n)) for n in found.ledger)
    assert moved > 0.01
    assert _signed_sum(found.ledger, end) == pytest.approx(_signed_sum(found.ledger, start),
                                                           abs=1e-9 * moved)


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_every_registration_is_complete(model: str) -> None:
    """Every FMU has dependency probes and a moving run the C host can set (Reals only); a
    mechanism has joints, each a port with its position."""
    found = registry.registration(model)
    assert found.dependency_probes
    values = {**found.moving_run.parameters, **found.moving_run.inputs}
    assert not any(isinstance(v, bool) for v in values.values())
    assert bool(found.joints()) == (found.physics is not None)


def names_used(source: str) -> set[str]:
    """The names a module's source gives that could be a mechanism's or one of its outputs':
    its string constants (`row["W_adjust"]` included), the attributes it reads
    (`settled.delta_b`, `ideal.E_drawn.self_regulating`) and the keyword arguments it passes
    (`Parameters(l_s=...)`). The names it binds itself (variables, arguments) are its own."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            found.add(node.value)
        elif isinstance(node, ast.Attribute):
            found.add(node.attr)
        elif isinstance(node, ast.keyword) and node.arg is not None:
            found.add(node.arg)
    return found


# Names outside the mechanisms' folders that are a mechanism's name by the rule below but
# mean something else or are not derived yet, each with its reason:
NOT_A_MECHANISM_NAME = {
    # a sweep file's plot role (its x axis), not SelfRegulatingBalancer's spring length x
    "sweeps/definition.py": {"x"}, "sweeps/plots.py": {"x"},
    # matplotlib's Axes.margins(x=...), the plot's horizontal margin
    "study/plots.py": {"x"},
    # the scenario format's default joint: the one-link mechanisms' common names
    "units/sequencer/scenario.py": {"tau_gravity"},
}


@pytest.fixture(scope="module")
def mechanism_names() -> set[str]:
    """The mechanisms' model names and the outputs that not every mechanism has (and that
    are no variable of the drive, the controller or the sequencer, as their FMUs declare
    them)."""
    outputs = [set(r.physics.Outputs._fields) for r in MECHANISMS.values()]
    units = {var.name for model in set(fmu_build.MODELS) - set(MECHANISMS)
             for var in read_model_description(fmu_build.fmu_path(model)).modelVariables}
    return {*MECHANISMS, *(set().union(*outputs) - set.intersection(*outputs) - units)}


def test_no_harness_or_shared_module_names_a_mechanism(mechanism_names: set[str]) -> None:
    """The harness and the FMUs' shared modules reach the mechanisms through their
    registrations alone: no harness module (its design tools aside) and no fmu_src module
    outside fmu_src/mechanisms gives a mechanism's name (names_used) but those of
    NOT_A_MECHANISM_NAME."""
    assert len(MECHANISMS) >= 5
    assert {"W_adjust", "delta_b", "OB", "Y_cw", "l_s", "q"} <= mechanism_names
    source = registry.SOURCE_DIR
    shared = [p for p in sorted(source.rglob("*.py"))
              if p.relative_to(source).parts[0] != "mechanisms"]
    assert {"fmi/slave.py", "units/sequencer/ScenarioSequencer.py", "integration.py"} <= {
        p.relative_to(source).as_posix() for p in shared}
    named = {}
    for root, paths in ((HARNESS, sorted(HARNESS.rglob("*.py"))), (source, shared)):
        for path in paths:
            if DESIGN_TOOLS not in path.parents:
                where = path.relative_to(root).as_posix()
                allowed = NOT_A_MECHANISM_NAME.get(where, set())
                if found := (names_used(path.read_text()) & mechanism_names) - allowed:
                    named[where] = sorted(found)
    assert not named


def test_the_name_check_sees_attribute_reads_keywords_and_subscripts(
        mechanism_names: set[str]) -> None:
    """A sentence built the way the report's code once built them (a recorded row's output
    read as an attribute, a summary's variant column, a parameter passed by keyword, an
    output looked up by its string) is caught, with its own variables left alone."""
    source = """
def sentence(results, ideal, physics):
    q = results.at("active_relocation", 17.0)
    settled = physics.Parameters(l_s=0.1)
    return f"{q.delta_b - settled.W_adjust} {ideal.E_drawn.self_regulating} {q['Y_cw']}"
"""
    assert names_used(source) & mechanism_names == {"delta_b", "W_adjust", "l_s", "Y_cw"}


@pytest.fixture
def scratch_source(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A copy of fmu_src with the scratch mechanism's folder (its physics module and slave
    script) added, first on the import path and the registry's source tree."""
    registry.mechanisms()  # the real modules imported first, from the source tree
    source = tmp_path / "src" / "fmu_src"
    shutil.copytree(registry.SOURCE_DIR, source, ignore=shutil.ignore_patterns("__pycache__"))
    folder = source / "mechanisms" / "pendulum"
    folder.mkdir()
    for path in SCRATCH.glob("*.py"):
        shutil.copy(path, folder)
    monkeypatch.syspath_prepend(str(source.parent))
    monkeypatch.setattr(registry, "SOURCE_DIR", source)
    yield source
    for name, module in list(sys.modules.items()):
        if str(getattr(module, "__file__", "")).startswith(str(tmp_path)):
            del sys.modules[name]


def test_a_mechanism_added_as_its_own_files_is_wired_by_the_harness(
        scratch_source: Path) -> None:
    """Discovery, the monolithic reference, the OSP ports, the documented run, the bench's
    step loop and the FMU's modules of the scratch mechanism, with no edit elsewhere."""
    models = registry.models(scratch_source)
    assert set(models) == {*fmu_build.MODELS, SCRATCH_MODEL}
    assert SCRATCH_MODEL in registry.mechanisms(scratch_source)
    assert (physics_module(SCRATCH_MODEL).__name__
            == "fmu_src.mechanisms.pendulum.physics")
    (joint,) = osp.model_groups(SCRATCH_MODEL)
    assert (joint.kind, [m.variables for m in joint.members]) == (
        "AngularMechanicalPort", [("tau_drive",), ("omega",)])
    run_ = fmu_docs.reference_run(SCRATCH_MODEL)
    assert run_.inputs.dtype.names == ("time", "tau_drive")
    assert max(run_.inputs["tau_drive"]) == 0.5 and run_.inputs["time"][-1] == 5.0
    loop = bench_steps.mechanism_loop(SCRATCH_MODEL, registry.registration(SCRATCH_MODEL).joints())
    assert (loop.input, loop.outputs) == ("tau_drive", ("theta", "omega"))
    assert {p.relative_to(scratch_source).as_posix()
            for p in fmu_build.dependencies(SCRATCH_MODEL, scratch_source)} == {
        "mechanisms/pendulum/physics.py", "fmi/mechanism_slave.py", "fmi/slave.py",
        "fmi/state.py", "fmi/variables.py", "fmi/failures.py", "fmi/model_description.py",
        "fmi/model_exchange.py", "fmi/vocabulary.py", "fmi/binding.py", "fmi/fmi2/slave.py",
        "fmi/fmi2/model_description.py",
        "integration.py", "mechanism.py", "parameters.py"}


def test_the_monolithic_reference_runs_the_added_mechanism(scratch_source: Path) -> None:
    """The scratch scenario (the frictionless pendulum lifted from hanging to horizontal and
    held) in the monolithic reference: the drive's work on the link is the potential energy
    it gained, m g l (1 - cos theta_end), and it ends at the target."""
    scenario = scenarios.load(SCRATCH / "scratch_swing.toml")
    result = reference.run(prepare(scenario, scenario.variant("pendulum")))
    assert result.series.time.iloc[-1] == pytest.approx(scenario.duration, abs=1e-12)
    theta_end = result.series[scenario.joints[0].position].iloc[-1]
    assert theta_end == pytest.approx(math.pi / 2, abs=1e-8)
    lifted = 1.0 * 9.81 * 0.5 * (1.0 - math.cos(theta_end))
    assert result.metrics["W_link"] == pytest.approx(lifted, rel=1e-9)


def test_the_added_mechanism_builds_into_a_valid_fmu(scratch_source: Path,
                                                     tmp_path: Path) -> None:
    """The build of the scratch mechanism passes FMPy's validation, writes its OSP interface,
    and the FMU swings as a pendulum from 1 rad with its ledger closed (E_p + E_kin + E_loss
    - W_drive stays at E_p at the start)."""
    fmu = fmu_build.build(SCRATCH_MODEL, tmp_path / "fmus", source_dir=scratch_source)
    assert validate_fmu(str(fmu)) == []
    assert (fmu.parent / f"{SCRATCH_MODEL}{osp.SUFFIX}").is_file()
    ledger = registry.registration(SCRATCH_MODEL).ledger
    with open_fmu(fmu, {"theta0": 1.0}) as instance:
        names = ("theta", *ledger)
        rows = run(instance, 2000, 1e-3, names)
    theta = rows[:, 0]
    residual = rows[:, 1:] @ [ledger[n] for n in names[1:]]
    start = -1.0 * 9.81 * 0.5 * math.cos(1.0)  # E_p at theta0, E_kin 0
    assert theta.min() < -0.9 and theta.max() <= 1.0
    assert residual == pytest.approx(start, abs=1e-9)
