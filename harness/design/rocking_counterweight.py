"""`python -m harness rocking-design`: Ciupitu's rocking counterweight (Figure 4b) designed for
the paper's Section 4 example (fmu_src/mechanisms/rocking_counterweight/README.md).

The data are the translational example's (G_pv,max = 4 N at OP = 2 m, counterweight G2 = 3 N,
the parabolic and the linear payload law over the workspace phi in [-pi/2, pi/2]); the
design variables are the paper's for Figure 4b: the pivot A (x1A, y1A) on the arm, the
ground pivot C (XC, YC), the bars AB and BC, the counterweight's place AC2 on its bar, and
the assembly branch B_left.

Objective: the unbalanced moment in the least-squares sense, the mean of M_u^2 over
SAMPLES equally spaced arm angles of the workspace (scipy SLSQP). Constraints, our design
rules: every length and coordinate within OP (the counterweight stays within the arm's
reach; the shortest bar is at least 5 % of OP), and a transmission angle (between the bars
at B) within [MU_MIN, pi - MU_MIN] over a full turn of the arm, so the linkage moves through
every angle with bar forces bounded. The problem has many local minima: MULTISTART starts
per branch drawn with a fixed seed, the best kept and rounded to 1e-6 m, so the design is
reproducible. The ciupitu2018 scenario's `*_rocking` variants hold the result
(tests/test_rocking.py checks).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from fmu_src.mechanisms.ciupitu import physics as ciupitu
from fmu_src.mechanisms.rocking_counterweight import physics as rocking
from harness.run import scenario_files as scenarios

SAMPLES = 61                  # arm angles in the least-squares objective
MU_MIN = math.radians(30.0)   # smallest transmission angle over a full turn [rad]
SHORTEST = 0.05               # shortest bar as a fraction of OP
MULTISTART = 12               # local searches per assembly branch
SEED = 2018
VARIABLES = ("x1A", "y1A", "XC", "YC", "AB", "BC", "AC2")
PAPER = ciupitu.ExampleData()  # the paper's data
SCENARIO = "ciupitu2018"
VARIANTS = {"parabolic": "parabolic_rocking", "linear": "linear_rocking"}  # law -> variant


@dataclass(frozen=True)
class Design:
    """A linkage for one payload law and what it achieves over the paper's stroke."""

    law: str
    linkage: rocking.Linkage
    rms_Mu: float                   # N m, RMS of M_u over the workspace samples
    stroke: ciupitu.StrokeResult    # eps (eq. 31) and max |M_u| of one stroke


def transmission_margins(k: rocking.Linkage, mu_min: float = MU_MIN) -> tuple[float, float]:
    """cos(mu_min) - |cos(mu)| at the two extremes of the distance AC over a full turn:
    both are >= 0 when the transmission angle mu stays within [mu_min, pi - mu_min]."""
    low, high = rocking.distance_range(k)
    cos_mu = [(k.AB ** 2 + k.BC ** 2 - d ** 2) / (2.0 * k.AB * k.BC) for d in (low, high)]
    return math.cos(mu_min) - cos_mu[0], math.cos(mu_min) + cos_mu[1]


def unbalance(data: ciupitu.ExampleData, law: str, k: rocking.Linkage) -> np.ndarray:
    """M_u [N m] at SAMPLES arm angles over the workspace (large where it cannot assemble)."""
    shape = ciupitu.PAYLOAD_LAWS[law]
    values = []
    for phi in np.linspace(-0.5 * math.pi, 0.5 * math.pi, SAMPLES).tolist():
        G_pv = data.Gmax * shape(ciupitu.stroke_fraction(phi))
        try:
            values.append(rocking.moments(G_pv, data.OP, data.G2, k, phi).M_u)
        except (ValueError, ZeroDivisionError):  # only at trial points outside the constraints
            values.append(10.0 * data.Gmax * data.OP)
    return np.array(values)


def design(law: str, data: ciupitu.ExampleData = PAPER) -> Design:
    """The linkage minimising the mean M_u^2 over the workspace for one payload law."""
    ciupitu.validate_example(data)
    size = data.OP
    bounds = [(-size, size)] * 4 + [(SHORTEST * size, size)] * 2 + [(-size, size)]
    low = np.array([b[0] for b in bounds])
    high = np.array([b[1] for b in bounds])
    rng = np.random.default_rng(SEED)
    best = None
    for B_left in (True, False):
        def linkage(x: np.ndarray, B_left: bool = B_left) -> rocking.Linkage:
            return rocking.Linkage(*x.tolist(), B_left)

        for _ in range(MULTISTART):
            result = minimize(
                lambda x: float(np.mean(unbalance(data, law, linkage(x)) ** 2)),
                rng.uniform(low, high), method="SLSQP", bounds=bounds,
                constraints=[{"type": "ineq",
                              "fun": lambda x: np.array(transmission_margins(linkage(x)))}],
                options={"maxiter": 300})
            if (result.success and min(transmission_margins(linkage(result.x))) >= -1e-9
                    and (best is None or result.fun < best.fun)):
                best, best_branch = result, B_left
    if best is None:
        raise RuntimeError(f"rocking counterweight design found no feasible linkage for {law}")
    k = rocking.Linkage(*(round(v, 6) for v in best.x.tolist()), best_branch)
    rms = float(np.sqrt(np.mean(unbalance(data, law, k) ** 2)))
    return Design(law, k, rms, rocking.stroke(data, k, law))


def stored_linkage(law: str) -> rocking.Linkage:
    """The linkage the ciupitu2018 scenario's rocking variant of a payload law holds."""
    return rocking.Linkage(**scenarios.load(SCENARIO).variant(VARIANTS[law]).parameters)


def report(designs: list[Design]) -> str:
    """The designs, as the ciupitu2018 scenario's variant parameters and with their stroke."""
    lines = ["Rocking counterweight (Ciupitu 2018, Figure 4b) for the Section 4 example: "
             "G_pv,max = 4 N at OP = 2 m, G2 = 3 N; objective mean M_u^2 over the workspace"]
    for d in designs:
        values = ", ".join(f"{name} = {getattr(d.linkage, name)!r}" for name in VARIABLES)
        lines += [f"{d.law}: {values}, B_left = {str(d.linkage.B_left).lower()}",
                  f"  RMS M_u = {d.rms_Mu:.4f} N m, max |M_u| = {d.stroke.max_abs_Mu:.4f} N m "
                  f"at phi = {d.stroke.phi_max_Mu:.4f} rad, eps = {d.stroke.eps:.6f}"]
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """No options: the data are the paper's (ciupitu.ExampleData defaults)."""


def run(args: argparse.Namespace) -> int:
    print(report([design(law) for law in ciupitu.PAYLOAD_LAWS]))
    return 0
