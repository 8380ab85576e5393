"""Hostile input to the FMUs: every call returns within a bounded amount of work, a step either
succeeds with finite outputs or is refused with the state unchanged, parameters cannot change
after initialisation, a restored state is validated, and every error names its cause."""

from __future__ import annotations

import math
import time

import pytest
from conftest import (
    FMI_DISCARD,
    FMI_ERROR,
    STEP_TIME_LIMIT,
    errors,
    failed_initialisation,
    open_fmu,
    refusal,
    refused_step,
)

from fmu_src import self_regulating
from fmu_src.integration import MAX_SUBSTEPS, SubstepBoundError, substeps
from harness import fmu_build
from harness.fmi import CoSimFMU, FMICallException

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


def test_fast_initial_speed_costs_at_most_the_bound() -> None:
    """omega0 = 1e6 rad/s: the step is either taken within the bound or refused; never a hang."""
    with open_fmu(fmu_build.fmu_path(SRB), {"omega0": 1e6}) as fmu:
        start = time.perf_counter()
        try:
            fmu.step(0.0, DT)
        except FMICallException as failure:
            assert failure.value.status == FMI_DISCARD
        assert time.perf_counter() - start < STEP_TIME_LIMIT


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
    """g = 0 used to give payload_max = inf: g must be positive now, and the defaults finite."""
    with open_fmu(fmu_build.fmu_path(SRB)) as fmu:
        assert all(math.isfinite(v) for v in fmu.get(["M0", "payload_max"]).values())


def test_huge_prismatic_force_is_refused_not_infinite() -> None:
    """f2 = 1e300 N used to return OK with E_springs, E_kin, W_drive, W_worm inf or NaN."""
    with open_fmu(fmu_build.fmu_path(PRISMATIC)) as fmu:
        before = fmu.get(fmu.names("output"))
        fmu.set({"f2": 1e300})
        assert "input f2 = 1e+300 N is beyond the magnitude limit" in refused_step(fmu)
        assert fmu.get(fmu.names("output")) == before


def test_huge_prismatic_torque_is_refused_and_the_state_survives() -> None:
    """tau1 = 1e300 used to Discard with only 'math domain error' and leave NaN for good."""
    with open_fmu(fmu_build.fmu_path(PRISMATIC)) as fmu:
        fmu.set({"tau1": 1e300})
        message = refused_step(fmu)
        assert "input tau1 = 1e+300 N.m is beyond the magnitude limit" in message
        fmu.set({"tau1": 0.0})
        fmu.step(0.0, DT)
        assert all(math.isfinite(v) for v in fmu.get(fmu.names("output")).values()
                   if not isinstance(v, bool))


def test_controller_subnormal_step_is_refused_and_recovers() -> None:
    """h = 5e-324 s used to leave V = NaN for good."""
    with open_fmu(fmu_build.fmu_path("PositionController"), {"theta_ref": 0.1}) as fmu:
        assert "output V would be nan" in refused_step(fmu, 0.0, 5e-324)
        fmu.step(0.0, DT)
        assert math.isfinite(fmu.get(["V"])["V"])


@pytest.mark.parametrize("time_point", [math.nan, -1.0, math.inf])
def test_bad_communication_point_is_refused(time_point: float) -> None:
    with open_fmu(fmu_build.fmu_path(SRB)) as fmu:
        assert "communication point" in refused_step(fmu, time_point)


def test_step_before_initialisation_is_refused() -> None:
    """It used to be a Fatal AttributeError."""
    fmu = CoSimFMU(fmu_build.fmu_path(SRB))
    try:
        assert "before initialisation" in refused_step(fmu)
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
        with pytest.raises(FMICallException):
            fmu.slave.setFMUstate(bad)
        fmu.fatal = True
        assert named in errors(fmu)[-1] and "FMU state refused" in errors(fmu)[-1]
    finally:
        fmu.close()


def test_bad_input_in_a_restored_state_is_refused_at_the_next_step() -> None:
    """Inputs are checked when set; a restored state sets them directly, so the step after
    it checks them again: payload = -1 kg saved in a state, a good payload stepped with in
    between, the restored state's step is refused naming payload and leaves theta as it was
    (1 rad/s then carries it DT further)."""
    with open_fmu(fmu_build.fmu_path(SRB), {"omega0": 1.0}) as fmu:
        fmu.set({"payload": -1.0})
        state = fmu.slave.getFMUstate()
        fmu.set({"payload": 0.5})
        fmu.step(0.0, DT)
        fmu.slave.setFMUstate(state)
        fmu.slave.freeFMUstate(state)
        before = fmu.get(["theta"])
        assert "input payload = -1.0 kg is outside [0.0, inf]" in refused_step(fmu)
        assert fmu.get(["theta"]) == before
        fmu.set({"payload": 0.0})  # the restored state's own payload: no event
        fmu.step(0.0, DT)
        assert fmu.get(["theta"])["theta"] == pytest.approx(before["theta"] + DT, abs=1e-5)


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
