"""The rocking counterweight's linkage and its statics (Ciupitu 2018, Figure 4b; standard
library only): the counterweight's position and its first two derivatives in the arm angle,
the static moments about O, and the paper's static stroke (Section 4) with this
counterweight. The geometry and the symbols are in physics.py's docstring and README.md;
`physics` builds the arm's dynamics on `geometry`."""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from fmu_src.mechanisms.ciupitu import example as paper_example
from fmu_src.parameters import DomainError

HALF_PI = 0.5 * math.pi


# ---- the linkage ------------------------------------------------------------------------
class Linkage(NamedTuple):
    """The rocking counterweight's linkage, lengths in m (see the module docstring)."""

    x1A: float      # bar 2's pivot A on the arm, along the arm towards the payload
    y1A: float      # and across it (upwards when the arm is horizontal)
    XC: float       # ground pivot C of bar 3, horizontal (towards the payload's side)
    YC: float       # and vertical
    AB: float       # bar 2, from A to the joint B with bar 3
    BC: float       # bar 3
    AC2: float      # counterweight's position on bar 2 from A along A -> B (signed)
    B_left: bool    # B on the left of the line from A to C (else on its right)

    @classmethod
    def of(cls, source: Any) -> Linkage:
        """The linkage fields of any object that has them (Parameters, a design)."""
        return cls(*(getattr(source, name) for name in cls._fields))


class Geometry(NamedTuple):
    """Counterweight position P (paper's frame) and its first two derivatives in phi."""

    X: float
    Y: float
    dX: float       # m/rad
    dY: float
    d2X: float      # m/rad^2
    d2Y: float
    psi: float      # rad, angle of bar 2 (A -> B) from the arm's x_1 axis, counter-clockwise


def distance_range(k: Linkage) -> tuple[float, float]:
    """Smallest and largest distance AC [m] over a full turn of the arm."""
    OA, OC = math.hypot(k.x1A, k.y1A), math.hypot(k.XC, k.YC)
    return abs(OA - OC), OA + OC


def check_linkage(k: Linkage) -> None:
    """Raise ValueError unless the triangle A-B-C stays proper over a full turn of the arm."""
    if not (k.AB > 0.0 and k.BC > 0.0):
        raise ValueError(f"AB = {k.AB} m and BC = {k.BC} m must be positive")
    low, high = distance_range(k)
    if not (abs(k.AB - k.BC) < low and high < k.AB + k.BC):
        raise ValueError(
            f"bars AB = {k.AB} m and BC = {k.BC} m must satisfy |AB - BC| < |OA - OC| = "
            f"{low} m and OA + OC = {high} m < AB + BC (OA from x1A = {k.x1A} m, y1A = "
            f"{k.y1A} m; OC from XC = {k.XC} m, YC = {k.YC} m), so that the linkage moves "
            "through every arm angle without locking")


def geometry(k: Linkage, phi: float) -> Geometry:
    """Counterweight position and derivatives at arm angle phi from the horizontal [rad]."""
    x1A, y1A, XC, YC, AB, BC, r, B_left = k   # one unpacking: a field read costs more
    cos_p, sin_p = math.cos(phi), math.sin(phi)
    Ax, Ay = x1A * cos_p - y1A * sin_p, x1A * sin_p + y1A * cos_p
    dAx, dAy = -Ay, Ax                      # A' = perp(A); A'' = -A
    dx, dy = XC - Ax, YC - Ay
    D = math.hypot(dx, dy)
    cos_a = (AB * AB + D * D - BC * BC) / (2.0 * AB * D)
    if not -1.0 < cos_a < 1.0:
        raise DomainError(f"the linkage cannot be assembled at phi = {phi} rad")
    sin_a = math.sqrt(1.0 - cos_a * cos_a) * (1.0 if B_left else -1.0)
    ex, ey = dx / D, dy / D
    ubx, uby = cos_a * ex - sin_a * ey, cos_a * ey + sin_a * ex       # u(beta)
    udx, udy = (Ax + AB * ubx - XC) / BC, (Ay + AB * uby - YC) / BC   # u(delta)
    s = ubx * udy - uby * udx                                         # sin(delta - beta)
    c = ubx * udx + uby * udy                                         # cos(beta - delta)
    db = -(dAx * udx + dAy * udy) / (AB * s)
    dd = -(dAx * ubx + dAy * uby) / (BC * s)
    d2b = (AB * db * db * c - BC * dd * dd + (Ax * udx + Ay * udy)) / (AB * s)
    # in field order, built by tuple.__new__: Geometry(...) is a Python call, and this runs
    # four times a sub-step
    return tuple.__new__(Geometry, (
        Ax + r * ubx, Ay + r * uby,                                               # X, Y
        dAx - r * db * uby, dAy + r * db * ubx,                                   # dX, dY
        -Ax + r * (-d2b * uby - db * db * ubx),                                   # d2X
        -Ay + r * (d2b * ubx - db * db * uby),                                    # d2Y
        math.atan2(uby * cos_p - ubx * sin_p, ubx * cos_p + uby * sin_p)))        # psi


class Moments(NamedTuple):
    """Static moments about O in the paper's convention (positive towards increasing phi)."""

    M_g: float      # N m, payload, eq. 8
    M_b: float      # N m, counterweight and its bars, -G2 dY_P/dphi
    M_u: float      # N m, unbalance M_b + M_g, eq. 16


def moments(G_pv: float, OP: float, G2: float, k: Linkage, phi: float) -> Moments:
    """M_g, M_b, M_u for payload weight G_pv [N] at OP [m] and counterweight G2 [N]."""
    return _moments(G_pv, OP, G2, geometry(k, phi).dY, math.cos(phi))


def _moments(G_pv: float, OP: float, G2: float, dY: float, cos_phi: float) -> Moments:
    """moments() for a known dY_P/dphi [m/rad] and cos(phi)."""
    M_g = -G_pv * OP * cos_phi
    M_b = -G2 * dY
    return tuple.__new__(Moments, (M_g, M_b, M_b + M_g))  # Moments(...) is a Python call


# ---- static example of the paper (Section 4), with a rocking counterweight ----------------
def stroke(data: paper_example.ExampleData, k: Linkage, law: str) -> paper_example.StrokeResult:
    """Net stroke energies, eps (eq. 31) and the largest |M_u| for one payload law of
    paper_example.PAYLOAD_LAWS, read as for the translational counterweight
    (paper_example.stroke); the data's OA and AB are the translational bar's and are not
    used."""
    paper_example.validate_example(data)
    check_linkage(k)
    shape = paper_example.PAYLOAD_LAWS[law]

    def unbalance(phi: float) -> Moments:
        G_pv = data.Gmax * shape(paper_example.stroke_fraction(phi))
        return moments(G_pv, data.OP, data.G2, k, phi)

    E_u = abs(paper_example.gauss_legendre(lambda phi: unbalance(phi).M_g, -HALF_PI, HALF_PI))
    E_b = abs(paper_example.gauss_legendre(lambda phi: unbalance(phi).M_u, -HALF_PI, HALF_PI))
    phi_max = paper_example.argmax(lambda phi: abs(unbalance(phi).M_u), -HALF_PI, HALF_PI)
    return paper_example.StrokeResult(E_u, E_b, 1.0 - E_b / E_u, abs(unbalance(phi_max).M_u),
                                phi_max)
