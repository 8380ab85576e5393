"""Writing result files atomically: any file, a CSV table, a figure.

Every file is written to a temporary file in the target folder and renamed over the old one,
so a crash or a kill never leaves a half-written file. Only a regular file or a new path is
written: a FIFO, a device node (/dev/null) or a folder at the path is refused, never replaced.
A write that fails (a full disk, a read-only folder) is a UserError naming the path, and the
old file stays as it was. This module imports only the standard library and harness.errors
(pandas and matplotlib come with the objects it writes), so every harness module can use it
without an import cycle.
"""

from __future__ import annotations

import csv
import os
import stat
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from harness.errors import UserError

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

FIGURE_DPI = 110  # PNG resolution of every figure the harness writes


def check_target(path: Path) -> None:
    """UserError unless path is a regular file (or a link to one) or does not exist yet:
    a rename onto a FIFO, a device node or a socket would replace the node, onto a folder
    fail."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return  # a new path (or a dangling link, which the rename replaces)
    except OSError as error:
        raise UserError(f"cannot write {path}: {error.strerror or error}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file (a device, FIFO or socket)"
        raise UserError(f"cannot write {path}: it is {kind}; give a regular file or a new path")


def write_atomic(path: Path, write: Callable[[Path], object], mode: int = 0o644,
                 suffix: str = ".tmp") -> Path:
    """Call write(temporary path) in path's folder (made if missing), give the file the
    permission bits mode, then rename it onto path; on any failure the temporary file is
    removed and path is left as it was. suffix ends the temporary name (a writer that infers
    the format from it, e.g. pythonfmu's ".fmu"). UserError naming path when path is not a
    regular file or new (check_target) or when the folder or the write fails with an OSError
    (no space left, permission denied)."""
    check_target(path)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
        os.close(fd)
        write(Path(tmp))
        os.chmod(tmp, mode)  # mkstemp creates 0600; results are meant to be shared
        check_target(path)  # again: a node may have appeared while writing
        os.replace(tmp, path)
    except BaseException as error:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        if not isinstance(error, OSError):
            raise
        other = (f" ({error.filename})" if error.filename is not None  # e.g. a source file
                 and Path(error.filename).parent != path.parent else "")
        raise UserError(f"cannot write {path}: {error.strerror or error}{other}") from None
    return path


def write_csv(frame: pd.DataFrame, path: Path) -> Path:
    """Write a table with a quoted header and full-precision numbers (10 significant
    digits), atomically; read it back with pandas.read_csv."""
    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            csv.writer(f, quoting=csv.QUOTE_ALL).writerow(frame.columns)
            frame.to_csv(f, header=False, index=False, float_format="%.10g")
    return write_atomic(path, write)


def save_figure(fig: Figure, path: Path) -> Path:
    """Write a figure as PNG atomically; a pyplot figure is closed after (a
    matplotlib.figure.Figure made without pyplot needs no closing)."""
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=FIGURE_DPI, format="png"))
    pyplot = sys.modules.get("matplotlib.pyplot")  # imported by whoever made a pyplot figure
    if pyplot is not None:
        pyplot.close(fig)
    return path
