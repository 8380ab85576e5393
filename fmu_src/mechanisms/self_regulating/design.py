"""Statics and design rule of the self-regulating balancer (standard library only).

The spring's geometry and the gravity moment, which `model` and `physics` use too, and the
design for a real spring and slider (docs/energy_ledger.md, "Design rule"): the residual
torque over a full turn, the slider position that balances a payload, the position the
counterweight M0 holds (Parameters.b_design) and the counterweight that reaches a position.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmu_src.mechanisms.self_regulating.model import Parameters

def spring_length(p: Parameters, theta: float, b: float) -> float:
    """Distance A-B, eq. 4 [m]."""
    return math.sqrt(max(p.a * p.a + b * b - 2.0 * p.a * b * math.cos(theta), 0.0))


def _free_length_factor(p: Parameters, theta: float, b: float) -> float:
    """(1 - L0/x): scales the zero-free-length force laws to a spring of free length L0.

    x is computed only when L0 > 0: the ideal spring needs no square root per evaluation.
    """
    return 1.0 - p.L0 / spring_length(p, theta, b) if p.L0 > 0.0 else 1.0


def gravity_moment(p: Parameters, payload: float, b: float) -> float:
    """(m c + payload w + m_slider b) g: gravity moment amplitude on the link [N m]."""
    return (p.m * p.c + payload * p.w + p.m_slider * b) * p.g


_TURN_SAMPLES = 72    # trapezoid rule over a full turn: exact for the low harmonics here


def residual_torque_rms(p: Parameters, payload: float, b: float) -> float:
    """RMS over a full turn of the link of tau_gravity with the slider locked at b [N m]."""
    total = 0.0
    for i in range(_TURN_SAMPLES):
        theta = 2.0 * math.pi * (i + 0.5) / _TURN_SAMPLES
        spring = p.k * p.a * b * _free_length_factor(p, theta, b)
        total += ((gravity_moment(p, payload, b) - spring) * math.sin(theta)) ** 2
    return math.sqrt(total / _TURN_SAMPLES)


def balancing_slider_position(p: Parameters, payload: float) -> float:
    """The slider position in [b_min, b_max] that minimises residual_torque_rms [m].

    With L0 = 0 the link balances exactly at b = (m c + payload w) g / (k a - m_slider g)
    (clipped to the stops); a real spring (L0 > 0) balances nowhere exactly, and this is the
    position of least RMS residual torque over the full turn.
    """
    if p.L0 == 0.0:
        stiffness = p.k * p.a - p.m_slider * p.g
        if stiffness <= 0.0:
            return p.b_max
        return min(max((p.m * p.c + payload * p.w) * p.g / stiffness, p.b_min), p.b_max)
    return _minimise(lambda b: residual_torque_rms(p, payload, b), p.b_min, p.b_max)


_DESIGN_PAYLOADS = 8  # intervals of the payload range the design rule averages over


def design_slider_position(p: Parameters) -> float:
    """Where M0 holds the slider at theta = pi, so that regulation (counterweight_added equal
    to the payload) leaves the least residual torque over the working range [m]: the mean of
    residual_torque_rms^2 over a full turn and over nine payloads evenly spaced from 0 to
    k r (b_max - b0) / (g R) (eq. 16's capacity), each at its regulated position
    b + payload g R / (r k).

    With an ideal spring (L0 = 0) the residual is (e0 + e1 payload) sin(theta), e0 = m c g
    - K b, e1 = w g - K g R / (r k), K = k a - m_slider g, and the mean square is least where
    its mean vanishes: b = (m c g + e1 capacity / 2) / K. With R/r = w/a and a massless
    slider e1 = 0: every payload balances exactly from b = m c g / (k a) (eq. 2: b0 for
    Table 1)."""
    if p.g <= 0.0:
        return p.b0  # nothing to balance
    stiffness = p.k * p.a - p.m_slider * p.g
    if p.k <= 0.0 or stiffness <= 0.0:
        return p.b_max  # the spring cannot carry the link
    travel = p.g * p.R / (p.r * p.k)      # slider travel per kg of payload regulated
    capacity = max(p.b_max - p.b0, 0.0) / travel
    if p.L0 == 0.0:
        slope = p.w * p.g - stiffness * travel
        return (p.m * p.c * p.g + 0.5 * capacity * slope) / stiffness
    payloads = [capacity * i / _DESIGN_PAYLOADS for i in range(_DESIGN_PAYLOADS + 1)]

    def mean_square(b: float) -> float:
        return sum(residual_torque_rms(p, m, b + m * travel) ** 2 for m in payloads) / len(
            payloads)
    return _minimise(mean_square, p.b_min, p.b_max)


def _minimise(f: Callable[[float], float], lo: float, hi: float) -> float:
    """Abscissa of the smallest f on [lo, hi] to 1e-9: a 40-interval grid, then golden
    section around its best point."""
    samples = 40
    grid = [lo + (hi - lo) * i / samples for i in range(samples + 1)]
    best = min(range(samples + 1), key=lambda i: f(grid[i]))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, samples)]
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    while hi - lo > 1e-9:
        x1, x2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        if f(x1) <= f(x2):
            hi = x2
        else:
            lo = x1
    return 0.5 * (lo + hi)


def _wire_pull(p: Parameters, b: float) -> float:
    """Wire tension that holds the slider at b with theta = pi, k (a + b - L0) - m_slider g [N]
    (the spring's pull, minus the slider's weight, which hangs outward there)."""
    return p.k * max(p.a + b - p.L0, 0.0) - p.m_slider * p.g


def counterweight_for(p: Parameters, b: float) -> float:
    """counterweight_added that makes regulation at theta = pi settle at b [kg]."""
    return _wire_pull(p, b) * p.r / (p.g * p.R) - p.M0
