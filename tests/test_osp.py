"""The OSP interface specification of the FMUs (harness.fmu.osp): `<Model>_OspModelDescription.xml`
valid against the OSP-IS 1.0.1 schema (tests/data/osp, see SOURCE.md there), written beside
each FMU by the build, with ports whose units and causalities are those of their quantity."""

from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import read_model_description
from lxml import etree

from harness import scenarios
from harness.fmu import build as fmu_build
from harness.fmu import osp

SCHEMA = Path(__file__).parent / "data" / "osp" / "OspModelDescription-1.0.1.xsd"
NS = {"osp": osp.NAMESPACE}
# SI base-unit exponents (kg, m, s, A, rad) of each quantity, from the definitions of the units
DIMENSIONS = {"Torque": (1, 2, -2, 0, 0), "AngularVelocity": (0, 0, -1, 0, 1),
              "Force": (1, 1, -2, 0, 0), "LinearVelocity": (0, 1, -1, 0, 0),
              "Voltage": (1, 2, -3, -1, 0), "Current": (0, 0, 0, 1, 0)}


@pytest.fixture(scope="module")
def schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(SCHEMA)))


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("osp")
    return {model: osp.write_model_description(fmu_build.fmu_path(model), folder)
            for model in fmu_build.MODELS}


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_model_description_is_valid_osp_is(schema: etree.XMLSchema, written: dict[str, Path],
                                           model: str) -> None:
    path = written[model]
    assert path.name == f"{model}_OspModelDescription.xml"   # the name libcosim looks for
    document = etree.parse(str(path))
    assert schema.validate(document), schema.error_log
    names = document.xpath("//osp:VariableGroups//@name", namespaces=NS)
    assert len(names) == len(set(names))   # group names are unique in a model (OSP-IS)


def test_schema_rejects_a_port_without_its_flow(schema: etree.XMLSchema,
                                                written: dict[str, Path]) -> None:
    document = etree.parse(str(written["DcMotorDrive"]))
    (velocity,) = document.xpath("//osp:AngularVelocity", namespaces=NS)
    velocity.getparent().remove(velocity)
    assert not schema.validate(document)


@pytest.mark.parametrize("model", [m for m in fmu_build.MODELS if osp.model_groups(m)])
def test_groups_have_the_units_and_causalities_of_their_quantity(
        written: dict[str, Path], model: str) -> None:
    """Each quantity's unit has its SI dimension, and a port's two quantities flow opposite
    ways (the check the OSP-IS validator makes beyond the schema)."""
    variables = {v.name: v for v in
                 read_model_description(fmu_build.fmu_path(model)).modelVariables}
    document = etree.parse(str(written[model]))
    units = {u.get("name"): u.find("osp:BaseUnit", NS)
             for u in document.xpath("//osp:Unit", namespaces=NS)}
    for kind, dimension in DIMENSIONS.items():
        for element in document.xpath(f"//osp:{kind}/osp:Variable", namespaces=NS):
            base = units[element.get("unit")]
            assert tuple(int(base.get(k)) for k in ("kg", "m", "s", "A", "rad")) == dimension
            variable = variables[element.get("ref")]
            declared = variable.declaredType.unit if variable.declaredType else variable.unit
            assert element.get("unit") == declared
    for group in osp.model_groups(model):
        if group.members:
            causalities = {variables[m.variables[0]].causality for m in group.members}
            assert causalities == {"input", "output"}, group.name


@pytest.mark.parametrize("name", scenarios.available())
def test_every_scenario_joint_is_a_mechanical_port(name: str) -> None:
    """Each joint a scenario drives, in every model its variants use, is a port of its kind
    made of the joint's effort and speed: what a drive connects to."""
    scenario = scenarios.load(name)
    kinds = {"revolute": "AngularMechanicalPort", "prismatic": "LinearMechanicalPort"}
    for variant in scenario.variants.values():
        model = variant.model or scenario.model
        ports = {(g.kind, tuple(m.variables[0] for m in g.members))
                 for g in osp.model_groups(model)}
        for joint in scenario.joints:
            assert (kinds[joint.kind], (joint.effort, joint.speed)) in ports, (model, joint)


def test_build_writes_it_beside_the_fmu(tmp_path: Path) -> None:
    fmu = fmu_build.build("PositionController", tmp_path)
    assert (tmp_path / "PositionController_OspModelDescription.xml").is_file()
    assert fmu.parent == tmp_path
