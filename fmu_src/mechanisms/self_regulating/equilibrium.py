"""Where the self-regulating balancer's released slider comes to rest (standard library only):
the static equilibrium of the free slider along the link, from the model's slider forces.
`model` holds the forces; `design` the statics of the balanced link and the design rule."""

from __future__ import annotations

from fmu_src.mechanisms.self_regulating.design import _free_length_factor, spring_length
from fmu_src.mechanisms.self_regulating.model import (
    Inputs,
    Parameters,
    _slider_force,
    slider_damping,
    wire_tension,
)


def regulated_slider_position(p: Parameters, u: Inputs, theta: float) -> float:
    """Static equilibrium of a free slider at angle theta with the pulley turning [m].

    Solves F_t(theta, b) = T_wire + m_slider g (-cos theta) for b (bisection on the monotonic
    spring force), clipped to the end stops. With L0 = 0 and theta = pi this is
    b0 + payload w g / (k a) (eq. 8) when counterweight_added equals the payload.
    """
    def net(b: float) -> float:
        if spring_length(p, theta, b) == 0.0:
            return 1.0
        return _slider_force(p, theta, 0.0, b, 0.0, _free_length_factor(p, theta, b),
                             wire_tension(p, u), slider_damping(p, u))
    lo, hi = p.b_min, p.b_max
    if net(lo) <= 0.0:
        return lo
    if net(hi) >= 0.0:
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if net(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
