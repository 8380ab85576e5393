"""The FMU variables a physics module declares (`fmu_src.mechanism.input_variables`,
`output_variables`): one per field of its Inputs and Outputs, checked at import, and the
slave registers exactly them."""

from __future__ import annotations

import typing
from typing import NamedTuple

import pytest

from fmu_src.mechanism import input_variables, output_variables, variable
from harness import registry

MECHANISMS = registry.mechanisms()


class _Inputs(NamedTuple):
    force: float = 0.0
    locked: bool = True


class _Outputs(NamedTuple):
    x: float
    v: float


def test_every_mechanism_is_covered() -> None:
    assert set(MECHANISMS) == {"SelfRegulatingBalancer", "ActiveSpringBalancer",
                               "CiupituBalancer", "RockingCounterweightBalancer",
                               "PrismaticCompensator"}


@pytest.mark.parametrize("model", sorted(MECHANISMS))
def test_declarations_follow_the_named_tuples(model: str) -> None:
    """One variable per field, in field order, each input starting at its field's default,
    and a Boolean (unit None) exactly where the field is a bool."""
    physics = MECHANISMS[model].physics
    for declared, fields_of in ((physics.INPUT_VARIABLES, physics.Inputs),
                                (physics.OUTPUT_VARIABLES, physics.Outputs)):
        assert tuple(v.name for v in declared) == fields_of._fields
        hints = typing.get_type_hints(fields_of)
        assert [v.name for v in declared if v.unit is None] == [
            name for name in fields_of._fields if hints[name] is bool]
    assert [v.start for v in physics.INPUT_VARIABLES] == list(physics.Inputs._field_defaults
                                                               .values())
    for v in physics.OUTPUT_VARIABLES:
        assert set(v.depends_on) <= set(physics.Inputs._fields), v.name


@pytest.mark.parametrize("model", sorted(MECHANISMS))
def test_the_slave_registers_the_declared_variables(model: str) -> None:
    """The FMU's inputs and outputs are the declared ones, with their units and
    dependencies."""
    physics = MECHANISMS[model].physics
    slave = registry._instance(model)
    for v in (*physics.INPUT_VARIABLES, *physics.OUTPUT_VARIABLES):
        info = slave.info[v.name]
        assert (info.unit, info.description) == (v.unit, v.description), v.name
    assert {v.name: v.depends_on for v in physics.OUTPUT_VARIABLES} == slave.dependencies
    assert slave.output_names == list(physics.Outputs._fields)


def test_a_missing_or_extra_field_is_refused() -> None:
    with pytest.raises(TypeError, match=r"missing: locked; not fields: -"):
        input_variables(_Inputs, force=variable("N", "Force"))
    with pytest.raises(TypeError, match=r"missing: -; not fields: a"):
        output_variables(_Outputs, _Inputs, x=variable("m", "Position"),
                         v=variable("m/s", "Speed"), a=variable("m/s2", "Acceleration"))


def test_fields_out_of_order_are_refused() -> None:
    with pytest.raises(TypeError, match=r"must declare its fields x, v in this order"):
        output_variables(_Outputs, _Inputs, v=variable("m/s", "Speed"),
                         x=variable("m", "Position"))


def test_a_dependency_on_no_input_is_refused() -> None:
    with pytest.raises(TypeError, match=r"v on torque"):
        output_variables(_Outputs, _Inputs, x=variable("m", "Position"),
                         v=variable("m/s", "Speed", depends_on=("torque",)))
    with pytest.raises(TypeError, match=r"inputs force .* declare depends_on"):
        input_variables(_Inputs, force=variable("N", "Force", depends_on=("locked",)),
                        locked=variable(None, "Locked"))


def test_inputs_start_at_their_defaults() -> None:
    force, locked = input_variables(_Inputs, force=variable("N", "Force", min=0.0),
                                    locked=variable(None, "Locked"))
    assert (force.name, force.start, force.min) == ("force", 0.0, 0.0)
    assert (locked.name, locked.start, locked.unit) == ("locked", True, None)
