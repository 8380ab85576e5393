"""Ctrl-C (SIGINT) and SIGTERM where FMU code runs: at a point the harness chooses, never
midway.

A KeyboardInterrupt raised at a random point lands in an FMU's Python code (which the FMU's
runtime then reports as a failed FMI call, or inside the FMI logger callback, where ctypes
prints and drops it), amid a scenario's writes, or in a worker process idle in its queue (a
traceback). So:

- `deferred()`: while inside, a SIGINT or SIGTERM only sets `requested` (and `received`,
  the signal); the code checks it at safe points (`stop_if_requested`), and leaving raises
  KeyboardInterrupt if one came, also in place of an error raised meanwhile (an FMU call the
  interrupt made fail);
- `blocked()`: processes and threads started inside get SIGINT and SIGTERM blocked (the mask
  is inherited through fork and exec), so a worker never sees the signal its parent handles;
  its parent tells it through a shared flag (`shared`), which the handler sets at once.

`python -m harness` prints a KeyboardInterrupt as one line and exits with 130 (SIGINT) or
143 (SIGTERM).
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


requested: Flag = threading.Event()  # a signal came (in a worker: its parent asks it to stop)
received: int | None = None  # the signal deferred() caught last
SIGNALS = (signal.SIGINT, signal.SIGTERM)


def stop_if_requested() -> None:
    """KeyboardInterrupt if an interrupt was requested."""
    if requested.is_set():
        raise KeyboardInterrupt


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """SIGINT and SIGTERM set `requested` while inside; leaving raises KeyboardInterrupt if
    it is set (in place of an Exception raised meanwhile), and clears it. Only in the main
    thread (the one that gets signals); a signal that is ignored (SIGINT of a job started in
    the background) stays ignored."""
    global received
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    requested.clear()
    received = None

    def handler(signum: int, _frame: object) -> None:
        global received
        received = signum
        requested.set()

    previous = {signum: signal.signal(signum, handler) for signum in SIGNALS
                if signal.getsignal(signum) is not signal.SIG_IGN}
    try:
        yield
    except Exception:
        if not requested.is_set():
            raise
    finally:
        for signum, handled in previous.items():
            signal.signal(signum, handled)
        # answered here (also by a KeyboardInterrupt leaving): what runs after is not stopped
        stop = requested.is_set()
        requested.clear()
    if stop:
        raise KeyboardInterrupt


@contextlib.contextmanager
def shared(flag: Flag) -> Iterator[None]:
    """`requested` is flag while inside (a multiprocessing Event the workers read), so that a
    signal reaches them the moment it comes; a signal that came meanwhile stays requested on
    leaving (flag itself may be set for other reasons: the workers' end)."""
    global requested
    previous = requested
    if previous.is_set():
        flag.set()
    requested = flag
    try:
        yield
    finally:
        requested = previous
        if received is not None:
            previous.set()


@contextlib.contextmanager
def blocked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in this thread while inside (and in what it starts: for
    good); one that comes meanwhile is delivered on leaving."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, set(SIGNALS))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def ignore_in_worker(flag: Flag) -> None:
    """A worker process's initializer: SIGINT and SIGTERM ignored (its parent decides, and
    tells it through flag, which `stop_if_requested` then reads)."""
    global requested
    for signum in SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    requested = flag
