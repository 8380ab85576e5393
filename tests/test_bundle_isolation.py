"""Each FMU runs the Python code of its own bundle (fmu_src/runtime/runtime_core.c, its helper).

The runtime imports an FMU's modules as a package named after the digest of the bundle's
Python files, so nothing the process imported before decides what an FMU runs: not another
FMU, not another version of the same model from another folder, not the working tree's
fmu_src that this test process (like every harness command) has imported. The bundles here
are built from small slaves written into temporary source folders, each reporting the
version its own bundle carries; both hosts are tried, FMPy in this process and the C host
tests/native_host/fmi2_stress.c with an empty environment.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from fmu_src import parameters as working_tree_parameters
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

TESTS = Path(__file__).resolve().parent
MODEL = "Versioned"
# The slave reads its version from fmu_src.parameters: in its bundle, a module that holds
# BUNDLE_VERSION; in the working tree (which this process imported), one that does not.
SLAVE = textwrap.dedent('''
    """A slave that reports the version of the fmu_src.parameters of its bundle."""
    from pythonfmu import Fmi2Causality, Fmi2Slave, Real
    from pythonfmu.enums import Fmi2Initial, Fmi2Variability

    from fmu_src import parameters


    class Versioned(Fmi2Slave):
        """bundle_version: BUNDLE_VERSION of fmu_src.parameters where the slave was imported from
        (-1 where there is none)."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.bundle_version = float(getattr(parameters, "BUNDLE_VERSION", -1.0))
            self.register_variable(Real("bundle_version", causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.discrete,
                                        initial=Fmi2Initial.exact,
                                        description="The bundle's version"))

        def do_step(self, current_time, step_size):
            return True
''')
BROKEN = "raise RuntimeError('this bundle cannot be imported')\n"

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the runtime and the C host are for Linux")


def build_version(folder: Path, version: str) -> Path:
    """The Versioned FMU of one version, built from a source folder of its own into
    folder/fmu."""
    source = folder / "source"
    source.mkdir(parents=True)
    (source / f"{MODEL}.py").write_text(SLAVE)
    (source / "parameters.py").write_text(f"BUNDLE_VERSION = {version}\n")
    return fmu_build.build(MODEL, folder / "fmu", source)


def broken_copy(fmu: Path, folder: Path) -> Path:
    """A copy of the FMU whose bundled fmu_src.parameters raises on import: the same model,
    module names and GUID, other code (as an FMU edited after its build)."""
    entries = fmu_build.archive_entries(fmu)
    entries["resources/fmu_src/parameters.py"] = BROKEN.encode()
    folder.mkdir(parents=True, exist_ok=True)
    fmu_build.write_archive(folder / fmu.name, entries)
    return folder / fmu.name


@pytest.fixture(scope="module")
def versions(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Versions 1 and 2 of the Versioned FMU, version 1 again in another folder, and a copy
    of version 1 whose bundled code raises on import."""
    built = {name: build_version(tmp_path_factory.mktemp(name), version)
             for name, version in (("v1", "1.0"), ("v2", "2.0"), ("v1 copy", "1.0"))}
    return {**built, "broken": broken_copy(built["v1"], tmp_path_factory.mktemp("broken"))}


def version(fmu: CoSimFMU) -> float:
    return fmu.get(["bundle_version"])["bundle_version"]


def test_the_working_tree_has_no_bundle_version() -> None:
    """What a slave would see if it ran the working tree's module (the test's premise)."""
    assert not hasattr(working_tree_parameters, "BUNDLE_VERSION")


def test_two_versions_of_one_model_run_side_by_side_in_a_python_host(
        versions: dict[str, Path]) -> None:
    """In this process (which imported the working tree's fmu_src, as every harness command
    does): versions 1 and 2 of one model at once, and version 1 from another folder, each
    with the code of its own bundle. Before, every instance ran what was imported first."""
    fmus = [CoSimFMU(versions[name], name) for name in ("v1", "v2", "v1 copy")]
    try:
        for fmu in fmus:
            fmu.initialize()
        for fmu in fmus:
            fmu.step(0.0, 1e-3)
        assert [version(fmu) for fmu in fmus] == [1.0, 2.0, 1.0]
    finally:
        for fmu in fmus:
            fmu.close()


def test_a_bundle_whose_code_raises_is_refused_after_another_was_loaded(
        versions: dict[str, Path]) -> None:
    """The broken copy is refused (fmi2Instantiate returns NULL, with the exception's
    message) even though version 1, of the same model, module names and GUID, is loaded: it
    used to instantiate then, running version 1's modules."""
    good = CoSimFMU(versions["v1"], "good")
    try:
        good.initialize()
        with pytest.raises(Exception, match="instantiate"):
            CoSimFMU(versions["broken"], "broken")
        assert version(good) == 1.0
    finally:
        good.close()


def unzipped(fmu: Path, folder: Path) -> list[str]:
    """The FMU unzipped into folder, as the stress host's arguments DIR MODEL GUID r:VR."""
    zipfile.ZipFile(fmu).extractall(folder)
    md = read_model_description(fmu)
    (vr,) = [v.valueReference for v in md.modelVariables if v.name == "bundle_version"]
    return [str(folder), MODEL, md.guid, f"r:{vr}"]


@pytest.fixture(scope="module")
def stress(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fmu_build.zig_cc(TESTS / "native_host" / "fmi2_stress.c",
                            tmp_path_factory.mktemp("stress") / "fmi2_stress", "-lpthread",
                            "-ldl")


@pytest.mark.parametrize("mode", ["serial", "threads"])
def test_two_versions_of_one_model_run_side_by_side_in_a_c_host(
        stress: Path, versions: dict[str, Path], tmp_path: Path, mode: str) -> None:
    """The same in a C host without Python of its own, one after the other and in two
    threads at once: each instance reads its own version."""
    first, second = (unzipped(versions[name], tmp_path / name) for name in ("v1", "v2"))
    done = subprocess.run([str(stress), mode, *first, *second], env={}, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-4000:]
    assert done.stdout.splitlines() == ["thread 0 value 1", "thread 1 value 2"]


def test_a_bundle_whose_code_raises_is_refused_after_another_in_a_c_host(
        stress: Path, versions: dict[str, Path], tmp_path: Path) -> None:
    first, second = (unzipped(versions[name], tmp_path / name) for name in ("v1", "broken"))
    done = subprocess.run([str(stress), "serial", *first, *second], env={},
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stdout + done.stderr[-4000:]
    assert "RuntimeError: this bundle cannot be imported" in done.stderr
    assert "fmi2Instantiate returned NULL" in done.stderr


def test_a_shipped_fmu_runs_the_modules_of_its_bundle() -> None:
    """A built FMU opened the way the harness opens it runs the files of its bundle, not
    the working tree's modules this process imported: its physics module is the bundle's
    file, another module object than the working tree's."""
    from fmu_src.mechanisms.self_regulating import physics as working_tree_physics

    fmu = CoSimFMU(fmu_build.fmu_path("SelfRegulatingBalancer"))
    try:
        bundled = [module for name, module in list(sys.modules.items())
                   if name.startswith("_fmu_bundle_")
                   and name.endswith(".fmu_src.mechanisms.self_regulating.physics")]
        assert bundled and working_tree_physics not in bundled
        for module in bundled:  # one per content of the bundle this process met
            assert Path(module.__file__).parts[-5:] == (
                "resources", "fmu_src", "mechanisms", "self_regulating", "physics.py")
    finally:
        fmu.close()
