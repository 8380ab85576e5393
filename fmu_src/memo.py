"""Derived constants on a mechanism's frozen `Parameters` (standard library only).

A derived constant is a value the fields determine (an inertia sum, an efficiency, the
linkage an inner loop reads), set by `derive(self, name=value, ...)` in the
`Parameters.__post_init__`, that is while `__init__` runs, and read as a plain attribute.

Rules:

- Set every derived constant in `__post_init__`, never later: the fields and these
  attributes then share the instance layout that CPython specialises attribute reads for.
  An attribute added after `__init__` (a `functools.cached_property` writes the instance
  `__dict__`) turns every later read of every field into a dictionary look-up, slower in
  each RK4 stage. So a derived constant is computed eagerly.
- A derived constant is computed before `validate` sees the fields, so it must not raise
  for values `validate` rejects (a division by a zero field, a power that overflows): one
  that may is `unless_rejected(lambda: ...)`, NaN where it raises, and `validate` then
  names the field.
- The one exception is a constant too costly to compute at every construction (a design
  optimisation, tens of milliseconds) that an evaluation for rejected values may make
  raise: it is a `functools.cached_property`, computed at its first read, and the
  instance's field reads are slower from then on.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any


def derive(instance: Any, **values: Any) -> None:
    """Set the derived constants `values` on a frozen dataclass instance, in its
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
