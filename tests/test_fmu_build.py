"""The build is by content: an FMU (or a compiled binary) is rebuilt when, and only when, the
digest of what goes into it changes; timestamps play no part."""

from __future__ import annotations

import os
import shutil
import time
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness import cli
from harness.errors import UserError
from harness.fmu import build as fmu_build


def snapshot(paths: list[Path]) -> dict[str, tuple[int, bytes]]:
    """Each file's modification time [ns] and bytes, by name."""
    return {path.name: (path.stat().st_mtime_ns, path.read_bytes()) for path in paths}


def test_a_second_build_rewrites_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    """`make fmu` twice: the second run reports every FMU unchanged and leaves every file of
    build/fmus and the runtime as they were, to the byte and the nanosecond."""
    assert cli.main(["build-fmus"]) == 0
    files = [fmu_build.RUNTIME_BUILD, *(fmu_build.DEFAULT_DEST / f"{m}{suffix}"
                                       for m in fmu_build.MODELS
                                       for suffix in (".fmu", "_OspModelDescription.xml"))]
    before = snapshot(files)
    capsys.readouterr()
    assert cli.main(["build-fmus"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == ["unchanged"] * len(fmu_build.MODELS)
    assert snapshot(files) == before


def test_a_deleted_osp_file_comes_back_without_a_rebuild() -> None:
    """An up-to-date FMU whose OSP model description was deleted gets the same file back,
    and the FMU itself is not rewritten."""
    model = fmu_build.MODELS[0]
    fmu = fmu_build.fmu_path(model)
    osp_file = fmu.with_name(f"{model}_OspModelDescription.xml")
    fmu_before, osp_before = snapshot([fmu])[fmu.name], osp_file.read_bytes()
    osp_file.unlink()
    assert not fmu_build.update(model)
    assert osp_file.read_bytes() == osp_before
    assert snapshot([fmu])[fmu.name] == fmu_before


@pytest.fixture
def sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A copy of fmu_src that the build reads instead of the committed one."""
    copy = tmp_path / "fmu_src"
    shutil.copytree(fmu_build.SOURCE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(fmu_build, "SOURCE_DIR", copy)
    return copy


def test_every_model_digests_its_own_modules(sources: Path) -> None:
    """A module every slave imports (fmi/slave.py) changes every FMU's digest; the
    controller's (pid) only the PositionController's; a new module that no slave imports,
    none."""
    def digests() -> dict[str, str]:
        return {m: fmu_build.fmu_inputs(m, sources) for m in fmu_build.MODELS}

    original = digests()
    assert len(set(original.values())) == len(fmu_build.MODELS)
    (sources / "unused_helper.py").write_text("VALUE = 1\n")
    assert digests() == original
    for module, importers in (("units/controller/pid.py", {"PositionController"}),
                              ("fmi/slave.py", set(fmu_build.MODELS))):
        path = sources / module
        text = path.read_text()
        path.write_text(text + "# changed\n")
        changed = {m for m, value in digests().items() if value != original[m]}
        assert changed == importers, module
        path.write_text(text)
    assert digests() == original


def test_a_changed_module_rebuilds_exactly_the_fmus_that_import_it(sources: Path,
                                                                    tmp_path: Path) -> None:
    """Two FMUs built from the copy: newer timestamps on every source rebuild neither; a
    change to pid.py rebuilds the PositionController (new GUID) and leaves DcMotorDrive as
    it was; --force rebuilds regardless."""
    dest = tmp_path / "fmus"
    models = ("PositionController", "DcMotorDrive")
    assert all(fmu_build.update(m, dest, sources) for m in models)
    fmus = [dest / f"{m}.fmu" for m in models]
    guid = read_model_description(fmus[0]).guid
    before = snapshot(fmus)
    later = time.time() + 100.0
    for path in sources.rglob("*"):
        os.utime(path, (later, later))
    assert not any(fmu_build.update(m, dest, sources) for m in models)
    assert snapshot(fmus) == before

    with (sources / "units" / "controller" / "pid.py").open("a") as module:
        module.write("# changed\n")
    assert [fmu_build.update(m, dest, sources) for m in models] == [True, False]
    after = snapshot(fmus)
    assert after["DcMotorDrive.fmu"] == before["DcMotorDrive.fmu"]
    assert after["PositionController.fmu"][1] != before["PositionController.fmu"][1]
    assert read_model_description(fmus[0]).guid != guid
    assert fmu_build.recorded_inputs(fmus[0]) == fmu_build.fmu_inputs(models[0], sources)
    assert fmu_build.fmu_path(models[0], dest, sources) == fmus[0]
    assert snapshot(fmus) == after
    assert fmu_build.update(models[1], dest, sources, force=True)
    forced = snapshot(fmus)["DcMotorDrive.fmu"]
    assert forced[0] != before["DcMotorDrive.fmu"][0]  # written again,
    assert forced[1] == before["DcMotorDrive.fmu"][1]  # to the same bytes (reproducible)


def test_the_same_inputs_give_the_same_fmu_to_the_byte(sources: Path, tmp_path: Path) -> None:
    """Two forced builds in two folders: identical bytes, the GUID derived from the recorded
    digest, no generation time, every entry of mode 0644 (readable by every user of a shared
    installation)."""
    model = "DcMotorDrive"
    first = fmu_build.build(model, tmp_path / "one", sources)
    second = fmu_build.build(model, tmp_path / "two", sources)
    assert first.read_bytes() == second.read_bytes()
    md = read_model_description(first)
    assert md.guid == fmu_build.content_guid(fmu_build.recorded_inputs(first))
    assert md.generationDateAndTime is None
    with zipfile.ZipFile(first) as archive:
        record = archive.read("resources/python.txt").decode()
        modes = {info.filename: info.external_attr >> 16 for info in archive.infolist()}
    assert f"guid={md.guid}\n" in record
    assert set(modes.values()) == {0o100644}, modes


def test_a_binary_is_recompiled_when_its_inputs_change(tmp_path: Path) -> None:
    """compiled(): the digest recorded beside the binary decides, not the timestamps; a
    missing record or binary recompiles."""
    source, output = tmp_path / "answer.c", tmp_path / "libanswer.so"
    source.write_text("int answer(void) { return 42; }\n")
    options = ("-shared", "-fPIC")
    fmu_build.compiled(source, output, *options)
    record = output.with_name(f"{output.name}.sha256")
    assert record.read_text() == fmu_build.compile_inputs(source, *options)
    before = snapshot([output])
    later = time.time() + 100.0
    os.utime(source, (later, later))
    fmu_build.compiled(source, output, *options)
    assert snapshot([output]) == before
    source.write_text("int answer(void) { return 43; }\n")
    fmu_build.compiled(source, output, *options)
    assert snapshot([output])[output.name][1] != before[output.name][1]
    compiled = snapshot([output])
    record.unlink()
    fmu_build.compiled(source, output, *options)
    assert record.exists() and snapshot([output]) != compiled


def test_running_locates_a_built_fmu_and_never_builds(tmp_path: Path) -> None:
    """`locate` returns an up-to-date FMU as it is and, for a missing one, names the command
    that builds it without building anything."""
    with pytest.raises(UserError, match=r"DcMotorDrive\.fmu is not built: build it with "
                                        r"`python -m harness build-fmus --out "):
        fmu_build.locate("DcMotorDrive", tmp_path)
    assert list(tmp_path.iterdir()) == []
    built = fmu_build.fmu_path("DcMotorDrive")
    copy = shutil.copy2(built, tmp_path / built.name)
    assert fmu_build.locate("DcMotorDrive", tmp_path) == copy
    assert copy.read_bytes() == built.read_bytes()
