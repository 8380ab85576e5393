"""Writing result files atomically: any file, a CSV table, a figure.

Every file is written to a temporary file in the target folder and renamed over the old one,
so a crash or a kill never leaves a half-written file. This module imports only the standard
library (pandas and matplotlib come with the objects it writes), so every harness module can
use it without an import cycle.
"""

from __future__ import annotations

import csv
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

FIGURE_DPI = 110  # PNG resolution of every figure the harness writes


def write_atomic(path: Path, write: Callable[[Path], object], mode: int = 0o644,
                 suffix: str = ".tmp") -> Path:
    """Call write(temporary path) in path's folder (made if missing), give the file the
    permission bits mode, then rename it onto path; on any failure the temporary file is
    removed and path is left as it was. suffix ends the temporary name (a writer that infers
    the format from it, e.g. pythonfmu's ".fmu")."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    os.close(fd)
    try:
        write(Path(tmp))
        os.chmod(tmp, mode)  # mkstemp creates 0600; results are meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
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
