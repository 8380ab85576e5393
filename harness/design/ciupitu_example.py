"""`python -m harness ciupitu-example`: the static example of Ciupitu 2018, Section 4.

One stroke of the arm (phi = +pi/2 -> -pi/2) for the parabolic and the linear payload law:
efficaciousness eps (eq. 31) and the largest unbalanced moment |M_u|. The calculation is
`fmu_src.mechanisms.ciupitu.example.stroke`; see that module for the interpretation of the
paper's numbers. Rows and keys `<law>` are the paper's reading (M_b the weight's moment alone),
`<law>_with_bar` count the bar's moment M_bar too, as the FMU's torque does and as the rocking
counterweight's M_u does: those are the translational figures to compare the rocking ones with.
Beside them (keys and rows `<law>_rocking`), the same stroke with the rocking counterweight of
Figure 4b as the ciupitu2018 scenario holds it (designed by `rocking-design` for the paper's
data, evaluated here with the data given; its OA and AB are not used). """

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import fields

from fmu_src.mechanisms.ciupitu import example as paper_example
from fmu_src.mechanisms.rocking_counterweight import statics
from harness.design import rocking_counterweight as rocking_design
from harness.errors import UserError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    for f in fields(paper_example.ExampleData):
        parser.add_argument(f"--{f.name}", type=float, default=f.default,
                            help=f"{f.metadata['description']} [{f.metadata['unit']}] "
                                 "(default: %(default)s, the paper's)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def results(strokes: dict[str, paper_example.StrokeResult]) -> dict[str, float]:
    """The JSON output: eps, max |M_u| [N m] and where it occurs [rad], per payload law."""
    return {key: value for law, r in strokes.items() for key, value in (
        (f"eps_{law}", r.eps), (f"max_abs_Mu_{law}", r.max_abs_Mu),
        (f"phi_max_Mu_{law}", r.phi_max_Mu))}


def run(args: argparse.Namespace) -> int:
    data = paper_example.ExampleData(**{f.name: getattr(args, f.name)
                                  for f in fields(paper_example.ExampleData)})
    try:
        paper_example.validate_example(data)
    except ValueError as error:  # messages start with the datum's name, i.e. the option's
        raise UserError(f"option --{error}") from None
    strokes = {law: paper_example.stroke(data, law) for law in paper_example.PAYLOAD_LAWS}
    strokes |= {f"{law}_with_bar": paper_example.stroke(data, law, with_bar=True)
                for law in paper_example.PAYLOAD_LAWS}
    strokes |= {f"{law}_rocking": statics.stroke(data, rocking_design.stored_linkage(law), law)
                for law in paper_example.PAYLOAD_LAWS}
    if args.json:
        values = results(strokes)
        undefined = [key for key, value in values.items() if not math.isfinite(value)]
        if undefined:  # e.g. eps with no unbalanced work (E_u = 0): JSON has no NaN or inf
            print(f"note: {', '.join(undefined)} undefined for these data: written as null",
                  file=sys.stderr)
        print(json.dumps({key: value if key not in undefined else None
                          for key, value in values.items()}, allow_nan=False))
        return 0
    print("Ciupitu 2018, Figure 4a (*_with_bar: M_u + M_bar; 4b: *_rocking, whose M_u counts "
          "its bars): one stroke, phi = +pi/2 -> -pi/2")
    print(f"G_pv,max = {data.Gmax:g} N at OP = {data.OP:g} m, G2 = {data.G2:g} N, "
          f"OA = {data.OA:g} m, AB = {data.AB:g} m")
    print(f"{'payload law':<18} {'E_u [J]':>10} {'E_b [J]':>10} {'eps':>9} "
          f"{'max|M_u| [N m]':>15} {'at phi [rad]':>13} {'[deg]':>7}")
    for law, r in strokes.items():
        print(f"{law:<18} {r.E_u:10.6f} {r.E_b:10.6f} {r.eps:9.6f} {r.max_abs_Mu:15.6f} "
              f"{r.phi_max_Mu:13.6f} {math.degrees(r.phi_max_Mu):7.2f}")
    return 0
