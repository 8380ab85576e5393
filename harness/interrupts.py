"""Ctrl-C (SIGINT) where FMU code runs: at a point the harness chooses, never midway.

A KeyboardInterrupt raised at a random point lands in an FMU's Python code (which the FMU's
runtime then reports as a failed FMI call, or inside the FMI logger callback, where ctypes
prints and drops it), amid a scenario's writes, or in a worker process idle in its queue (a
traceback). So:

- `deferred()`: while inside, a SIGINT only sets `requested`; the code checks it at safe
  points (`stop_if_requested`), and leaving raises KeyboardInterrupt if one came, also in
  place of an error raised meanwhile (an FMU call the interrupt made fail);
- `blocked()`: processes and threads started inside get SIGINT blocked (the mask is
  inherited through fork and exec), so a worker never sees the Ctrl-C its parent handles.

`python -m harness` prints a KeyboardInterrupt as one line and exits with 130.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Protocol


class Flag(Protocol):
    """threading.Event here, a multiprocessing Event shared with worker processes."""

    def is_set(self) -> bool: ...

    def set(self) -> None: ...

    def clear(self) -> None: ...


requested: Flag = threading.Event()  # a SIGINT came (in a worker: its parent asks it to stop)


def stop_if_requested() -> None:
    """KeyboardInterrupt if an interrupt was requested."""
    if requested.is_set():
        raise KeyboardInterrupt


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """SIGINT sets `requested` while inside; leaving raises KeyboardInterrupt if it is set
    (in place of an Exception raised meanwhile). Only in the main thread (the one that gets
    signals), and not if SIGINT is ignored (e.g. a job started in the background)."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        yield
        return
    requested.clear()
    previous = signal.signal(signal.SIGINT, lambda _signal, _frame: requested.set())
    try:
        yield
    except Exception:
        if not requested.is_set():
            raise
    finally:
        signal.signal(signal.SIGINT, previous)
    stop_if_requested()


@contextlib.contextmanager
def blocked() -> Iterator[None]:
    """SIGINT blocked in this thread while inside (and in what it starts: for good); one that
    comes meanwhile is delivered on leaving."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def ignore_in_worker(flag: Flag) -> None:
    """A worker process's initializer: SIGINT ignored (its parent decides, and tells it
    through flag, which `stop_if_requested` then reads)."""
    global requested
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    requested = flag
