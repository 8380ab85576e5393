"""Derived constants and one-entry memo slots on a mechanism's frozen `Parameters` (standard
library only).

Both are attributes beyond the dataclass fields, set by `derive(self, name=value, ...)` in
the `Parameters.__post_init__`, that is while `__init__` runs:

- A derived constant is a value the fields determine (an inertia sum, an efficiency, a
  tuple of what an inner loop reads), computed once there and read as a plain attribute.
- A one-entry slot, `slot(empty)`, is a one-element list holding one tuple: a key and what
  was computed for it (for example `(theta, payload, terms)`), `empty` until the first
  write. A reader compares the key and takes the rest; a writer replaces the entry with one
  assignment, `p._slot[0] = (key, ..., value)`.

Rules:

- Set every attribute in `__post_init__`, never later: the fields and these attributes then
  share the instance layout that CPython specialises attribute reads for. An attribute
  added after `__init__` (a `functools.cached_property` writes the instance `__dict__`)
  turns every later read of every field into a dictionary look-up, slower in each RK4
  stage. So a derived constant is computed eagerly, and a slot exists from the start.
- A derived constant is computed before `validate` sees the fields, so it must not raise
  for values `validate` rejects (a division by a zero field, a power that overflows): one
  that may is `unless_rejected(lambda: ...)`, NaN where it raises, and `validate` then
  names the field.
- The one exception is a constant too costly to compute at every construction (a design
  optimisation, tens of milliseconds) that an evaluation for rejected values may make
  raise: it is a `functools.cached_property`, computed at its first read, and the
  instance's field reads are slower from then on.
- A key is compared by identity (`is`) where the very object comes back (the state a step
  ended in and the next starts from, an input held over many steps, an angle an RK4 stage
  passes on): the comparison costs no arithmetic, and the entry holds a reference to the
  key, so its identity cannot be reused by another object while it is kept. A key is
  compared by equality (`==`) where equal values give the same terms (a payload in kg) and
  a new float object arrives at every step. A key of `None` (or NaN, which equals
  nothing) in `empty` matches nothing.
- The entry is one tuple, replaced by one assignment of a list item: a thread reading the
  slot meanwhile gets the old entry or the new one, never the key of one with the value
  of another, and no lock is needed. The list, not the attribute, is what changes, so the
  frozen instance stays frozen and its layout stays the same.
- A slot of two entries keeps the latest first: a write moves entry 0 to 1, then writes
  entry 0, two assignments of whole entries, so a reader still never sees a mixed one.
- The slots belong to the parameters object: instances never share them, and equal
  parameters built apart do not share what they keep.

The slots pay their way with the integration kernels they serve (fmu_src/integration.py:
together, 36 to 99 % of a closed-loop step, measured with callgrind).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any


def derive(instance: Any, **values: Any) -> None:
    """Set the derived constants and slots `values` on a frozen dataclass instance, in its
    `__post_init__` (see the module's rules), in the order given."""
    for name, value in values.items():
        object.__setattr__(instance, name, value)


def unless_rejected(compute: Callable[[], float]) -> float:
    """compute(), or NaN where it raises ArithmeticError (a division by zero, an overflow):
    a derived constant of field values that `validate` rejects."""
    try:
        return compute()
    except ArithmeticError:
        return math.nan


def slot(empty: tuple, entries: int = 1) -> list[tuple]:
    """A memo slot of `entries` entries (one unless a caller alternates between two keys),
    each `empty` (a key that matches nothing, and placeholders) until written."""
    return [empty] * entries
