"""harness.io: a file is replaced whole or not at all, with the permissions asked for; CSV
tables read back as written; figures are written as PNG and pyplot's are closed."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from harness.errors import UserError  # noqa: E402
from harness.io import save_figure, write_atomic, write_csv  # noqa: E402


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    path = tmp_path / "result.txt"
    path.write_text("old")

    def half_written(tmp: Path) -> None:
        tmp.write_text("ne")
        raise KeyboardInterrupt  # a kill half way

    with pytest.raises(KeyboardInterrupt):
        write_atomic(path, half_written)
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["result.txt"]


def test_the_written_file_has_the_mode_and_the_temporary_the_suffix(tmp_path: Path) -> None:
    """0o644 by default (mkstemp makes 0o600); a binary 0o755; a writer that infers the
    format from the name (pythonfmu's .fmu) sees the suffix asked for."""
    seen = []

    def write(tmp: Path) -> None:
        seen.append(tmp)
        tmp.write_bytes(b"x")

    plain = write_atomic(tmp_path / "sub" / "a.csv", write)
    binary = write_atomic(tmp_path / "tool", write, mode=0o755, suffix=".fmu")
    assert stat.S_IMODE(plain.stat().st_mode) == 0o644
    assert stat.S_IMODE(binary.stat().st_mode) == 0o755
    assert seen[0].parent == tmp_path / "sub" and seen[0].name.startswith(".a.csv.")
    assert seen[1].suffix == ".fmu" and not seen[1].exists()


def test_csv_reads_back_with_quoted_header_and_ten_digits(tmp_path: Path) -> None:
    frame = pd.DataFrame({"time": [0.0, 0.001], "theta": [1.0 / 3.0, -2.5e-12],
                          "locked": [0, 1]})
    path = write_csv(frame, tmp_path / "run.csv")
    assert path.read_text().splitlines()[0] == '"time","theta","locked"'
    back = pd.read_csv(path)
    assert list(back.columns) == list(frame.columns)
    assert back.theta.tolist() == pytest.approx(frame.theta.tolist(), rel=5e-10)
    assert back.theta.iloc[0] != frame.theta.iloc[0]  # 10 significant digits, not 17
    assert back.locked.tolist() == [0, 1]


def test_save_figure_writes_a_png_and_closes_a_pyplot_figure(tmp_path: Path) -> None:
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    path = save_figure(fig, tmp_path / "plot.png")
    assert path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert not plt.fignum_exists(fig.number)


def test_a_full_disk_is_one_line_naming_the_path_and_keeps_the_old_file(
        tmp_path: Path) -> None:
    """A write failing with ENOSPC is one line naming the path, not a traceback (an
    OSError), and the file keeps its old content."""
    path = tmp_path / "summary.csv"
    path.write_text("old")

    def disk_full(tmp: Path) -> None:
        tmp.write_text("ne")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(UserError) as refused:
        write_atomic(path, disk_full)
    assert str(refused.value) == f"cannot write {path}: No space left on device"
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.csv"]


def test_only_a_regular_file_or_a_new_path_is_written(tmp_path: Path) -> None:
    """A FIFO or a folder at the path is refused and left as it was; a regular file, a link
    to one and a new path are written."""
    fifo, folder = tmp_path / "fifo", tmp_path / "folder"
    os.mkfifo(fifo)
    folder.mkdir()
    for node, kind in ((fifo, "not a regular file"), (folder, "a folder")):
        with pytest.raises(UserError, match=f"cannot write {node}: it is {kind}"):
            write_atomic(node, lambda tmp: tmp.write_text("x"))
    assert stat.S_ISFIFO(fifo.stat().st_mode) and list(folder.iterdir()) == []
    regular, link = tmp_path / "regular", tmp_path / "link"
    regular.write_text("old")
    link.symlink_to(regular)
    for path in (regular, link, tmp_path / "new"):
        assert write_atomic(path, lambda tmp: tmp.write_text("new")).read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo", "folder", "link", "new",
                                                          "regular"]
