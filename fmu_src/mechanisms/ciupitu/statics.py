"""The translational counterweight's geometry and the paper's static moments (Ciupitu 2018,
Figure 4a, eqs. 8, 12, 13 and 16; standard library only): the counterweight's distance OB and
its first two derivatives in the arm angle, and the moments about O. The symbols and the
equations are in physics.py's docstring and README.md; `physics` builds the arm's dynamics on
them and `example` the paper's static stroke."""

from __future__ import annotations

import math
from typing import NamedTuple


def _check_bar(OA: float, AB: float) -> None:
    if not AB > OA:
        raise ValueError(f"AB = {AB} m must be above OA = {OA} m (eq. 13 needs AB > OA)")


# ---- geometry and the paper's moments ---------------------------------------------------
class Geometry(NamedTuple):
    """Counterweight distance OB and its derivatives with respect to phi."""

    OB: float         # m, eq. 13
    dOB: float        # m/rad, dOB/dphi
    d2OB: float       # m/rad^2, d^2 OB/dphi^2


def geometry(OA: float, AB: float, phi: float) -> Geometry:
    """OB(phi) of eq. 13 and its first two derivatives; phi from the horizontal [rad]."""
    return Geometry._make(_geometry(OA, AB, phi))


def _geometry(OA: float, AB: float, phi: float) -> tuple[float, float, float]:
    """geometry() as a plain tuple (the dynamics evaluate it four times per RK4 sub-step)."""
    sin_p, cos_p = math.sin(phi), math.cos(phi)
    root = math.sqrt(AB * AB - (OA * cos_p) ** 2)
    d_root = OA * OA * sin_p * cos_p / root
    d2_root = (OA * OA * math.cos(2.0 * phi) - d_root * d_root) / root
    return root - OA * sin_p, d_root - OA * cos_p, d2_root + OA * sin_p


class Moments(NamedTuple):
    """Static moments about O in the paper's convention (positive towards increasing phi)."""

    M_g: float        # N m, payload, eq. 8
    M_b: float        # N m, counterweight weight, eq. 12
    M_u: float        # N m, unbalance M_b + M_g, eq. 16


def moments(G_pv: float, OP: float, G2: float, OA: float, AB: float, phi: float) -> Moments:
    """M_g, M_b, M_u for payload weight G_pv [N] at OP [m] and counterweight G2 [N]."""
    return _moments(G_pv, OP, G2, geometry(OA, AB, phi).OB, math.cos(phi))


def _moments(G_pv: float, OP: float, G2: float, OB: float, cos_phi: float) -> Moments:
    """moments() for a known OB [m] and cos(phi)."""
    M_g = -G_pv * OP * cos_phi
    M_b = G2 * OB * cos_phi
    return tuple.__new__(Moments, (M_g, M_b, M_b + M_g))  # Moments(...) is a Python call
