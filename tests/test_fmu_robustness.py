"""Hostile input to the FMUs: every call returns within a bounded amount of work, a step either
succeeds with finite outputs or is refused with the state unchanged, parameters cannot change
after initialisation, a restored state is validated, and every error names its cause."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from typing import Any

import pytest
from conftest import (
    FMI_ERROR,
    STEP_TIME_LIMIT,
    errors,
    failed_initialisation,
    open_fmu,
    refusal,
    refused_set,
    refused_step,
    resumed,
    serialized_state,
)
from fmpy import read_model_description
from pythonfmu.enums import Fmi2Status

from fmu_src.integration import (
    MAX_SUBSTEPS,
    STEP_RATE_PRODUCT,
    SubstepBoundError,
    substeps,
)
from fmu_src.mechanisms.self_regulating import physics as self_regulating
from fmu_src.mechanisms.self_regulating.SelfRegulatingBalancer import SelfRegulatingBalancer
from fmu_src.parameters import DomainError
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU, FMICallException

SRB, PRISMATIC, CIUPITU = "SelfRegulatingBalancer", "PrismaticCompensator", "CiupituBalancer"
DT = 1e-3


# ---- section 1: bounded work per step

def test_substeps_are_bounded() -> None:
    """The sub-step count is exact up to the bound, and refused past it (also for NaN/inf)."""
    assert substeps(1.0, 0.05 * MAX_SUBSTEPS) == MAX_SUBSTEPS
    for rate in (0.05 * MAX_SUBSTEPS * 1.001, math.inf, math.nan):
        with pytest.raises(SubstepBoundError, match="sub-steps"):
            substeps(1.0, rate)


def test_stiff_physics_is_refused_before_any_work() -> None:
    """J_link = 1e-300 would need ~1e296 sub-steps of 1 ms: refused at once."""
    p = self_regulating.Parameters(J_link=1e-300)
    start = time.perf_counter()
    with pytest.raises(SubstepBoundError):
        self_regulating.advance(p, self_regulating.Inputs(), self_regulating.initial_state(p),
                                DT)
    assert time.perf_counter() - start < 0.1


def test_huge_drive_torque_step_then_refusal_keeps_the_state() -> None:
    """tau_drive = 1e12 N m: the first step is fine (finite, 6.2e9 rad/s), the next one would
    need ~1e8 sub-steps and is refused quickly naming the rate and the speed; the state stays."""
    with open_fmu(fmu_build.fmu_path(SRB)) as fmu:
        fmu.set({"tau_drive": 1e12})
        fmu.step(0.0, DT)
        before = fmu.get(fmu.names("output"))
        assert before["omega"] == pytest.approx(1e12 / 0.16 * DT, rel=1e-3)
        message = refused_step(fmu, DT)
        assert "sub-steps" in message and "rate" in message and "omega = 6.2498e+09" in message
        assert fmu.get(fmu.names("output")) == before
        refused_step(fmu, DT)  # refused again: not NaN, not a hang


def test_massless_frictionless_released_slider_is_refused_by_name() -> None:
    """m_slider = 0 and d_slider = 0, slider released with the pulley locked: nothing sets the
    slider's motion (m v' = F - d v has no answer), so the step is refused naming both
    parameters, the state stays, and locking the slider again lets the run go on."""
    params = {"m_slider": 0.0, "d_slider": 0.0, "theta0": 2.0}
    with open_fmu(fmu_build.fmu_path(SRB), params) as fmu:
        before = fmu.get(fmu.names("output"))
        fmu.set({"slider_locked": False, "pulley_locked": True})
        message = refused_step(fmu)
        assert "m_slider = 0.0 kg with the pulley locked" in message
        assert "d_slider = 0.0 N.s/m" in message
        assert fmu.get(fmu.names("output")) == before
        fmu.set({"slider_locked": True})
        fmu.step(0.0, DT)
        assert fmu.get(["b"])["b"] == before["b"]


@pytest.mark.parametrize("parameters", [
    {"J_link": 1e-40}, {"d_link": 1e6}, {"k": 1e14}, {"m": 1e12, "c": 1e6},
], ids=["J_link=1e-40", "d_link=1e6", "k=1e14", "m c=1e18"])
def test_stiff_self_regulating_balancer_refuses_steps(parameters: dict[str, float]) -> None:
    with open_fmu(fmu_build.fmu_path(SRB), parameters) as fmu:
        before = fmu.get(fmu.names("output"))
        assert "sub-steps" in refused_step(fmu)
        assert fmu.get(fmu.names("output")) == before


def test_fast_initial_speed_at_the_bound_is_taken_and_past_it_refused() -> None:
    """omega0 = 1e6 rad/s at 1 ms needs exactly the bound of sub-steps (dt omega /
    STEP_RATE_PRODUCT = MAX_SUBSTEPS, integration.substeps): the step is taken within the time
    limit with finite outputs, the link spinning down by its viscous friction alone (omega =
    omega0 exp(-d_link dt / J_link); gravity's moment changes it by ~1e-8 of that), and 0.01 %
    faster the step is refused with Discard and the state unchanged; never a hang."""
    omega0 = STEP_RATE_PRODUCT * MAX_SUBSTEPS / DT
    assert omega0 == 1e6
    p = self_regulating.Parameters()
    decay = math.exp(-p.d_link * DT / (p.J_link + p.J_drive))
    with open_fmu(fmu_build.fmu_path(SRB), {"omega0": omega0}) as fmu:
        start = time.perf_counter()
        fmu.step(0.0, DT)
        assert time.perf_counter() - start < STEP_TIME_LIMIT
        out = fmu.get(fmu.names("output"))
    assert all(math.isfinite(value) for value in out.values()), out
    assert out["omega"] == pytest.approx(omega0 * decay, rel=1e-6)
    assert out["theta"] == pytest.approx(
        p.theta0 + omega0 * (1.0 - decay) * (p.J_link + p.J_drive) / p.d_link, rel=1e-6)
    with open_fmu(fmu_build.fmu_path(SRB), {"omega0": 1.0001 * omega0}) as fmu:
        before = fmu.get(fmu.names("output"))
        assert "sub-steps" in refused_step(fmu)
        assert fmu.get(fmu.names("output")) == before


# ---- section 6: no raw Python error, outputs finite or the step refused

@pytest.mark.parametrize(("model", "parameters", "named"), [
    (SRB, {"k": 1e300}, "k"), (SRB, {"m": 1e300}, "m"), (SRB, {"d_link": 1e300}, "d_link"),
    (SRB, {"L0": 1e300}, "L0"), (SRB, {"omega0": 1e300}, "omega0"), (SRB, {"w": 1e300}, "w"),
    (SRB, {"J_link": 0.0}, "J_link"), (SRB, {"J_link": 1e-300}, "J_link"),
    (SRB, {"g": 0.0}, "g"), (SRB, {"R": 5e-324}, "R"),
    (CIUPITU, {"AB": 1e300}, "AB"), (CIUPITU, {"c_fixed_cw": 1e300}, "c_fixed_cw"),
    (CIUPITU, {"omega0": 1e300}, "omega0"), (PRISMATIC, {"lc1": 1e300}, "lc1"),
    ("DcMotorDrive", {"N": 1e300}, "N"),
], ids=lambda value: str(value) if not isinstance(value, dict) else ",".join(value))
def test_extreme_parameters_are_refused_by_name(model: str, parameters: dict[str, float],
                                                named: str) -> None:
    """No OverflowError/ZeroDivisionError: an Error message starting with the parameter."""
    message = failed_initialisation(model, parameters)
    assert message.startswith(f"invalid parameter: {named} = ")
    assert "Error" not in message.split(":", 1)[1]  # no Python exception class name


def test_self_regulating_calculated_parameters_are_finite() -> None:
    """g = 0 used to give payload_max = inf (eq. 16 divides by g): g = 0 and g < 0 are refused
    at initialisation naming g and its range (0, inf), and the defaults and the smallest g
    accepted far from the 1e-50 floor (1e-30 m/s2, M0 and payload_max ~1e31 kg) give finite
    calculated parameters."""
    for g in (0.0, -9.81):
        assert failed_initialisation(SRB, {"g": g}) == (
            f"invalid parameter: g = {g} m/s2 is outside (0.0, inf)")
    for parameters in ({}, {"g": 1e-30}):
        with open_fmu(fmu_build.fmu_path(SRB), parameters) as fmu:
            values = fmu.get(["M0", "payload_max"])
        assert all(math.isfinite(v) and v > 0.0 for v in values.values()), (parameters, values)


def test_huge_prismatic_force_is_refused_not_infinite() -> None:
    """f2 = 1e300 N used to return OK with E_springs, E_kin, W_drive, W_worm inf or NaN; then
    it was refused at the next step; now fmi2SetReal refuses it and the outputs stay."""
    with open_fmu(fmu_build.fmu_path(PRISMATIC)) as fmu:
        before = fmu.get(fmu.names("output"))
        assert refused_set(fmu, {"f2": 1e300}) == (
            "input f2 = 1e+300 N is beyond the magnitude limit 1e+50 of these models "
            "(allowed [-inf, inf])")
        assert fmu.get(fmu.names("output")) == before


def test_huge_prismatic_torque_is_refused_and_the_state_survives() -> None:
    """tau1 = 1e300 used to Discard with only 'math domain error' and leave NaN for good."""
    with open_fmu(fmu_build.fmu_path(PRISMATIC)) as fmu:
        assert "input tau1 = 1e+300 N.m is beyond the magnitude limit" in refused_set(
            fmu, {"tau1": 1e300})
        fmu.step(0.0, DT)
        assert all(math.isfinite(v) for v in fmu.get(fmu.names("output")).values()
                   if not isinstance(v, bool))


def test_controller_subnormal_step_is_refused_and_recovers() -> None:
    """h = 5e-324 s used to leave V = NaN for good."""
    with open_fmu(fmu_build.fmu_path("PositionController"), {"theta_ref": 0.1}) as fmu:
        assert "output V would be nan" in refused_step(fmu, 0.0, 5e-324)
        fmu.step(0.0, DT)
        assert math.isfinite(fmu.get(["V"])["V"])


def test_step_before_initialisation_is_refused() -> None:
    """It used to be a Fatal AttributeError, then fmi2Discard from the slave; FMI 2.0 allows
    no step before initialisation: fmi2Error from the runtime's state machine."""
    fmu = CoSimFMU(fmu_build.fmu_path(SRB))
    try:
        with pytest.raises(FMICallException) as failure:
            fmu.step(0.0, DT)
        assert failure.value.status == FMI_ERROR
        assert errors(fmu)[-1].startswith("fmi2DoStep is not allowed in instantiated")
    finally:
        fmu.close()


# ---- section 4: parameters after initialisation, restored states

@pytest.mark.parametrize(("name", "value", "expected"), [
    ("k", -100.0, "k is a fixed parameter"), ("J_link", math.nan, "J_link is a fixed"),
    ("k", 2000.0, "k is a fixed parameter"), ("M0", 1.0, "M0 is a calculated parameter"),
])
def test_parameters_cannot_change_after_initialisation(name: str, value: float,
                                                       expected: str) -> None:
    """setReal on a fixed or calculated parameter is refused with fmi2Error and a message, and
    the value stays."""
    fmu = open_fmu(fmu_build.fmu_path(SRB))
    try:
        before = fmu.get([name])
        with pytest.raises(FMICallException) as failure:
            fmu.set({name: value})
        assert failure.value.status == FMI_ERROR and not fmu.fatal
        assert expected in refusal(errors(fmu)[-1], "fmi2SetReal")
        assert fmu.get([name]) == before
    finally:
        fmu.close()


def test_parameters_can_be_set_before_initialisation_exit() -> None:
    with open_fmu(fmu_build.fmu_path(SRB), {"k": 500.0}) as fmu:
        assert fmu.get(["k"])["k"] == 500.0


@pytest.mark.parametrize(("original", "replacement", "named"), [
    (b'"k": 981.0', b'"k": -5.0', "k = -5.0"),
    (b'"J_link": 0.16', b'"J_link": NaN', "J_link"),
])
def test_restored_state_is_validated(original: bytes, replacement: bytes, named: str) -> None:
    """A state whose parameters are out of range (here edited in its serialised form) is
    refused naming the variable, not taken into effect unchecked."""
    fmu = open_fmu(fmu_build.fmu_path(SRB))
    try:
        state = fmu.slave.getFMUstate()
        serialized = bytes(fmu.slave.serializeFMUstate(state))
        fmu.slave.freeFMUstate(state)
        assert original in serialized
        bad = fmu.slave.deSerializeFMUstate(serialized.replace(original, replacement))
        with resumed(fmu), pytest.raises(FMICallException):
            fmu.slave.setFMUstate(bad)
        fmu.slave.freeFMUstate(bad)
        assert named in errors(fmu)[-1] and "FMU state refused" in errors(fmu)[-1]
    finally:
        fmu.close()


def test_bad_input_in_a_restored_state_is_refused() -> None:
    """Inputs are checked when set, and a restored state's inputs the same way: payload =
    -1 kg written into a serialised state is refused by fmi2SetFMUstate naming payload (it
    used to be taken and the next step refused), and the instance steps on as before."""
    with open_fmu(fmu_build.fmu_path(SRB), {"omega0": 1.0}) as fmu:
        message = refused_state(fmu, lambda s: {**s, "payload": -1.0})
        assert message == "FMU state refused: input payload = -1.0 kg is outside [0.0, inf]"
        before = fmu.get(["theta"])
        fmu.step(0.0, DT)
        assert fmu.get(["theta"])["theta"] == pytest.approx(before["theta"] + DT, abs=1e-5)


def slave_json(fmu: CoSimFMU) -> dict[str, Any]:
    """The slave's part of a serialised FMU state of the instance now: its JSON, decoded."""
    return json.loads(serialized_state(fmu)[2])


def refused_state(fmu: CoSimFMU, doctor: Callable[[dict[str, Any]], dict[str, Any]],
                  body: dict[str, Any] | None = None) -> str:
    """Serialise the instance's state, doctor its JSON (or use body, another FMU's), and set
    it: fmi2SetFMUstate must return fmi2Error (not Fatal) with one Error message and change
    no variable (`resumed`: nor the slave's state); the slave's words in that message."""
    header, machine, own = serialized_state(fmu)
    variables = [v.name for v in fmu.model_description.modelVariables
                 if v.type in ("Real", "Boolean", "String")]  # CoSimFMU reads no Integer
    before = fmu.get(variables)
    text = json.dumps(doctor(json.loads(own) if body is None else body)).encode()
    bad = fmu.slave.deSerializeFMUstate(b"\n".join((header, machine, text)))
    logged = len(fmu.messages)
    try:
        with resumed(fmu), pytest.raises(FMICallException) as failure:
            fmu.slave.setFMUstate(bad)
    finally:
        fmu.slave.freeFMUstate(bad)
    assert failure.value.status == FMI_ERROR
    (message,) = [m.message for m in fmu.messages[logged:] if m.status == "Error"]
    assert fmu.get(variables) == before
    return refusal(message, "fmi2SetFMUstate")


def test_state_of_another_model_is_refused() -> None:
    """A CiupituBalancer state (its JSON behind the PrismaticCompensator's header, so the
    runtime's GUID check passes) used to be taken: c went from 0.4 to 0.2, m2 from 0.5 to
    0.75. Now it is refused naming both models, and nothing changes."""
    with open_fmu(fmu_build.fmu_path(CIUPITU)) as ciupitu:
        ciupitu.step(0.0, DT)
        body = slave_json(ciupitu)
    with open_fmu(fmu_build.fmu_path(PRISMATIC)) as fmu:
        message = refused_state(fmu, lambda s: s, body)
        assert message == "FMU state refused: made by model 'CiupituBalancer', not " \
                          "PrismaticCompensator"


def test_state_of_another_layout_is_refused() -> None:
    """A state of another version of the model (other variables or hidden state) is refused."""
    with open_fmu(fmu_build.fmu_path(SRB)) as fmu:
        message = refused_state(fmu, lambda s: {**s, "__layout__": "0123456789abcdef"})
        assert message.startswith("FMU state refused: layout '0123456789abcdef' is not this "
                                  "SelfRegulatingBalancer's")
        assert "another version" in message


def hidden(name: str, value: Any) -> Callable[[dict[str, Any]], dict[str, Any]]:
    """A doctor of a state that sets one of its hidden values (a function of the old one)."""
    def doctor(state: dict[str, Any]) -> dict[str, Any]:
        old = state["__hidden__"]
        return {**state, "__hidden__": {**old, name: value(old[name])}}
    return doctor


@pytest.mark.parametrize(("doctor", "named"), [
    # one element short: restored, the ledger's last field (E_added) became 0
    (hidden("state", lambda s: s[:-1]), "hidden state state = "),
    (hidden("state", lambda s: [*s, 0.0]), "hidden state state = "),
    (hidden("previous_inputs", lambda u: [*u[:3], "false", u[4]]),
     "hidden state previous_inputs = "),
    (hidden("stop_reported", lambda _: "false"), "hidden state stop_reported = 'false'"),
    (hidden("state", lambda s: ["1.0", *s[1:]]), "hidden state state = ['1.0'"),
    (hidden("state", lambda s: [*s[:5], 1e400, *s[6:]]), "is not finite"),
    (lambda s: {**s, "slider_locked": "false"},
     "slider_locked = 'false' is not of type Boolean"),  # restored as True
    (lambda s: {**s, "k": "981.0"}, "k = '981.0' is not of type Real"),
    (lambda s: {**s, "payload": None}, "payload = None is not of type Real"),
    (lambda s: {**s, "k": True}, "k = True is not of type Real"),
    (lambda s: {name: v for name, v in s.items() if name != "theta"}, "theta is missing"),
    (lambda s: {**s, "E_cw2": 0.0}, "E_cw2 is not a variable of SelfRegulatingBalancer"),
    (lambda s: {**s, "__hidden__": None}, "hidden state None does not hold"),
], ids=["state-short", "state-long", "bool-as-string-hidden", "flag-as-string",
        "string-for-number-hidden", "huge-hidden", "bool-as-string", "string-for-number",
        "null-for-number", "bool-for-number", "missing", "extra", "no-hidden"])
def test_doctored_state_is_refused(doctor: Callable[[dict[str, Any]], dict[str, Any]],
                                   named: str) -> None:
    """Doctored serialised states are refused naming what is wrong, and change nothing; the
    instance steps on from its own state (1 rad/s carries theta DT further)."""
    with open_fmu(fmu_build.fmu_path(SRB), {"omega0": 1.0}) as fmu:
        fmu.step(0.0, DT)
        message = refused_state(fmu, doctor)
        assert message.startswith("FMU state refused: ") and named in message, message
        before = fmu.get(["theta"])["theta"]
        fmu.step(DT, DT)
        assert fmu.get(["theta"])["theta"] == pytest.approx(before + DT, abs=1e-5)


@pytest.mark.parametrize(("doctor", "named"), [
    (lambda s: {**s, "variant_number": 99}, "variant_number = 99 is outside [0, "),
    (lambda s: {**s, "variant_number": -1}, "variant_number = -1 is outside [0, "),
    (lambda s: {**s, "variant_number": None}, "variant_number = None is not of type Integer"),
    (lambda s: {**s, "variant_number": 1.5}, "variant_number = 1.5 is not of type Integer"),
    (lambda s: {**s, "variant": None}, "variant = None is not of type String"),
    (lambda s: {**s, "variant": "no_such_variant"}, "no variant 'no_such_variant'"),
], ids=["number-high", "number-negative", "number-null", "number-float", "name-null",
        "name-unknown"])
def test_doctored_sequencer_state_is_refused(doctor: Callable[[dict[str, Any]], dict[str, Any]],
                                             named: str) -> None:
    """A sequencer state with its variant outside the choices or null is refused, and the
    sequencer plays on as before (a second one playing the same variant agrees)."""
    path = fmu_build.fmu_path("ScenarioSequencer")
    with open_fmu(path) as fmu, \
            open_fmu(path) as untouched:
        message = refused_state(fmu, doctor)
        assert named in message, message
        for fmu_ in (fmu, untouched):
            fmu_.step(0.0, 3.0)
        outputs = fmu.names("output")
        assert fmu.get(outputs) == untouched.get(outputs)


# ---- setting outputs

def output_cases() -> list[tuple[str, str]]:
    """(model, output) for every output of every FMU."""
    return [(model, v.name) for model in fmu_build.MODELS
            for v in read_model_description(str(fmu_build.fmu_path(model))).modelVariables
            if v.causality == "output"]


@pytest.mark.parametrize(("model", "name"), output_cases())
def test_outputs_cannot_be_set(model: str, name: str) -> None:
    """fmi2SetReal (fmi2SetBoolean) on an output used to return OK in DcMotorDrive,
    PositionController and ScenarioSequencer: E_in = 1e6 went on accumulating from 1e6, V = 999
    read back above V_supply. FMI 2.0 lets a host set only inputs and parameters: fmi2Error
    naming the output, and the value stays."""
    with open_fmu(fmu_build.fmu_path(model)) as fmu:
        kind = fmu.variables[name].type
        value = {"Real": 999.0, "Boolean": not fmu.get([name])[name]}[kind]
        message = refused_set(fmu, {name: value}, f"fmi2Set{kind}")
        assert message.startswith(f"{name} = {value!r} refused: {name} is of causality output")


def test_refused_output_set_leaves_the_energy_count() -> None:
    """DcMotorDrive E_in after a refused E_in = 1e6: the same as an instance never given it."""
    path = fmu_build.fmu_path("DcMotorDrive")
    with open_fmu(path, {"V": 6.0}) as fmu, open_fmu(path, {"V": 6.0}) as untouched:
        refused_set(fmu, {"E_in": 1e6})
        for fmu_ in (fmu, untouched):
            fmu_.step(0.0, DT)
        E_in = fmu.get(["E_in"])["E_in"]
        assert E_in == untouched.get(["E_in"])["E_in"] and 0.0 < E_in < 1.0


# ---- only the physics' own refusals become fmi2Discard

def python_instance() -> SelfRegulatingBalancer:
    """A SelfRegulatingBalancer slave in this process (no FMU), initialised at omega0 = 1."""
    slave = SelfRegulatingBalancer(instance_name="python")
    slave.omega0 = 1.0
    slave.setup_experiment(0.0, None, None)
    slave.exit_initialization_mode()
    return slave


@pytest.mark.parametrize("defect", [
    TypeError("unsupported operand"), KeyError("theta"),
    ValueError("tuple.index(x): x not in tuple"),  # a ValueError, not a physics refusal
], ids=["TypeError", "KeyError", "ValueError"])
def test_a_defect_in_a_step_is_not_a_discard(monkeypatch: pytest.MonkeyPatch,
                                              defect: Exception) -> None:
    """do_step used to turn every ValueError, programming errors included, into fmi2Discard
    (False). Now only the physics' refusals (DomainError) and failed arithmetic do: any other
    exception propagates (the runtime returns fmi2Error naming its type), the state kept."""
    slave = python_instance()
    before = slave.state

    def broken(dt: float) -> None:
        slave.state = slave.state._replace(theta=0.0)  # half done
        raise defect

    monkeypatch.setattr(slave, "step", broken)
    with pytest.raises(type(defect)):
        slave.do_step(0.0, DT)
    assert slave.state == before


@pytest.mark.parametrize("refusal_", [
    DomainError("the released slider has neither mass nor damping"),
    ValueError("math domain error"), ZeroDivisionError("float division by zero"),
], ids=["DomainError", "math-domain", "ZeroDivisionError"])
def test_a_physics_refusal_is_a_discard(monkeypatch: pytest.MonkeyPatch,
                                         refusal_: Exception) -> None:
    """The physics' own refusals and failed arithmetic refuse the step (False: fmi2Discard),
    logging one Error message, with the state as it was."""
    slave = python_instance()
    before = slave.state

    def refused(dt: float) -> None:
        slave.state = slave.state._replace(theta=0.0)
        raise refusal_

    monkeypatch.setattr(slave, "step", refused)
    assert slave.do_step(0.0, DT) is False
    assert slave.state == before
    (logged,) = [m for m in slave.log_queue if m.status == Fmi2Status.error]
    assert "refused, state unchanged" in logged.msg


def test_substep_bound_and_slider_refusals_are_domain_errors() -> None:
    """The refusals of the physics modules are DomainErrors (so they stay fmi2Discard)."""
    assert issubclass(SubstepBoundError, DomainError)
    p = self_regulating.Parameters(m_slider=0.0, d_slider=0.0)
    u = self_regulating.Inputs(slider_locked=False)
    with pytest.raises(DomainError, match="m_slider"):
        self_regulating.advance(p, u, self_regulating.initial_state(p), DT)


# ---- section 9: per-instance growth that is ours

def test_instances_leave_sys_path_as_it_was() -> None:
    """pythonfmu's runtime adds the resources folder to sys.path at every instantiation
    (200 entries after 200 instances, most of them deleted folders); the slaves take it out."""
    import sys

    path = fmu_build.fmu_path(SRB)
    CoSimFMU(path).close()  # modules imported, build checked
    before = list(sys.path)
    for _ in range(5):
        fmu = CoSimFMU(path)
        fmu.initialize()
        fmu.step(0.0, DT)
        fmu.close()
    assert sys.path == before
