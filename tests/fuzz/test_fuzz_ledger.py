"""The energy ledger's bound under hypothesis-drawn runs: for every mechanism, steps whose
inputs sit at the extremes of what the mechanism is built for (efforts at +- full scale or
zero, payloads none or full, locks either way, the active spring's screw with friction and
in its lossless limits; tests/test_ledger_bound.py CASES) or anywhere
between, and step sizes from 0.1 ms to 32 ms. The residual stays within ledger_accuracy
(1e-9) times the energy throughput plus the ledger's rounding at every communication point
(test_ledger_bound.worst_ratio_over, docs/energy_ledger.md).
`make test` runs a few fixed examples, `make fuzz` (HYPOTHESIS_PROFILE=deep) thousands.
"""

from __future__ import annotations

import random
from typing import Any

import fuzzing  # noqa: F401 - registers and loads the hypothesis profiles
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_ledger_bound import CASES, worst_ratio_over


@st.composite
def runs(draw: st.DrawFn, case: str) -> list[tuple[dict[str, Any], float]]:
    """Up to 60 steps: each one's inputs the case's extremes (drawn with a drawn seed) or,
    for its Real efforts, scaled anywhere within them; its step size log-uniform."""
    steps = []
    for _ in range(draw(st.integers(1, 60))):
        inputs = CASES[case][1](random.Random(draw(st.integers(0, 2 ** 32))))
        scale = draw(st.sampled_from((1.0, 0.5, 1e-3)) | st.floats(0.0, 1.0))
        inputs = {name: value * scale if isinstance(value, float) and not name.startswith(
            ("payload", "counterweight")) else value for name, value in inputs.items()}
        steps.append((inputs, 10.0 ** draw(st.floats(-4.0, -1.5))))
    return steps


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_ledger_bound_holds_over_any_run(case: str) -> None:
    """Every case of CASES, the active spring's screws with and without friction among them."""
    @given(runs(case))
    def bound_holds(steps: list[tuple[dict[str, Any], float]]) -> None:
        worst, _ = worst_ratio_over(case, CASES[case][0], steps)
        assert worst <= 1.0, steps

    bound_holds()
