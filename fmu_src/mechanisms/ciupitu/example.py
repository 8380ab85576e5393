"""The static example of Ciupitu 2018, Section 4 (standard library only): one stroke of the arm
for a payload law, its efficaciousness eps (eq. 31) and largest unbalanced moment, from the
geometry and moments of `physics`; and the FMU's parameters of the paper's example arm."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from fmu_src.mechanisms.ciupitu.physics import HALF_PI, Parameters
from fmu_src.mechanisms.ciupitu.statics import Moments, _check_bar, _geometry, _moments
from fmu_src.parameters import check_ranges, parameter


@dataclass(frozen=True)
class ExampleData:
    """Data of the paper's Section 4 example (defaults are the paper's)."""

    Gmax: float = parameter(4.0, "N", "Peak of the variable payload weight G_pv,max", min=0.0,
                            min_exclusive=True)
    OP: float = parameter(2.0, "m", "Distance from O to the payload P", min=0.0, min_exclusive=True)
    G2: float = parameter(3.0, "N", "Weight of the sliding counterweight", min=0.0)
    OA: float = parameter(1.0, "m", "Height of the ground pivot A above O", min=0.0)
    AB: float = parameter(2.0, "m", "Length of the bar joining A to the counterweight B", min=0.0,
                          min_exclusive=True)


def validate_example(data: ExampleData) -> None:
    """Raise ValueError naming the first datum that is NaN or outside its range."""
    check_ranges(data)
    _check_bar(data.OA, data.AB)


def stroke_fraction(phi: float) -> float:
    """s = t/T of the uniform rocking at arm angle phi on the stroke +pi/2 -> -pi/2."""
    return (HALF_PI - phi) / (2.0 * math.pi)


# G_pv / G_max as a function of s over the stroke, s in [0, 1/2]
PAYLOAD_LAWS: dict[str, Callable[[float], float]] = {
    "parabolic": lambda s: 4.0 * s * (1.0 - s),
    "linear": lambda s: 2.0 * s,
}


class StrokeResult(NamedTuple):
    """Energies and unbalance of one stroke of the static example."""

    E_u: float            # J, net work of M_g (unbalanced arm)
    E_b: float            # J, net work of M_u (balanced arm)
    eps: float            # efficaciousness 1 - E_b/E_u, eq. 31
    max_abs_Mu: float     # N m
    phi_max_Mu: float     # rad, where |M_u| is largest


def stroke(data: ExampleData, law: str, with_bar: bool = False) -> StrokeResult:
    """Net stroke energies, eps and the largest |M_u| for one payload law of PAYLOAD_LAWS.

    with_bar: the unbalance is M_u + M_bar (the bar's moment counted, as the FMU's torque and
    the rocking counterweight's M_u count it) instead of the paper's M_u."""
    validate_example(data)
    shape = PAYLOAD_LAWS[law]

    def unbalance(phi: float) -> Moments:
        G_pv = data.Gmax * shape(stroke_fraction(phi))
        OB, dOB, _ = _geometry(data.OA, data.AB, phi)
        M = _moments(G_pv, data.OP, data.G2, OB, math.cos(phi))
        if not with_bar:
            return M
        M_b = M.M_b + data.G2 * dOB * math.sin(phi)
        return Moments(M.M_g, M_b, M_b + M.M_g)

    E_u = abs(gauss_legendre(lambda phi: unbalance(phi).M_g, -HALF_PI, HALF_PI))
    E_b = abs(gauss_legendre(lambda phi: unbalance(phi).M_u, -HALF_PI, HALF_PI))
    phi_max = argmax(lambda phi: abs(unbalance(phi).M_u), -HALF_PI, HALF_PI)
    return StrokeResult(E_u, E_b, 1.0 - E_b / E_u, abs(unbalance(phi_max).M_u), phi_max)


# Five-point Gauss-Legendre rule on [-1, 1]
_GL_X = (-math.sqrt(5.0 + 2.0 * math.sqrt(10.0 / 7.0)) / 3.0,
         -math.sqrt(5.0 - 2.0 * math.sqrt(10.0 / 7.0)) / 3.0, 0.0,
         math.sqrt(5.0 - 2.0 * math.sqrt(10.0 / 7.0)) / 3.0,
         math.sqrt(5.0 + 2.0 * math.sqrt(10.0 / 7.0)) / 3.0)
_GL_W = ((322.0 - 13.0 * math.sqrt(70.0)) / 900.0, (322.0 + 13.0 * math.sqrt(70.0)) / 900.0,
         128.0 / 225.0, (322.0 + 13.0 * math.sqrt(70.0)) / 900.0,
         (322.0 - 13.0 * math.sqrt(70.0)) / 900.0)


def gauss_legendre(f: Callable[[float], float], a: float, b: float, panels: int = 64) -> float:
    """Integral of a smooth f over [a, b]: composite 5-point Gauss-Legendre (error ~ h^10)."""
    h = (b - a) / panels
    total = 0.0
    for i in range(panels):
        mid = a + (i + 0.5) * h
        total += sum(w * f(mid + 0.5 * h * x) for x, w in zip(_GL_X, _GL_W))
    return 0.5 * h * total


def argmax(f: Callable[[float], float], a: float, b: float, samples: int = 2001,
           tol: float = 1e-12) -> float:
    """Abscissa of the largest f on [a, b]: a grid search refined by golden-section search."""
    h = (b - a) / (samples - 1)
    best = max(range(samples), key=lambda i: f(a + i * h))
    lo, hi = max(a, a + (best - 1) * h), min(b, a + (best + 1) * h)
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    f1, f2 = f(x1), f(x2)
    while hi - lo > tol:
        if f1 >= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - ratio * (hi - lo)
            f1 = f(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + ratio * (hi - lo)
            f2 = f(x2)
    return 0.5 * (lo + hi)


def paper_example_parameters(data: ExampleData = ExampleData(), g: float = 9.81) -> Parameters:
    """Parameters of the paper's example arm: payload at OP, counterweight G2/g, bar OA-AB.

    The paper gives no arm mass or inertia (its weight is balanced by the fixed counterweight
    and drops out), so the arm is massless, without friction, and starts at phi = pi/2.
    """
    validate_example(data)
    return Parameters(m=0.0, c=0.0, J_link=0.0, w=data.OP, m2=data.G2 / g, OA=data.OA,
                      AB=data.AB, m_fixed_cw=0.0, c_fixed_cw=0.0, d_link=0.0, g=g,
                      theta0=0.0, omega0=0.0)
