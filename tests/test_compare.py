"""The CSV comparison command: tolerance and band checks, exit codes, bad files."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import write

from harness import cli
from harness.run.compare import compare, read_result


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


def _samples(tmp_path: Path, name: str, values: np.ndarray) -> Path:
    return write(tmp_path / name, pd.DataFrame({"time": np.linspace(0.0, 1.0, len(values)),
                                                "theta": values}))


@pytest.mark.parametrize(("reference_values", "result_values", "bad_file", "row", "kind"), [
    # one inf reference sample made the allowed band infinite: +-1e6 passed with exit 0
    (np.where(np.arange(101) == 50, np.inf, np.sin(np.linspace(0, 1, 101))),
     1e6 * (-1.0) ** np.arange(101), "ref.csv", 51, "+inf"),
    (np.full(101, np.inf), np.full(101, -np.inf), "ref.csv", 1, "+inf"),
    (np.zeros(101), np.where(np.arange(101) == 7, -np.inf, 0.0), "res.csv", 8, "-inf"),
], ids=["inf-reference", "inf-against-minus-inf", "minus-inf-result"])
def test_non_finite_values_are_refused_naming_file_column_and_row(
        tmp_path: Path, capsys: pytest.CaptureFixture, reference_values: np.ndarray,
        result_values: np.ndarray, bad_file: str, row: int, kind: str) -> None:
    reference = _samples(tmp_path, "ref.csv", reference_values)
    result = _samples(tmp_path, "res.csv", result_values)
    assert cli.main(["compare", str(reference), str(result)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert str(tmp_path / bad_file) in err and f"{kind} in signal(s) theta" in err
    assert f"at row {row}:" in err


def test_non_finite_time_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_text("time,x\n0,1\ninf,2\n")
    with pytest.raises(ValueError, match=r"bad.csv has \+inf in signal\(s\) time.* row 2"):
        read_result(path)


def test_plot_onto_a_fifo_or_a_device_node_leaves_the_node(
        tmp_path: Path, reference: Path, capsys: pytest.CaptureFixture) -> None:
    """compare --plot onto a FIFO or a device node exits 2 with one line and leaves the node
    as it is, not replaced by a PNG. The nodes are made in tmp_path (never the system's
    /dev/null, which a regression run as root would replace); a device node only where
    mknod is allowed."""
    nodes = [tmp_path / "fifo"]
    os.mkfifo(nodes[0])
    with contextlib.suppress(PermissionError):
        os.mknod(tmp_path / "null", stat.S_IFCHR | 0o666, os.makedev(1, 3))
        nodes.append(tmp_path / "null")
    for node in nodes:
        assert cli.main(["compare", str(reference), str(reference), "--plot", str(node)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and f"cannot write {node}: it is not a regular file" in err
    assert stat.S_ISFIFO(nodes[0].stat().st_mode)
    assert all(stat.S_ISCHR(node.stat().st_mode) for node in nodes[1:])


def test_plot_to_a_folder_or_a_read_only_place_is_one_line(
        tmp_path: Path, reference: Path, capsys: pytest.CaptureFixture,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A plot to a folder or to a read-only mount is one line naming the place, not a
    traceback (IsADirectoryError, PermissionError)."""
    assert cli.main(["compare", str(reference), str(reference), "--plot", str(tmp_path)]) == 2
    assert f"cannot write {tmp_path}: it is a folder" in capsys.readouterr().err
    # a read-only mount (the tests may run as root, whom file modes do not stop)
    def read_only(*_args: object, **_kwargs: object) -> None:
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    plot = tmp_path / "report.png"
    assert cli.main(["compare", str(reference), str(reference), "--plot", str(plot)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: cannot write {plot}: Read-only file system"
    assert not plot.exists()


def refused(argv: list[str], capsys: pytest.CaptureFixture) -> str:
    """The one error line of a refused compare (exit 2)."""
    assert cli.main(["compare", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    return err


def test_a_result_lacking_a_reference_signal_is_refused_naming_it(
        tmp_path: Path, reference: Path, capsys: pytest.CaptureFixture) -> None:
    """It exited 0 on a result holding only one of the reference's signals."""
    only_e = write(tmp_path / "only_e.csv", pd.read_csv(reference)[["time", "E"]])
    assert "lacks the reference's signal(s) theta" in refused(
        [str(reference), str(only_e)], capsys)
    assert cli.main(["compare", str(reference), str(only_e), "--signals", "E"]) == 0


@pytest.mark.parametrize("names", [("theta", "theta "), ("theta", "Theta"), ("theta", "theta")])
def test_near_duplicate_columns_are_refused_naming_them(
        tmp_path: Path, reference: Path, capsys: pytest.CaptureFixture,
        names: tuple[str, str]) -> None:
    """A second, wrong theta column (equal, or but for case or blanks) was skipped or read as
    theta.1, and the comparison passed."""
    frame = pd.read_csv(reference)
    path = tmp_path / "twice.csv"
    path.write_text(f'"time","{names[0]}","E","{names[1]}"\n' + "".join(
        f"{t},{y},{e},{-y}\n" for t, y, e in zip(frame.time, frame.theta, frame.E)))
    err = refused([str(reference), str(path)], capsys)
    assert repr(names[0]) in err and repr(names[1]) in err


def test_a_fifo_or_an_endless_device_is_refused_before_reading(
        tmp_path: Path, reference: Path, capsys: pytest.CaptureFixture) -> None:
    """A FIFO as the reference waited for ever; /dev/zero read without end."""
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    assert "not a regular file" in refused([str(fifo), str(reference)], capsys)
    assert "not a regular file" in refused([str(reference), "/dev/zero"], capsys)


def test_a_file_beyond_the_size_bound_is_refused(tmp_path: Path, reference: Path,
                                                 capsys: pytest.CaptureFixture,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    from harness.run import compare as compare_module
    monkeypatch.setattr(compare_module, "MAX_BYTES", 100)
    assert "more than the 100 a result file may have" in refused(
        [str(reference), str(reference)], capsys)
