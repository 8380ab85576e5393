"""Hostile files and options for the command line: one line naming the field and its allowed
values, exit 2, nothing simulated or written; the FMU's own messages reach the user; result
sets keep their rows; compare refuses what it cannot check."""

from __future__ import annotations

import json
import math
import os
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from conftest import write

from harness import cli, scenarios
from harness.errors import UserError
from harness.run import plots, results
from harness.sweeps import definition, execution

SHORT = '''
name = "short"
model = "SelfRegulatingBalancer"
initial_angle_deg = 60.0
baseline = "unbalanced"
[parameters]
[[phases]]
name = "hold"
duration = 0.2
target_deg = 60.0
inputs = { payload = 0.0 }
[[phases]]
name = "move"
duration = 0.2
target_deg = 70.0
[variants.balanced]
[variants.unbalanced]
parameters = { k = 0.0 }
'''


def scenario_file(tmp_path: Path, old: str = "", new: str = "", text: str = SHORT) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text(text.replace(old, new, 1) if old else text)
    return path


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], *named: str) -> str:
    """Run the command line: exit 2 and one error line naming every string in named."""
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error: ") and "Traceback" not in err
    for text in named:
        assert text in err, err
    return err


# ---- scenario files and cosim options (sections 5 and 12)

@pytest.mark.parametrize(("old", "new", "named"), [
    ("duration = 0.2", "duration = inf", ("duration", "inf")),
    ("duration = 0.2", "duration = [1, 2]", ("duration", "[1, 2]")),
    ("[parameters]", "[parameters]\nk = [1, 2]", ("parameters k",)),
    ("[parameters]", "[parameters]\nnot_a_parameter = 1.0", ("no parameter not_a_parameter",)),
    ('model = "SelfRegulatingBalancer"', 'model = "NoSuchModel"', ("unknown model",)),
    ("target_deg = 70.0", "target_deg = nan", ("target_deg", "nan")),
    ("payload = 0.0", "payload = { ramp = nan }", ("payload ramp", "nan")),
    ("parameters = { k = 0.0 }", "parameters = { k = 0.0 }\ninputs = { payload = nan }",
     ("variant unbalanced inputs payload", "nan")),
    ('name = "move"', 'name = "hold"', ("phase names repeat", "hold")),
    ("duration = 0.2", "duration = 1e308", ("phase move", "finite")),
    ('name = "move"\nduration = 0.2', 'name = "move"\nduration = 1e-18', ("phase move",)),
    ('name = "short"', 'name = "../../x"', ("name", "../../x")),
    ('name = "short"', 'name = ""', ("name", "''")),
    ("[variants.balanced]", "[variants.\"../up\"]", ("variant name", "../up")),
], ids=["duration=inf", "duration=list", "parameter=list", "unknown-parameter", "unknown-model",
        "target_deg=nan", "ramp=nan", "variant-input=nan", "duplicate-phase",
        "duration-huge", "duration-vanishes", "name=../../x",
        "name=empty", "variant-name=../up"])
def test_bad_scenario_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       old: str, new: str, named: tuple[str, ...]) -> None:
    out = tmp_path / "out"
    refused(["cosim", "--scenario", str(scenario_file(tmp_path, old, new)), "--out", str(out),
             "--quiet"], capsys, *named)
    assert not any(out.rglob("*.csv"))


def test_empty_variants_table_is_one_line(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    text = SHORT[:SHORT.index("[variants.balanced]")] + "[variants]\n"
    refused(["cosim", "--scenario", str(scenario_file(tmp_path, text=text)), "--quiet"], capsys,
            "no variants")


@pytest.mark.parametrize(("options", "named"), [
    (["--step", "0"], "--step"), (["--step", "inf"], "--step"), (["--step", "nan"], "--step"),
    (["--variants", "nope"], "no variant 'nope'"), (["--variants", ""], "no variant ''"),
    (["--scenario", "no_such_scenario"], "no scenario 'no_such_scenario'"),
    (["--workers", "0"], "--workers = 0"),
])
def test_bad_cosim_option_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      options: list[str], named: str) -> None:
    argv = ["cosim", "--scenario", str(scenario_file(tmp_path)), "--out", str(tmp_path),
            "--quiet"]
    refused(argv + options, capsys, named)


def test_read_only_out_is_found_before_simulating(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "locked"
    out.mkdir()
    out.chmod(0o500)
    if os.access(out, os.W_OK):
        out.chmod(0o700)
        pytest.skip("this user writes into read-only folders (root); see the next test")
    try:
        start = time.perf_counter()
        refused(["cosim", "--scenario", str(scenario_file(tmp_path)), "--out", str(out),
                 "--quiet"], capsys, "not writable")
        assert time.perf_counter() - start < 5.0
    finally:
        out.chmod(0o700)


def test_out_that_is_a_file_is_found_before_simulating(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """(Works as root too: a file where the folder should be.)"""
    blocker = tmp_path / "out"
    blocker.write_text("")
    refused(["cosim", "--scenario", str(scenario_file(tmp_path)), "--out", str(blocker),
             "--quiet"], capsys, "not writable")


def test_fmu_message_reaches_the_user(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """k = -5 used to end in 'fmi2ExitInitializationMode failed with status 4' only; the
    model's own check now refuses it before any run, naming the model."""
    path = scenario_file(tmp_path, "[parameters]", "[parameters]\nk = -5.0")
    refused(["cosim", "--scenario", str(path), "--out", str(tmp_path / "out"), "--quiet"],
            capsys, "k = -5.0 N/m is outside [0.0, inf)", "SelfRegulatingBalancer")


def test_out_of_range_input_is_one_line(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    """payload = -1.4 kg in a phase: the FMU refuses it when the master sets it (fmi2SetReal,
    fmi2Error), and the user sees that one line, naming the input and its range."""
    path = scenario_file(tmp_path, "inputs = { payload = 0.0 }", "inputs = { payload = -1.4 }")
    refused(["cosim", "--scenario", str(path), "--out", str(tmp_path / "out"), "--quiet"],
            capsys, "SelfRegulatingBalancer: fmi2SetReal failed with status Error",
            "input payload = -1.4 kg is outside [0.0, inf]")
    assert not (tmp_path / "out" / "short" / "summary.csv").exists()


def test_truncated_fmu_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from harness.fmu.loader import CoSimFMU

    broken = tmp_path / "Broken.fmu"
    broken.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(UserError, match="Broken.fmu"):
        CoSimFMU(broken)


# ---- result sets (section 3)

def test_one_variant_merges_into_the_result_set(tmp_path: Path) -> None:
    """cosim --variants X used to rewrite summary.csv with X's row alone."""
    path, out = scenario_file(tmp_path), tmp_path / "out"
    # the legacy drives: no sizing runs, the merging is the same
    assert cli.main(["cosim", "--scenario", str(path), "--out", str(out), "--quiet",
                     "--drives", "legacy"]) == 0
    first = pd.read_csv(out / "short" / "summary.csv")
    assert list(first.variant) == ["balanced", "unbalanced"]
    # the baseline alone (a variant's run also runs its baseline; this one is its own)
    assert cli.main(["cosim", "--scenario", str(path), "--variants", "unbalanced", "--out",
                     str(out), "--quiet", "--drives", "legacy"]) == 0
    second = pd.read_csv(out / "short" / "summary.csv")
    pd.testing.assert_frame_equal(first, second)  # same runs, same numbers, both rows


def test_worker_processes_write_what_one_process_writes(tmp_path: Path) -> None:
    """cosim --workers 2 runs the variants and writes the files in worker processes: the
    same CSV files, byte for byte, as one process."""
    path = scenario_file(tmp_path)
    for workers in ("1", "2"):
        assert cli.main(["cosim", "--scenario", str(path), "--workers", workers, "--out",
                         str(tmp_path / workers), "--quiet"]) == 0
    csvs = sorted(p.name for p in (tmp_path / "1" / "short").glob("*.csv"))
    assert csvs == ["balanced.csv", "drives.csv", "summary.csv", "unbalanced.csv"]
    for name in csvs:
        assert ((tmp_path / "1" / "short" / name).read_bytes()
                == (tmp_path / "2" / "short" / name).read_bytes()), name


def test_interrupted_write_leaves_the_result_set_as_it_was(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Killed mid-write (while plotting, after the CSVs are made), cosim leaves every file of
    the result set as it was: nothing is renamed into place before all are staged."""
    path, out = scenario_file(tmp_path), tmp_path / "out"
    assert cli.main(["cosim", "--scenario", str(path), "--out", str(out), "--quiet",
                     "--drives", "legacy"]) == 0
    before = {p.name: p.read_bytes() for p in (out / "short").iterdir()}

    def killed(*_args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "plot", killed)
    assert cli.main(["cosim", "--scenario", str(path), "--variants", "unbalanced", "--step",
                     "0.002", "--out", str(out), "--quiet", "--drives", "legacy",
                     "--replace"]) == 130
    assert {p.name: p.read_bytes() for p in (out / "short").iterdir()} == before


def test_concurrent_writers_are_serialised(tmp_path: Path) -> None:
    """A second writer waits for the folder lock instead of interleaving its files."""
    out = tmp_path / "set"
    finished = threading.Event()

    def writer() -> None:
        with results.locked(out):
            finished.set()

    with results.locked(out):
        thread = threading.Thread(target=writer)
        thread.start()
        time.sleep(0.3)
        assert not finished.is_set()
    thread.join(5.0)
    assert finished.is_set()


# ---- compare (section 2)

@pytest.fixture
def reference(tmp_path: Path) -> Path:
    t = np.linspace(0.0, 35.0, 351)
    return write(tmp_path / "reference.csv", pd.DataFrame({"time": t, "theta": np.sin(t)}))


@pytest.mark.parametrize(("result", "named"), [
    (pd.DataFrame({"time": np.linspace(0, 35, 351), "theta": np.nan}), "NaN in signal(s) theta"),
    (pd.DataFrame({"time": np.linspace(0, 0.5, 6), "theta": np.sin(np.linspace(0, 0.5, 6))}),
     "covers time [0, 0.5] s"),
    (pd.DataFrame({"time": np.linspace(0, 35, 351), "omega": 0.0}), "no signal in common"),
], ids=["nan", "short", "disjoint"])
def test_compare_refuses_what_it_cannot_check(tmp_path: Path, reference: Path,
                                              capsys: pytest.CaptureFixture[str],
                                              result: pd.DataFrame, named: str) -> None:
    refused(["compare", str(reference), str(write(tmp_path / "result.csv", result))], capsys,
            named)


def test_compare_still_passes_an_equal_result(tmp_path: Path, reference: Path) -> None:
    assert cli.main(["compare", str(reference), str(reference)]) == 0


# ---- sweep files (section 11)

SWEEP = '''
name = "tiny"
scenario = "scenario.toml"
variants = ["balanced"]
[[axes]]
name = "k"
set = "parameters.k"
values = [981.0, 500.0]
'''


@pytest.mark.parametrize(("old", "new", "named"), [
    ('set = "parameters.k"', "set = 5", "set = 5"),
    ("values = [981.0, 500.0]", "values = [[1.0, 2.0]]", "[1.0, 2.0]"),
    ("values = [981.0, 500.0]", 'range = "0:1"', "range = '0:1'"),
    ("values = [981.0, 500.0]", "range = { start = 0, stop = 1, num = 1e12 }", "num"),
    ("values = [981.0, 500.0]", "range = { start = 0, stop = 1, num = 2.7 }", "num = 2.7"),
    ("values = [981.0, 500.0]", "values = [981.0, 981.0]", "values repeat: 981"),
    ("values = [981.0, 500.0]", "values = [981.0, nan]", "nan"),
    ('name = "tiny"', 'name = "tiny"\nstep_size = inf', "step_size"),
    ('name = "tiny"', 'name = "../../x"', "../../x"),
    ('set = "parameters.k"', 'set = "parameters.no_such"', "no parameter no_such"),
    ('variants = ["balanced"]', 'variants = "balanced"', "variants = 'balanced'"),
    ('name = "tiny"', 'name = "tiny"\nmetrics = 5', "metrics = 5"),
    ("values = [981.0, 500.0]", 'values = [981.0, 500.0]\n[plots.saving]\nx = "k"\n'
     'baseline = "nope"', "baseline = 'nope'"),
], ids=["set=5", "nested", "range=string", "num=1e12", "num=2.7", "duplicates", "nan",
        "step=inf", "name=../../x", "unknown-parameter", "variants=string", "metrics=5",
        "plot-baseline"])
def test_bad_sweep_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    old: str, new: str, named: str) -> None:
    scenario_file(tmp_path)
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.replace(old, new, 1))
    with pytest.raises(UserError, match=None) as failure:
        definition.load(path)
    assert named in str(failure.value)
    refused(["sweep", str(path), "--out", str(tmp_path / "out")], capsys, named)
    assert not (tmp_path / "out").exists()


# ---- ciupitu-example --json (section 12)

def test_ciupitu_json_is_json_for_degenerate_data(capsys: pytest.CaptureFixture[str],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Data with no unbalanced work (E_u = 0, as OP = 5e-324 m gave before the magnitude
    limits) leave eps undefined: written null, not NaN or -Infinity (which are not JSON)."""
    from fmu_src.mechanisms.ciupitu import example as ciupitu

    undefined = ciupitu.StrokeResult(0.0, 1.0, -math.inf, 6.0, -0.46)
    monkeypatch.setattr(ciupitu, "stroke", lambda data, law, with_bar=False: undefined._replace(
        eps=math.nan if law == "linear" else -math.inf))
    assert cli.main(["ciupitu-example", "--json"]) == 0
    captured = capsys.readouterr()
    values = json.loads(captured.out, parse_constant=lambda name: pytest.fail(name))
    assert values["eps_parabolic"] is None and values["eps_linear"] is None
    assert "eps_parabolic" in captured.err
    assert all(v is None or math.isfinite(v) for v in values.values())
    assert cli.main(["ciupitu-example", "--json", "--OP=5e-324"]) == 2  # now out of range


def test_scenarios_load_error_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="duration"):
        scenarios.load(scenario_file(tmp_path, "duration = 0.2", "duration = -1.0"))


@pytest.mark.slow
def test_sweep_whose_runs_all_fail_exits_non_zero(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Every run refused by the FMU (k < 0): exit 1 with the first error, not 0."""
    scenario_file(tmp_path)
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.replace("values = [981.0, 500.0]", "values = [-1.0, -2.0]"))
    assert cli.main(["sweep", str(path), "--out", str(tmp_path / "out"), "--workers", "1",
                     "--quiet"]) == 1
    assert "all 2 runs failed" in capsys.readouterr().err


def test_sweep_tables_are_replaced_together(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A failure (or kill) while the final tables are written leaves the old parquet and CSV
    together: it used to leave a 20-row parquet beside a 17-row CSV."""
    scenario_file(tmp_path)
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    loaded = definition.load(path)
    out = tmp_path / "out"
    runs = definition.plan(loaded)
    row = {"status": "failed", "error": "test"}
    execution.write_part(loaded, out, [{"run_id": runs[0].run_id, "point": runs[0].point,
                                         "variant": runs[0].variant, **runs[0].values, **row}])
    execution.consolidate(loaded, out)
    execution.write_part(loaded, out, [{"run_id": runs[1].run_id, "point": runs[1].point,
                                         "variant": runs[1].variant, **runs[1].values, **row}])

    def killed(*_args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(execution, "write_csv", killed)
    with pytest.raises(KeyboardInterrupt):
        execution.consolidate(loaded, out)
    parquet = pd.read_parquet(out / "tiny.parquet")
    csv = pd.read_csv(out / "tiny.csv")
    assert len(parquet) == len(csv) == 1
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_closing_a_cluster_whose_workers_are_gone_is_quiet() -> None:
    """After Ctrl-C the workers may be gone: closing the client used to end in a
    CommClosedError traceback instead of the 'interrupted' line."""
    from distributed.comm.core import CommClosedError

    class GoneClient:
        cluster = None

        def close(self) -> None:
            raise CommClosedError("in <TCP (closed)>: Stream is closed")

    execution.close_client(GoneClient())  # type: ignore[arg-type]


# ---- issue 22: user mistakes that ended in a traceback or exit 0 (one line, exit 2) --------

BIG_INTEGER = "1" + "0" * 400          # a TOML integer beyond the range of a float (1.8e308)
DEEP_ARRAY = "[" * 20_000 + "]" * 20_000
NOT_UTF8 = b"\n# caf\xe9 in Latin-1\n"


def _files(tmp_path: Path, scenario: str = SHORT, sweep: str = SWEEP) -> dict[str, Path]:
    """The scenario and sweep files of a case, a plain file and a folder named like a file."""
    (tmp_path / "scenario.toml").write_text(scenario)
    (tmp_path / "sweep.toml").write_text(sweep)
    (tmp_path / "a_file").write_text("")
    (tmp_path / "folder.toml").mkdir()
    return {"scenario": tmp_path / "scenario.toml", "sweep": tmp_path / "sweep.toml",
            "file": tmp_path / "a_file", "folder": tmp_path / "folder.toml",
            "out": tmp_path / "out"}


def _swept(path: str, values: str) -> str:
    """SWEEP with its one axis setting path to values (a TOML array)."""
    return SWEEP.replace('set = "parameters.k"', f"set = {json.dumps(path)}").replace(
        "[981.0, 500.0]", values)


def _latin1(path: Path) -> Path:
    path.write_bytes(path.read_bytes() + NOT_UTF8)
    return path


COSIM = ["cosim", "--scenario", "{scenario}", "--out", "{out}", "--quiet"]
SWEEP_CLI = ["sweep", "{sweep}", "--out", "{out}", "--quiet"]
SYSTEM = ["cosim", "--engine", "libcosim", "--scenario", "{scenario}", "--out", "{out}",
          "--quiet"]
# id -> (files: scenario and sweep text, or a function of the files; argv; named strings)
CASES: dict[str, tuple[Any, list[str], tuple[str, ...]]] = {
    # exit 0 on nonsense
    "cosim-target_deg=1e300": ({"scenario": SHORT.replace("target_deg = 70.0",
                                                          "target_deg = 1e300")}, COSIM,
                               ("target_deg = 1e+300 deg is outside [-1e+50, 1e+50]",)),
    "system-step=100": ({}, SYSTEM + ["--step", "100"], ("--step = 100.0 s is outside",
                                                         "0.4]")),
    "sweep-omega_c=-25": ({"sweep": _swept("design.omega_c", "[-25.0]")}, SWEEP_CLI,
                          ("axis k value -25", "omega_c = -25.0 rad/s is outside (0.0, inf)")),
    "sweep-variants-repeat": ({"sweep": SWEEP.replace('["balanced"]', '["balanced", "balanced"]')},
                              SWEEP_CLI, ("variants = ['balanced', 'balanced']",
                                          "more than once")),
    # every engine has the bound of the scenario's duration in at most 10 million steps
    "system-step=1e-9": ({}, SYSTEM + ["--engine", "fmpy-ssp", "--step", "1e-9"],
                         ("--step = 1e-09 s is outside [4e-08, 0.4]",)),
    "sweep-step_size=1e-9": ({"sweep": SWEEP.replace('name = "tiny"',
                                                     'name = "tiny"\nstep_size = 1e-9')},
                             SWEEP_CLI, ("step_size = 1e-09 s is outside [4e-08, 0.4]",)),
    # huge sweep axes, refused when parsing
    "sweep-axis-100000-values": ({"sweep": _swept("parameters.k", "[" + ", ".join(
        str(100.0 + i) for i in range(100_000)) + "]")}, SWEEP_CLI,
                                 ("axis k values", "list of 1 to 10,000 numbers")),
    "sweep-range-num=100000": ({"sweep": _swept("parameters.k", "[1.0]").replace(
        "values = [1.0]", "range = { start = 100, stop = 900, num = 100000 }")}, SWEEP_CLI,
                               ("range num = 100000 is not a whole number in [1, 10000]",)),
    # files that are not UTF-8
    "utf8-cosim-scenario": (lambda f: _latin1(f["scenario"]), COSIM,
                            ("scenario.toml: not UTF-8", "0xe9")),
    "utf8-system-scenario": (lambda f: _latin1(f["scenario"]), SYSTEM,
                             ("scenario.toml: not UTF-8",)),
    "utf8-sweep": (lambda f: _latin1(f["sweep"]), SWEEP_CLI, ("sweep.toml: not UTF-8",)),
    "utf8-sweep-scenario": (lambda f: _latin1(f["scenario"]), SWEEP_CLI,
                            ("scenario.toml: not UTF-8",)),
    "utf8-sequencer-scenario": (lambda f: _latin1(f["scenario"]),
                                ["build-fmus", "--out", "{out}", "--sequencer-scenario",
                                 "{scenario}"], ("scenario.toml: not UTF-8",)),
    # TOML integers beyond the range of a float
    "bigint-duration": ({"scenario": SHORT.replace("duration = 0.2", f"duration = {BIG_INTEGER}",
                                                   1)}, COSIM,
                        ("phase hold: duration = an integer of about 400 digits",)),
    "bigint-parameter": ({"scenario": SHORT.replace("[parameters]",
                                                    f"[parameters]\nk = {BIG_INTEGER}")}, COSIM,
                         ("parameters k = an integer of about 400 digits",)),
    "bigint-target": ({"scenario": SHORT.replace("target_deg = 70.0",
                                                 f"target_deg = {BIG_INTEGER}")}, COSIM,
                      ("target_deg = an integer of about 400 digits",)),
    "bigint-sweep-value": ({"sweep": _swept("parameters.k", f"[{BIG_INTEGER}]")}, SWEEP_CLI,
                           ("axis k values item = an integer of about 400 digits",)),
    "integer-of-5000-digits": ({"scenario": SHORT.replace("[parameters]",
                                                          "[parameters]\nk = 1" + "0" * 5000)},
                               COSIM, ("scenario.toml: not valid TOML",)),
    # arrays nested 20,000 deep
    "deep-scenario": ({"scenario": SHORT.replace("[parameters]",
                                                 f"[parameters]\nk = {DEEP_ARRAY}")}, COSIM,
                      ("scenario.toml: arrays or tables nested too deeply",)),
    "deep-sweep": ({"sweep": _swept("parameters.k", DEEP_ARRAY)}, SWEEP_CLI,
                   ("sweep.toml: arrays or tables nested too deeply",)),
    # a scenario or sweep path that is a folder
    "folder-scenario": ({}, ["cosim", "--scenario", "{folder}", "--out", "{out}", "--quiet"],
                        ("folder.toml: cannot be read as a file", "Is a directory")),
    "folder-sweep": ({}, ["sweep", "{folder}", "--out", "{out}"],
                     ("folder.toml: cannot be read as a file",)),
    # options
    "system-step=inf": ({}, SYSTEM + ["--step", "inf"], ("--step = inf s is outside",)),
    "system-out-is-a-file": ({}, ["cosim", "--engine", "fmpy-ssp", "--out", "{file}"],
                             ("a_file is not writable",)),
    "out-name-of-300-bytes": ({}, ["cosim", "--out", "{out}/" + "x" * 300],
                              ("a name of 300 bytes, more than the 255",)),
    "losses-unknown": ({}, COSIM + ["--losses", "real"],
                       ("--losses = 'real'", "all", "ideal", "realistic")),
    "build-fmus-out-is-a-file": ({}, ["build-fmus", "--out", "{file}"],
                                 ("a_file is not writable",)),
    "active-design-Fs0-k": ({}, ["active-design", "--Fs0", "1e50", "--k", "1e-50"],
                            ("no Y_B balances the link", "--Fs0", "--k")),
    "active-design-ls0": ({}, ["active-design", "--ls0", "1e50"],
                          ("no Y_B balances the link in double precision", "--ls0 1e+50")),
    # sweep files and options
    "sweep-scenario=5": ({"sweep": SWEEP.replace('"scenario.toml"', "5")}, SWEEP_CLI,
                         ("scenario = 5 is not a scenario name",)),
    "sweep-scenario=list": ({"sweep": SWEEP.replace('"scenario.toml"', '["scenario.toml"]')},
                            SWEEP_CLI, ("scenario = ['scenario.toml'] is not a scenario name",)),
    "sweep-path-of-100000-dashes": ({"sweep": _swept("-" * 100_000, "[1.0]")}, SWEEP_CLI,
                                    ("axis k set path", "has 100,000 characters, more than "
                                     "1,000")),
    "sweep-bracket-of-100000-dashes": ({"sweep": _swept("phases[" + "-" * 100_000 + "]",
                                                        "[1.0]")}, SWEEP_CLI,
                                       ("has 100,008 characters",)),
    "sweep-omega_c=0": ({"sweep": _swept("design.omega_c", "[0.0, 25.0]")}, SWEEP_CLI,
                        ("axis k value 0", "omega_c = 0.0 rad/s is outside (0.0, inf)")),
    "sweep-derivative_filter_ratio=0": ({"sweep": _swept("design.derivative_filter_ratio",
                                                         "[10.0, 0.0]")}, SWEEP_CLI,
                                        ("derivative_filter_ratio = 0.0 1 is outside",)),
    "sweep-out-is-a-file": ({}, ["sweep", "{sweep}", "--out", "{file}", "--quiet"],
                            ("a_file is not writable",)),
    "sweep-out-unwritable": ({}, ["sweep", "{sweep}", "--out", "/proc/harness-test-out",
                                  "--quiet"], ("/proc/harness-test-out is not writable",)),
    "sweep-scheduler-garbage": ({}, SWEEP_CLI + ["--scheduler", "garbage"],
                                ("--scheduler = 'garbage' is not an address",)),
    "sweep-scheduler-unknown-protocol": ({}, SWEEP_CLI + ["--scheduler", "no://such:1"],
                                         ("--scheduler = 'no://such:1' is not an address",)),
    "sweep-scheduler-unreachable": ({}, SWEEP_CLI + ["--scheduler", "tcp://127.0.0.1:1"],
                                    ("--scheduler = 'tcp://127.0.0.1:1': no Dask scheduler "
                                     "answered within 1 s",)),
}
@pytest.mark.parametrize(("files", "argv", "named"), [
    pytest.param(*case, id=name) for name, case in CASES.items()] + [
    pytest.param(lambda f: _latin1(write(f["file"].with_suffix(".csv"), pd.DataFrame(
        {"time": [0.0, 1.0], "theta": [0.0, 1.0]}))), ["compare", "{csv}", "{good}"],
        ("a_file.csv",), id="utf8-compare-reference"),
    pytest.param(lambda f: _latin1(write(f["file"].with_suffix(".csv"), pd.DataFrame(
        {"time": [0.0, 1.0], "theta": [0.0, 1.0]}))), ["compare", "{good}", "{csv}"],
        ("a_file.csv",), id="utf8-compare-result")])
def test_user_mistake_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         monkeypatch: pytest.MonkeyPatch, files: Any,
                                         argv: list[str], named: tuple[str, ...]) -> None:
    """Each of these ended in a traceback, ran for minutes, or exited 0 with a wrong result
    (issue 22); now one line naming the field, exit 2, before any run or file written."""
    import harness.sweeps

    monkeypatch.setattr(harness.sweeps, "SCHEDULER_TIMEOUT", 1.0, raising=False)
    paths = _files(tmp_path, **({} if callable(files) else files))
    if callable(files):
        files(paths)
    paths |= {"csv": paths["file"].with_suffix(".csv"), "good": write(
        tmp_path / "good.csv", pd.DataFrame({"time": [0.0, 1.0], "theta": [0.0, 1.0]}))}
    if "/proc/harness-test-out" in argv and not Path("/proc/self").exists():
        pytest.skip("no /proc: a file system where nobody (root included) makes folders")
    start = time.perf_counter()
    refused([word.format(**paths) for word in argv], capsys, *named)
    assert time.perf_counter() - start < 30.0  # refused up front, not after the runs
    written = [p for p in paths["out"].rglob("*") if p.is_file()] if paths["out"].exists() else []
    assert written == []  # nothing was written
