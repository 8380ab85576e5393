"""`python -m harness active-design`: where to move the spring's frame joint B when the payload
changes (Ciupitu 2018, Section 3, Fig. 8, eq. 27).

The paper's symbols are the options; `fmu_src.mechanisms.active_spring.physics` has the model
and the mapping to the project's conventions (phi_1 = pi/2 - theta, the paper's X_B is the
project's -X_B). Eq. 27 has no explicit solution for Y_B' (the paper's eqs. 29-30), so it is
solved numerically: a bracket search outwards from the present Y_B, then Brent's method; of the
roots, the one nearest to Y_B (the smallest adjustment) is returned.

The vertical link. Eq. 27 reads F_s' OA sin(theta' - phi_1) - M_g1 - dM_g = 0; with B on the
vertical through O (X_B = 0) both moments are proportional to cos(phi_1), so where the link
is vertical (cos(phi_1) = 0, franchetti2021 regulates at the hanging position) the equation
holds for every Y_B and says nothing. With X_B = 0 the equation solved is therefore eq. 27
divided by cos(phi_1):

    x1A Y_B' F_s' / l_s' - (m1 OC1 + (m_p + dm_p) w) g = 0

which is exact at every angle and is the limit of eq. 27 / cos(phi_1) at the vertical: the
Y_B' it gives balances the link in the neighbourhood of the vertical (the torque's slope
there vanishes). With X_B != 0 the spring keeps a torque at the vertical, eq. 27 is not
degenerate and is solved as it stands (at the vertical it then asks for F_s' = 0).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from fmu_src.mechanisms.active_spring import model as active_spring
from harness.errors import UserError

# option -> (field of active_spring.Parameters, sign from the paper's frame to the project's,
# help); the defaults are the model's
GEOMETRY_OPTIONS = {
    "m1": ("m", 1.0, "link mass m1 [kg]"),
    "OC1": ("c", 1.0, "distance OC1 from the pivot to the link's centre of mass [m]"),
    "x1A": ("x1A", 1.0, "distance x1A from the pivot to the spring's link joint A [m]"),
    "w": ("w", 1.0, "distance from the pivot to the payload (x1A: the paper's payload at A) "
          "[m]"),
    "k": ("k", 1.0, "spring stiffness k [N/m]"),
    "Fs0": ("F_s0", 1.0, "spring force F_s0 at the length l_s0 (eq. 19) [N]"),
    "ls0": ("l_s0", 1.0, "spring length l_s0 (F_s0 = k l_s0: zero-free-length spring) [m]"),
    "XB": ("X_B", -1.0, "abscissa X_B of the spring's frame joint B, paper's frame [m]"),
    "YB": ("Y_B0", 1.0, "present ordinate Y_B of the frame joint B [m]"),
}
DEFAULT_PAYLOAD_CHANGE = 1.0   # kg, dm_p: franchetti2021's payload
DEFAULT_PHI = 0.0              # deg, the horizontal link
SEARCH_RANGE = 1e4             # the bracket search reaches |Y_B' - Y_B| = SEARCH_RANGE * scale
FIRST_STEP = 1e-4              # its first step, a fraction of scale
ROOT_TOLERANCE = 1e-9          # a sign change is a root if |f| <= this * (M_g + k x1A scale)
BALANCE_TOLERANCE = 1e-6       # and it must balance the gravity moment M_g to this fraction


@dataclass(frozen=True)
class Design:
    """Balancing ordinate of B for a payload at an angle, and the equation it solves."""

    Y_B_new: float       # [m]
    delta_Y_B: float     # Y_B_new - Y_B [m]
    residual: float      # left side of the equation solved at Y_B_new [N m]
    equation: str        # "27" or "27 / cos(phi_1)"
    l_s: float           # spring length at Y_B_new [m]
    F_s: float           # spring force at Y_B_new [N]


def balance_equation(p: active_spring.Parameters, payload: float,
                     theta: float) -> tuple[str, Callable[[float], float]]:
    """The equation solved for Y_B, as (name, left side [N m] as a function of Y_B [m]) in the
    paper's sign (spring moment minus gravity moment)."""
    if p.X_B == 0.0:
        return "27 / cos(phi_1)", lambda Y_B: -active_spring.balance_error(p, payload, theta, Y_B)
    return "27", lambda Y_B: -active_spring.tau_gravity(p, payload, theta, Y_B)


def _scale(p: active_spring.Parameters) -> float:
    """Length scale of the geometry [m]."""
    return max(abs(p.Y_B0), abs(p.X_B), p.x1A, p.l_s0, abs(p.free_length))


def _brackets(f: Callable[[float], float], start: float, scale: float,
              ) -> Iterator[tuple[int, float, float]]:
    """Intervals (step number, lo, hi) where f changes sign or reaches 0, by steps doubling
    outwards on both sides of start, from FIRST_STEP * scale up to SEARCH_RANGE * scale."""
    sides = [(start, f(start)), (start, f(start))]
    step, number = FIRST_STEP * scale, 0
    while step <= SEARCH_RANGE * scale:
        for index, direction in enumerate((1.0, -1.0)):
            previous, previous_value = sides[index]
            y = start + direction * step
            value = f(y)
            if value == 0.0 or value * previous_value < 0.0:
                yield number, min(previous, y), max(previous, y)
            sides[index] = (y, value)
        step *= 2.0
        number += 1


def design(p: active_spring.Parameters, payload: float, theta: float) -> Design:
    """The Y_B nearest to p.Y_B0 that balances payload [kg] at theta [rad] (project
    conventions); UserError if none within SEARCH_RANGE times the geometry's scale."""
    name, f = balance_equation(p, payload, theta)
    scale = _scale(p)
    tolerance = ROOT_TOLERANCE * (active_spring.gravity_moment(p, payload) + p.k * p.x1A * scale)
    roots, found_at = [p.Y_B0] if f(p.Y_B0) == 0.0 else [], None
    for number, lo, hi in ([] if roots else _brackets(f, p.Y_B0, scale)):
        if found_at is not None and number > found_at:
            break   # later brackets lie farther from Y_B than the roots found
        # an end at 0: that end; a bracket Brent's method does not narrow down in its
        # iterations (lengths of 1e50 m) holds no root it can give
        from scipy.optimize import brentq

        root, outcome = brentq(f, lo, hi, xtol=1e-15, rtol=4.0 * 2.0 ** -52,
                               full_output=True, disp=False)
        if outcome.converged and abs(f(root)) <= tolerance:  # not a pole of F_s / l_s,
            roots.append(root)                               # where B meets A
            found_at = number
    if not roots:
        raise UserError(
            f"no Y_B balances the link: eq. {name} keeps one sign within "
            f"{SEARCH_RANGE * scale:g} m of --YB {p.Y_B0:g} for --phi "
            f"{math.degrees(math.pi / 2 - theta):g} deg, --mp + --dmp = {payload:g} kg at --w "
            f"{p.w:g} m; change the spring (--k, --Fs0, --ls0), its joints (--x1A, --XB) or the "
            f"load (--m1, --OC1, --mp, --dmp, --w)")
    Y_B = min(roots, key=lambda y: abs(y - p.Y_B0))
    moment = active_spring.gravity_moment(p, payload)
    if abs(f(Y_B)) > (BALANCE_TOLERANCE * moment if moment > 0.0 else tolerance):
        raise UserError(
            f"no Y_B balances the link in double precision: at Y_B' = {Y_B:g} m eq. {name} "
            f"leaves {f(Y_B):g} N m of the gravity moment {moment:g} N m (allowed "
            f"{BALANCE_TOLERANCE:g} of it); the geometry's lengths (--ls0 {p.l_s0:g}, --YB "
            f"{p.Y_B0:g}, --XB {-p.X_B:g}, --x1A {p.x1A:g} m) are too far apart in magnitude")
    spring = active_spring.spring(p, theta, Y_B)
    return Design(Y_B, Y_B - p.Y_B0, f(Y_B), name, spring.l_s, spring.F_s)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    defaults = active_spring.Parameters()
    for option, (field, sign, text) in GEOMETRY_OPTIONS.items():
        default = sign * getattr(defaults, field) + 0.0   # + 0.0: no "-0.0" in the help
        parser.add_argument(f"--{option}", type=float, default=default,
                            help=f"{text} (default: %(default)s)")
    parser.add_argument("--mp", type=float, default=0.0,
                        help="payload mass m_p balanced at the present Y_B [kg] "
                             "(default: %(default)s)")
    parser.add_argument("--dmp", type=float, default=DEFAULT_PAYLOAD_CHANGE,
                        help="payload change dm_p to balance (eq. 22) [kg] (default: %(default)s)")
    parser.add_argument("--phi", type=float, default=DEFAULT_PHI,
                        help="arm angle phi_1 from the horizontal (eq. 18) [deg] "
                             "(default: %(default)s)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def parameters(args: argparse.Namespace) -> active_spring.Parameters:
    """The model parameters from the options; UserError naming the option when invalid."""
    values = {field: sign * getattr(args, option)
              for option, (field, sign, _) in GEOMETRY_OPTIONS.items()}
    option_of = {field: option for option, (field, _, _) in GEOMETRY_OPTIONS.items()}
    p = active_spring.Parameters(**values)
    try:
        active_spring.validate(p)
    except ValueError as error:  # messages start with the field's name
        field = str(error).split(" ", 1)[0]
        raise UserError(f"option --{option_of.get(field, field)}: {error}") from None
    for option in ("mp", "dmp", "phi"):
        if not math.isfinite(getattr(args, option)):
            raise UserError(f"option --{option} = {getattr(args, option)} is not a finite number")
    if not args.mp >= 0.0:
        raise UserError(f"option --mp = {args.mp} kg is outside [0, inf)")
    if not args.mp + args.dmp >= 0.0:
        raise UserError(f"option --dmp = {args.dmp} kg is outside [-mp, inf) = [{-args.mp}, inf)")
    return p


def run(args: argparse.Namespace) -> int:
    p = parameters(args)
    payload = args.mp + args.dmp
    result = design(p, payload, math.pi / 2 - math.radians(args.phi))
    values = {"Y_B_new": result.Y_B_new, "delta_Y_B": result.delta_Y_B,
              "residual": result.residual, "equation": result.equation,
              "l_s": result.l_s, "F_s": result.F_s}
    if args.json:
        print(json.dumps(values))
        return 0
    print(f"Ciupitu 2018 Fig. 8: payload {args.mp:g} + {args.dmp:g} kg at w = {p.w:g} m, "
          f"phi_1 = {args.phi:g} deg")
    print(f"Y_B = {p.Y_B0:.6f} m -> Y_B' = {result.Y_B_new:.6f} m "
          f"(delta_Y_B = {result.delta_Y_B * 1e3:.3f} mm); spring l_s' = {result.l_s:.6f} m, "
          f"F_s' = {result.F_s:.4f} N; residual of eq. {result.equation}: "
          f"{result.residual:.3g} N m")
    return 0
