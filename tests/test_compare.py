"""The CSV comparison command: tolerance and band checks, exit codes, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import write

from harness import cli
from harness.compare import compare, read_result


@pytest.fixture
def reference(tmp_path: Path) -> Path:
    t = np.linspace(0.0, 2.0, 201)
    return write(tmp_path / "ref.csv", pd.DataFrame({"time": t, "theta": np.sin(t),
                                                     "E": 5.0 * t}))


def shifted(tmp_path: Path, reference: Path, delta: float) -> Path:
    frame = pd.read_csv(reference)
    frame["theta"] += delta
    return write(tmp_path / f"res_{delta}.csv", frame)


def test_within_tolerance_passes(tmp_path: Path, reference: Path) -> None:
    # max |theta| = 1 (at pi/2), so rtol = 1e-3 allows a deviation of 1e-3
    result = shifted(tmp_path, reference, 0.5e-3)
    assert cli.main(["compare", str(reference), str(result), "--rtol", "1e-3"]) == 0


def test_outside_tolerance_fails_and_names_the_signal(tmp_path: Path, reference: Path,
                                                      capsys: pytest.CaptureFixture) -> None:
    result = shifted(tmp_path, reference, 2e-3)
    plot = tmp_path / "report.png"
    code = cli.main(["compare", str(reference), str(result), "--plot", str(plot)])
    assert code == 1
    assert "outside tolerance: theta" in capsys.readouterr().out.splitlines()[-1]
    assert plot.stat().st_size > 0


def test_band_check_catches_a_spike_a_loose_tolerance_allows(reference: Path) -> None:
    frame = pd.read_csv(reference)
    result = frame.copy()
    result.loc[100, "theta"] += 0.3  # 15 % of the signal's range: outside the FMI band
    (theta,) = compare(frame, result, ["theta"], rtol=0.5)
    assert theta.outside_tolerance == 0 and theta.outside_band >= 1 and not theta.passed


@pytest.mark.parametrize("content, message", [
    ("a,b\n1,2\n2,3\n", "first column must be 'time'"),
    ("time,x\n0,1\n0,2\n", "not strictly increasing"),
    ("time,x\n0,1\n", "at least two rows"),
])
def test_bad_files_give_a_clear_error(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        read_result(path)


def test_unknown_signal_is_an_error(reference: Path, capsys: pytest.CaptureFixture) -> None:
    assert cli.main(["compare", str(reference), str(reference), "--signals", "omega"]) == 2
    assert "unknown signal(s) omega" in capsys.readouterr().err
