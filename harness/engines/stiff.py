"""The stiff solve the continuous engines share (the monolithic reference, Model Exchange):
scipy's Radau with a finite-difference Jacobian whose steps stay bounded.

Why not scipy's own: its `num_jac` multiplies a state's difference step by 10 at every
Jacobian it makes while that state's column stays below round-off, with no upper bound. A
state that no rate depends on (an energy account: a drive's E_drawn, a mechanism's E_loss
or W_drive) has a zero column for ever, so its step grows until the trial state is 1e6 J,
then infinite: the solve ends in `array must not contain infs or NaNs`, or an FMU refuses
the state and the run fails (franchetti2021's realistic sets, its unbalanced link in Model
Exchange). Here each column's step is sqrt(eps) max(|y_j|, 1) in the state's SI unit, the
typical-size rule of Dennis and Schnabel (Numerical Methods for Unconstrained Optimization,
5.4): the Jacobian only steers Radau's Newton iteration, so its error costs iterations, not
accuracy, which the solver's tolerances alone set.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

Rates = Callable[[float, np.ndarray], np.ndarray]
SQRT_EPS = float(np.sqrt(np.finfo(float).eps))


def jacobian(rates: Rates) -> Callable[[float, np.ndarray], np.ndarray]:
    """The forward-difference Jacobian of rates(t, y) with bounded steps (module docstring)."""
    def jac(t: float, y: np.ndarray) -> np.ndarray:
        at = np.asarray(rates(t, y))
        out = np.empty((len(y), len(y)))
        for j in range(len(y)):
            shifted = y.copy()
            shifted[j] += SQRT_EPS * max(abs(y[j]), 1.0)
            out[:, j] = (np.asarray(rates(t, shifted)) - at) / (shifted[j] - y[j])
        return out
    return jac


def solve(rates: Rates, span: tuple[float, float], y0: np.ndarray, rtol: float,
          atol: float, **options: Any) -> Any:
    """solve_ivp's Radau over span [s] from y0 with the bounded Jacobian; options as
    solve_ivp's (t_eval, events, dense_output)."""
    return solve_ivp(rates, span, y0, method="Radau", rtol=rtol, atol=atol,
                     jac=jacobian(rates), **options)
