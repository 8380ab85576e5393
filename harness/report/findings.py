"""docs/findings.md (`make docs`): what the committed results say. Every scenario's summary,
ideal and realistic, the study over random tasks, the co-simulation's accuracy and the
sweeps, in tables and in sentences whose numbers are read from the CSV files under results/.

Nothing runs: the files are read. The tables cover every result set results/ holds; the
sentences are about the shipped scenarios and sweeps, and name their variants and columns.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import pandas as pd

from harness import scenarios
from harness.report import study
from harness.report.committed import Results, realistic
from harness.report.text import (
    falls_or_rises,
    markdown_table,
    more_or_less,
    number,
    percent,
    plain,
    span,
    wrapped,
)


def joints(summary: pd.DataFrame) -> list[str]:
    """The joint suffixes of a summary's per-joint columns ("" for a one-joint summary)."""
    found = [c.removeprefix("track_err_rms_") for c in summary.columns
             if c.startswith("track_err_rms_")]
    return found or [""]


def column(name: str, joint: str) -> str:
    return f"{name}_{joint}" if joint else name


def effort_column(summary: pd.DataFrame, joint: str) -> tuple[str, str, float, str]:
    """(RMS effort column, its unit, the tracking error's scale, its unit) of a joint: a torque
    in N m with the tracking error in deg, or a force in N with it in mm."""
    if column("tau_rms", joint) in summary:
        return column("tau_rms", joint), "N m", math.degrees(1.0), "deg"
    return column("F_rms", joint), "N", 1e3, "mm"


def drawn_cell(row: pd.Series, summary: pd.DataFrame) -> str:
    """E_drawn of a variant, with each drive's share where it drives several joints."""
    total = number(row.E_drawn, 4)
    shares = [(j, row[column("E_drawn", j)]) for j in joints(summary)
              if j and column("E_drawn", j) in summary
              and math.isfinite(row[column("E_drawn", j)])]
    if len(shares) < 2:
        return total
    return f"{total} ({', '.join(f'{j} {number(v, 4)}' for j, v in shares)})"


def per_joint(row: pd.Series, summary: pd.DataFrame, name: str, scale: float = 1.0,
              digits: int = 3) -> str:
    """A per-joint metric of a variant, "a / b" over the summary's joints that it drives."""
    values = [row[column(name, j)] for j in joints(summary)
              if column(name, j) in summary and math.isfinite(row[column(name, j)])]
    return " / ".join(number(scale * v, digits) for v in values) or "-"


# ---- the pages -----------------------------------------------------------------------------
def scenario_table(results: Results, scenario: str) -> list[str]:
    """Per variant: E_drawn, E_copper and eps of the ideal and (where there is one) the
    realistic set, eps_W, and per joint the RMS effort (a torque in N m or a force in N), peak
    voltage and RMS tracking error (in deg or mm)."""
    ideal = results.summary(scenario)
    real = results.summary(realistic(scenario)) if results.has_realistic(scenario) else None
    joint_names = joints(ideal)
    if len(joint_names) == 1:
        _, effort_unit, _, track_unit = effort_column(ideal, joint_names[0])
        suffix, effort_unit, track_unit = "", f" [{effort_unit}]", f" [{track_unit}]"
    else:
        suffix, effort_unit, track_unit = f" {' / '.join(joint_names)}", "", " [deg or mm]"
    both = real is not None
    header = ["variant", "E_drawn [J]", *(["E_drawn realistic [J]"] if both else []),
              "E_copper [J]", *(["E_copper realistic [J]"] if both else []),
              "eps", *(["eps realistic"] if both else []), "eps_W",
              f"RMS effort{suffix}{effort_unit}", f"V_peak{suffix} [V]",
              f"tracking RMS{suffix}{track_unit}"]
    rows = []
    for variant, row in ideal.iterrows():
        cells = [f"`{variant}`", drawn_cell(row, ideal)]
        if real is not None:
            cells.append(drawn_cell(real.loc[variant], real))
        cells.append(number(row.E_copper, 4))
        if real is not None:
            cells.append(number(real.loc[variant].E_copper, 4))
        cells.append(number(row.eps, 4))
        if real is not None:
            cells.append(number(real.loc[variant].eps, 4))
        cells.append(number(row.eps_W, 4))
        efforts, tracking = [], []
        for joint in joint_names:
            name, _, scale, _ = effort_column(ideal, joint)
            if math.isfinite(row.get(name, math.nan)):
                efforts.append(number(row[name], 3))
                tracking.append(number(scale * row[column("track_err_rms", joint)], 2))
        cells += [" / ".join(efforts) or "-", per_joint(row, ideal, "V_peak"),
                  " / ".join(tracking) or "-"]
        rows.append(cells)
    return markdown_table(header, rows)


def ranking_sentence(results: Results) -> str:
    """Whether the order of the variants by E_drawn is the same with ideal and real parts."""
    changed = [s for s in results.scenarios() if results.has_realistic(s) and list(
        results.summary(s).E_drawn.sort_values().index) != list(
        results.summary(realistic(s)).E_drawn.sort_values().index)]
    if not changed:
        return ("the order of the variants by E_drawn is the same as with ideal parts in every "
                "scenario, but the margins move")
    return (f"the order of the variants by E_drawn changes in {', '.join(changed)} and holds "
            "in the other scenarios")


def one_line_answer(results: Results) -> str:
    """The headline: what self-regulation saves, ideal and real, and what active regulation
    costs against it."""
    ideal, real = results.summary("franchetti2021"), results.summary(realistic("franchetti2021"))
    return (
        "On the franchetti2021 task, self-regulation cuts the drive's energy to "
        f"{percent(ideal.E_drawn.self_regulating / ideal.E_drawn.unregulated, 2)} % of the "
        "unregulated spring balancer's with ideal parts and to "
        f"{percent(real.E_drawn.self_regulating / real.E_drawn.unregulated, 3)} % with the "
        "losses of real parts; regulating with a second drive instead (active relocation of "
        "the spring's anchor on a self-locking screw) costs "
        f"{number(real.E_drawn.active_relocation / real.E_drawn.self_regulating, 3)} times "
        "self-regulation's energy with real parts.")


def franchetti_text(results: Results) -> list[str]:
    name = "franchetti2021"
    ideal, real = results.summary(name), results.summary(realistic(name))
    sr, ur, ci = (ideal.loc[v] for v in ("self_regulating", "unregulated", "ciupitu"))
    ar, al = ideal.loc["active_relocation"], ideal.loc["active_relocation_lossless_screw"]
    rsr, rur, rci, rar = (real.loc[v] for v in ("self_regulating", "unregulated", "ciupitu",
                                                  "active_relocation"))
    scenario = scenarios.load(name)
    design = scenario.variant("ciupitu").parameters
    phases = {phase: (start, end) for phase, start, end in scenario.phase_times()}
    start, _ = phases["III regulate"]
    _, settled = phases["IV settle and lock"]
    sr0, sr1 = results.at(name, "self_regulating", start), results.at(name, "self_regulating",
                                                                       settled)
    ar0, ar1 = results.at(name, "active_relocation", start), results.at(
        name, "active_relocation", settled)
    spring = ar1.E_e - ar0.E_e
    lost = ar1.E_loss - ar0.E_loss
    return [
        f"With the losses of real parts ([losses.md](losses.md)) {ranking_sentence(results)}. "
        "Both franchetti2021 sets run `active_relocation` on the real screw (a self-locking "
        "screw without friction does not exist); `active_relocation_lossless_screw` is its "
        f"lossless limit, a lower bound. Self-regulation draws {number(rsr.E_drawn)} J instead "
        f"of {number(sr.E_drawn)} J: {percent(rsr.E_drawn / rur.E_drawn)} % of the unregulated "
        f"balancer's energy ({percent(sr.E_drawn / ur.E_drawn, 2)} % with ideal parts) and "
        f"{percent(rsr.E_drawn / rci.E_drawn)} % of the Ciupitu counterweight's "
        f"({percent(sr.E_drawn / ci.E_drawn, 2)} % ideal). A spring of real free length "
        "balances the link exactly at no angle: self-regulation's RMS drive torque grows from "
        f"{number(sr.tau_rms, 2)} to {number(rsr.tau_rms, 3)} N m. The unregulated balancer draws "
        f"{more_or_less(rur.E_drawn - ur.E_drawn, 'J')}, the Ciupitu counterweight "
        f"{more_or_less(rci.E_drawn - ci.E_drawn, 'J')}. Active regulation costs "
        f"{number(rar.E_drawn / rsr.E_drawn)} times self-regulation's energy with real parts and "
        f"{number(ar.E_drawn / sr.E_drawn, 4)} times with ideal ones.",
        "",
        "The `ciupitu` row is the Ciupitu counterweight that `ciupitu-design` finds best for "
        f"this task by minimising E_drawn: m2 = {number(design['m2'], 3)} kg on a bar of "
        f"AB = {plain(design['AB'])} m with OA = {plain(design['OA'])} m"
        + (", so the optimum does not slide at all: a fixed counterweight"
           if design["OA"] == 0 else "") + ".",
        "",
        "Self-regulation against active regulation. `active_relocation` is Ciupitu's Fig. 8 "
        "with the same link, payload and ideal spring: instead of the slider, a second drive "
        "raises the spring's frame anchor on a self-locking trapezoidal screw by "
        f"{number(1e3 * (ar1.q - ar0.q))} mm in phase III, to the height that balances the "
        f"payload of {plain(ar1.payload)} kg, and the screw holds it there. Its link drive "
        f"draws {number(ar.E_drawn_theta)} J, what the self-regulating link draws "
        f"({number(sr.E_drawn)} J): both keep the link balanced. The anchor's drive draws "
        f"{number(ar.E_drawn_q, 5)} J. W_adjust = {number(ar.W_adjust, 4)} J of mechanical work "
        f"goes into the screw: {number(spring, 4)} J is stored in the spring (with the link "
        f"hanging, raising the anchor stretches it from {number(1e3 * ar0.l_s)} to "
        f"{number(1e3 * ar1.l_s)} mm), {number(lost)} J is lost in the screw's thread and the "
        f"carriage's damper, and {number(ar.W_adjust - spring - lost, 2)} J lifts the carriage. "
        f"The anchor motor's copper losses add {number(ar.E_copper_q)} J. Self-regulation "
        f"spends {number(sr.E_drawn)} J, {percent(sr.E_drawn / ar.E_drawn, 2)} % of that. On the "
        "screw's lossless limit (`active_relocation_lossless_screw`: self-locking at "
        "efficiency 1, which no screw reaches) the anchor's drive would still draw "
        f"{number(al.E_drawn_q, 4)} J (W_adjust = {number(al.W_adjust, 4)} J), "
        f"{number(al.E_drawn / ur.E_drawn, 2)} times the unregulated balancer's whole energy.",
        "",
        "The difference is where the regulation energy comes from. Self-regulation takes it "
        f"from the counterweight, which sinks and releases {number(sr0.E_cw - sr1.E_cw)} J in "
        f"phases III and IV, {number(sr1.E_e - sr0.E_e)} J of it into the spring, whose slider "
        f"end moves {number(1e3 * (sr1.delta_b - sr0.delta_b), 2)} mm along the link, while the "
        "link's drive only holds the link. Active regulation must supply the spring's energy "
        "through a motor and a self-locking screw, which passes on less than half of the "
        "motor's work, and pays copper losses on top. Where regulating is cheap: the "
        "regulation sweep [below](#where-to-regulate-regulation).",
    ]


def ciupitu_text(results: Results) -> list[str]:
    name = "ciupitu2018"
    ideal, real = results.summary(name), results.summary(realistic(name))
    laws = ("parabolic", "linear")

    def drop(summary: pd.DataFrame, variant: str) -> float:
        return ideal.eps[variant] - summary.eps[variant]

    sliding_most = all(drop(real, f"{law}_balanced") > drop(real, f"{law}_rocking")
                       for law in laws)
    ratios = {law: (real.E_drawn[f"{law}_balanced"] / real.E_drawn[f"{law}_rocking"],
                    ideal.E_drawn[f"{law}_balanced"] / ideal.E_drawn[f"{law}_rocking"])
              for law in laws}
    return [
        "With real parts the sliding counterweight's eps "
        f"{falls_or_rises(ideal.eps.parabolic_balanced, real.eps.parabolic_balanced)} "
        f"(parabolic) and {falls_or_rises(ideal.eps.linear_balanced, real.eps.linear_balanced)}"
        " (linear), the rocking counterweight's "
        f"{falls_or_rises(ideal.eps.parabolic_rocking, real.eps.parabolic_rocking)} and "
        f"{falls_or_rises(ideal.eps.linear_rocking, real.eps.linear_rocking)}"
        + (": the guide of the sliding counterweight costs it most" if sliding_most else "")
        + ". The sliding counterweight draws "
        + " and ".join(f"{number(r)} times the rocking one's energy with the {law} law "
                       f"({number(i)} ideal)" if n == 0 else
                       f"{number(r)} times with the {law} law ({number(i)} ideal)"
                       for n, (law, (r, i)) in enumerate(ratios.items())) + ".",
        "",
        "eps_W counts the stroke work (`W_phases`, the paper's measure): "
        f"{number(ideal.eps_W.parabolic_balanced, 4)} (parabolic) and "
        f"{number(ideal.eps_W.linear_balanced, 4)} (linear) for the sliding counterweight, "
        f"{number(ideal.eps_W.parabolic_rocking, 4)} and {number(ideal.eps_W.linear_rocking, 4)}"
        " for the rocking one. The payload joins from rest on the way down and leaves with its "
        "speed on the way up, which costs the drive the same kinetic energy on both strokes, "
        "balanced or not, so it cancels from the stroke work like the pivot friction. Why the "
        "paper's static eps differ (the bar's own moment) and how the rocking counterweight "
        "is designed: [modelling_choices.md](modelling_choices.md#ciupitus-counterweights).",
    ]


def demian_text(results: Results) -> list[str]:
    name = "demian2022"
    ideal, real = results.summary(name), results.summary(realistic(name))
    c, cb, u = "compensated", "compensated_backdrivable", "uncompensated"
    return [
        "With real parts the compensated arm draws "
        f"{number(real.E_drawn[c] / ideal.E_drawn[c], 2)} times its ideal energy (its revolute "
        f"joint's RMS torque is {number(real.tau_rms_q1[c], 2)} N m against "
        f"{number(ideal.tau_rms_q1[c], 2)} N m ideally: the springs' free length), yet "
        f"{percent(real.E_drawn[c] / real.E_drawn[u], 2)} % of the uncompensated arm's; the "
        "back-drivable compensator draws "
        f"{number(real.E_drawn[cb] / real.E_drawn[c], 2)} times the self-locking one's energy "
        f"({number(ideal.E_drawn[cb] / ideal.E_drawn[c], 2)} times ideally). Why the prismatic "
        "joint needs the self-locking worm: [modelling_choices.md](modelling_choices.md"
        "#where-the-prismatic-compensator-departs-from-the-paper).",
    ]


SCENARIO_TEXT: dict[str, Callable[[Results], list[str]]] = {
    "franchetti2021": franchetti_text, "ciupitu2018": ciupitu_text, "demian2022": demian_text}


def scenario_section(results: Results, name: str) -> list[str]:
    ideal = results.summary(name)
    scenario = scenarios.load(name) if name in scenarios.available() else None
    lines = [f"## {name}", ""]
    if scenario is not None:
        compared: dict[str, list[str]] = {}
        for variant, baseline in scenario.baselines.items():
            if variant != baseline:
                compared.setdefault(baseline, []).append(f"`{variant}`")
        lines += [f"{scenario.description} eps against "
                  + "; ".join(f"`{b}` for {', '.join(v)}" for b, v in compared.items())
                  + ".", ""]
    files = f"`results/{name}/summary.csv`" + (
        f", `results/{realistic(name)}/summary.csv`" if results.has_realistic(name) else "")
    steps = ", ".join(plain(1e3 * h) for h in ideal.step_size.unique())
    lines += [f"{files}; the plot: [`{name}.png`](../results/{name}/{name}.png). At a "
              f"communication step of {steps} ms.", ""]
    lines += scenario_table(results, name) + [""]
    if name in SCENARIO_TEXT and results.has_realistic(name):
        lines += SCENARIO_TEXT[name](results) + [""]
    return lines


def accuracy_section(results: Results) -> list[str]:
    convergence = results.csv("bench/convergence")
    worst = convergence.groupby(["scenario", "step_size"], sort=False).max_rel_err.max()
    per_scenario = []
    for scenario, errors in worst.groupby(level="scenario", sort=False):
        errors = errors.droplevel("scenario").sort_index(ascending=False)
        steps = list(errors.index)
        orders = [math.log2(errors[a] / errors[b]) for a, b in zip(steps, steps[1:])]
        variants = convergence[convergence.scenario == scenario].variant.nunique()
        per_scenario.append(
            f"{scenario} ({variants} variants) "
            + ", ".join(f"{number(errors[h], 2)} at {number(1e3 * h, 1)} ms" for h in steps)
            + f", order {span(orders, 2)}")
    ecco = results.csv("bench/ecco")
    fixed = ecco[ecco.algorithm == "fixed"]
    ideal = results.summary("franchetti2021").loc["unbalanced"]
    agreement = (fixed.err_E_in - fixed.rel_bond_error).abs() / fixed.rel_bond_error.abs()
    lines = [
        "## Accuracy of the co-simulation", "",
        "Against the monolithic reference (`cosim --engine reference`: the whole system as one "
        "ODE in `solve_ivp`, continuous controllers; `results/bench/convergence.csv`, every "
        "variant with a reference, legacy drives), the largest relative error of an energy "
        "metric is, per scenario: " + "; ".join(per_scenario) + " in the step (first order: "
        "the one-step delay of the exchange).", "",
        "Coupling energy (`W_bond_*`, [results.md](results.md#power-bonds)): in the FMPy master "
        "at 1 ms the drive-to-joint bond of franchetti2021's `unbalanced` variant "
        f"{'loses' if ideal.W_bond_error < 0 else 'gains'} {number(abs(ideal.W_bond_error), 2)}"
        f" J of the {number(ideal.W_bond_drive)} J the drive delivers. At a fixed step the "
        "coupling's error is all of E_in's error against the monolithic reference: in "
        f"`results/bench/ecco.csv` err_E_in and rel_bond_error agree to "
        f"{percent(agreement.max(), 2)} % at every fixed step.", "",
        "ECCO (`cosim --engine libcosim-ecco`, [results.md](results.md#variable-steps-ecco)): "
        "steps taken and the relative E_drawn error against the monolithic reference "
        "(`results/bench/ecco.csv`, `ecco.png`):", ""]
    cases = ecco.groupby(["scenario", "variant"], sort=False)
    fixed_steps = sorted(fixed.step_size.unique(), reverse=True)
    tolerances = sorted(ecco.abs_tolerance.dropna().unique(), reverse=True)
    header = ["case", *(f"fixed {number(1e3 * h, 1)} ms" for h in fixed_steps),
              *(f"ECCO {number(t, 1)} J" for t in tolerances)]
    rows, verdicts = [], []
    for (scenario, variant), case in cases:
        by_step = case[case.algorithm == "fixed"].set_index("step_size")
        by_tolerance = case[case.algorithm == "ecco"].set_index("abs_tolerance")
        rows.append([f"{scenario} {variant}",
                     *(f"{int(by_step.steps[h])}: {number(by_step.err_E_drawn[h], 3)}"
                       for h in fixed_steps),
                     *(f"{int(by_tolerance.steps[t])}: {number(by_tolerance.err_E_drawn[t], 3)}"
                       for t in tolerances)])
        target = by_step.loc[1e-3]
        better = by_tolerance[by_tolerance.err_E_drawn <= target.err_E_drawn]
        if len(better):
            best = better.loc[better.steps.idxmin()]
            verdicts.append(
                f"On {scenario} ECCO at {number(best.name, 1)} J beats the 1 ms step's E_drawn "
                f"accuracy with {number(target.steps / best.steps, 2)} times fewer steps.")
        else:
            closest = by_tolerance.loc[by_tolerance.err_E_drawn.idxmin()]
            verdicts.append(
                f"On {scenario} no tolerance reaches the 1 ms step's E_drawn accuracy "
                f"({number(target.err_E_drawn, 3)}): the closest, {number(closest.name, 1)} J, "
                f"gives {number(closest.err_E_drawn, 3)} with "
                f"{number(target.steps / closest.steps, 2)} times fewer steps, and the event "
                f"lag reaches {number(1e3 * case.event_lag_max.max(), 2)} ms (ECCO does not hit "
                "the phase starts).")
        ordered = by_tolerance.sort_index(ascending=False)
        tightest = ordered.iloc[-1]
        if tightest.err_E_drawn > ordered.err_E_drawn.min():
            falling = bool((ordered.bond_error.diff().dropna() < 0).all())
            verdicts.append(
                f"A tighter tolerance does not make E_drawn better: "
                f"{number(tightest.err_E_drawn, 3)} at {number(tightest.name, 1)} J, while the "
                "bonds' own error "
                + ("keeps falling (" if falling else "moves (")
                + ", ".join(f"{number(b, 2)} J" for b in ordered.bond_error)
                + f"; the 1 ms step's {number(target.bond_error, 2)} J).")
    return lines + markdown_table(header, rows) + ["", " ".join(verdicts), ""]


def saving(table: pd.DataFrame, keys: Sequence[str], variant: str = "self_regulating",
           against: str = "unregulated") -> pd.Series:
    """1 - E_drawn(variant) / E_drawn(against) at each point of a sweep, by its keys."""
    ok = table[table.status == "ok"]
    mine = ok[ok.variant == variant].set_index(list(keys)).E_drawn
    theirs = ok[ok.variant == against].set_index(list(keys)).E_drawn
    return 1 - mine / theirs


def runs_note(table: pd.DataFrame, name: str) -> str:
    failed = int((table.status != "ok").sum())
    return (f"`results/sweeps/{name}.csv`, {len(table)} runs"
            + (f", {failed} failed" if failed else ""))


def sweep_table1(results: Results) -> list[str]:
    table = results.csv("sweeps/table1")
    saved = saving(table, ["payload", "regulation_angle", "L0"])
    payload_max = float(table.payload_max.iloc[0])
    angles = sorted(table.regulation_angle.unique(), reverse=True)
    lengths = sorted(table.L0.unique())
    hanging = saved.xs(angles[0], level="regulation_angle")
    ideal_spring = hanging.xs(0.0, level="L0")
    within = ideal_spring[(ideal_spring.index > 0) & (ideal_spring.index <= payload_max)]
    beyond = ideal_spring[ideal_spring.index > payload_max]
    header = ["payload [kg]", *(f"L0 = {plain(1e3 * l)} mm" for l in lengths),
              *(f"{plain(a)} deg, L0 = 0" for a in angles[1:])]
    rows = [[plain(p), *(percent(hanging[(p, l)], 3) for l in lengths),
             *(percent(saved[(p, a, 0.0)], 3) for a in angles[1:])]
            for p in sorted(table.payload.unique())]
    unloaded = table[(table.payload == 0) & (table.L0 == 0) & (table.variant == "self_regulating")
                     ].set_index("regulation_angle").E_drawn
    return [
        "### Energy saving by payload, regulation angle and free length (`table1`)", "",
        "The saving of self-regulation, 1 - E_drawn(self_regulating) / E_drawn(unregulated) "
        f"in %, regulated at {plain(angles[0])} deg unless a column says otherwise "
        f"({runs_note(table, 'table1')}):", "",
        *markdown_table(header, rows), "",
        f"With an ideal spring (L0 = 0) regulated at {plain(angles[0])} deg "
        f"self-regulation saves {span(within, 3, 100)} % of the unregulated drive energy for "
        f"payloads up to payload_max = {number(payload_max)} kg"
        + (f", and {', '.join(f'{percent(v)} % at {plain(p)} kg' for p, v in beyond.items())}"
           " beyond it (the slider then sits at its end stop)" if len(beyond) else "")
        + f". Regulating at {plain(angles[-1])} deg with no payload moves the slider away "
        f"from balance: the drive then spends {number(unloaded[angles[-1]], 2)} J instead of "
        f"{number(unloaded[angles[0]], 2)} J. The plots: [`table1_saving.png`]"
        "(../results/sweeps/table1_saving.png), [`table1_map.png`]"
        "(../results/sweeps/table1_map.png).", ""]


def sweep_real_spring(results: Results) -> list[str]:
    table = results.csv("sweeps/real_spring")
    saved = saving(table, ["payload", "L0", "m_slider"])
    lengths, masses = sorted(table.L0.unique()), sorted(table.m_slider.unique())
    header = ["payload [kg]", *(f"L0 {plain(1e3 * l)} mm, slider {plain(m)} kg"
                                for l in lengths for m in masses)]
    rows = [[plain(p), *(percent(saved[(p, l, m)], 3) for l in lengths for m in masses)]
            for p in sorted(table.payload.unique())]
    one = saved.xs(1.0, level="payload")
    return [
        "### Real springs and slider mass (`real_spring`)", "",
        "The saving of self-regulation in % on the franchetti2021 task, by spring free length "
        f"L0 and slider mass ({runs_note(table, 'real_spring')}):", "",
        *markdown_table(header, rows), "",
        "A real spring's free length dominates: at 1 kg self-regulation saves "
        + ", ".join(f"{span(one.xs(l, level='L0'), 3, 100)} % with L0 = {plain(1e3 * l)} mm"
                    for l in lengths)
        + " (over the slider masses). The plot: [`real_spring_saving.png`]"
        "(../results/sweeps/real_spring_saving.png).", ""]


def sweep_design_rule(results: Results) -> list[str]:
    table = results.csv("sweeps/design_rule")
    mine = table[(table.variant == "self_regulating") & (table.status == "ok")].set_index(
        ["L0", "m_slider", "paper_design"])
    lengths, masses = sorted(table.L0.unique()), sorted(table.m_slider.unique())
    header = ["L0 [mm]", "m_slider [kg]", "E_drawn rule / eqs. 10,16 [J]",
              "RMS torque rule / eqs. 10,16 [N m]", "E_copper rule / eqs. 10,16 [J]"]
    rows = [[plain(1e3 * l), plain(m),
             *(f"{number(mine[c][(l, m, 0)])} / {number(mine[c][(l, m, 1)])}"
               for c in ("E_drawn", "tau_rms", "E_copper"))]
            for l in lengths for m in masses]

    def verdict(l: float, m: float) -> str:
        rule, paper = mine.tau_rms[(l, m, 0)], mine.tau_rms[(l, m, 1)]
        better = "the rule" if rule < paper else "eqs. 10/16"
        return (f"L0 = {plain(1e3 * l)} mm and m_slider = {plain(m)} kg: "
                f"{better} ({number(rule, 4)} against {number(paper, 4)} N m)")

    return [
        "### The design rule for real parts (`design_rule`)", "",
        "Self-regulation with M0 and payload_max from the general design rule "
        "([energy_ledger.md](energy_ledger.md)) against eqs. 10/16 of the paper as printed "
        f"(`paper_design`), 1 kg regulated at 180 deg ({runs_note(table, 'design_rule')}):", "",
        *markdown_table(header, rows), "",
        "The better balanced, by RMS drive torque, with both departures from the paper at "
        f"their largest, {verdict(lengths[-1], masses[-1])}; with the slider's mass alone, "
        f"{verdict(lengths[0], masses[-1])}; with the free length alone, "
        f"{verdict(lengths[-1], masses[0])}. The rule balances the whole payload range, not "
        "1 kg. E_drawn counts no regeneration, so it can favour an unbalance that helps the "
        "move.", ""]


def sweep_slider_friction(results: Results) -> list[str]:
    table = results.csv("sweeps/slider_friction")
    mine = table[(table.variant == "self_regulating") & (table.status == "ok")].pivot(
        index="mu_slider", columns="regulation_angle", values="E_drawn")
    angles = sorted(mine.columns)
    header = ["mu_slider", *(f"{plain(a)} deg" for a in angles)]
    rows = [[plain(mu), *(number(mine.loc[mu, a]) for a in angles)]
            for mu in mine.index]
    top = mine.index.max()
    hanging = mine[angles[-1]]
    return [
        "### Friction on the slider (`slider_friction`)", "",
        "E_drawn [J] of self-regulation for 1 kg by Coulomb friction on the slider and "
        f"regulation angle ({runs_note(table, 'slider_friction')}):", "",
        *markdown_table(header, rows), "",
        (f"At {plain(angles[-1])} deg the wire pulls the slider along the link with no "
         "normal force, so friction does nothing: "
         f"{number(hanging.iloc[0])} J for every mu_slider up to {plain(top)}."
         if span(hanging) == number(hanging.iloc[0]) else "")
        + " Away from it friction stops the slider short of its frictionless position: with "
        f"mu_slider = {plain(top)} E_drawn "
        + ", ".join(f"{falls_or_rises(mine.loc[0, a], mine.loc[top, a])} J at "
                    f"{plain(a)} deg" for a in angles[:-1]) + ".", ""]


def sweep_regulation(results: Results) -> list[str]:
    table = results.csv("sweeps/regulation")
    ok = table[table.status == "ok"]
    sr = ok[ok.variant == "self_regulating"].set_index(["payload", "regulation_angle"])
    ar = ok[ok.variant == "active_relocation"].set_index(["payload", "regulation_angle"])
    angles = sorted(table.regulation_angle.unique(), reverse=True)
    payloads = sorted(table.payload.unique())
    one, heaviest = 1.0, payloads[-1]
    header = ["angle [deg]", "self-regulation: E_drawn [J]", "E_cw [J]", "balance left [N m]",
              "active: W_adjust [J]", "E_drawn of the anchor [J]", "balance left [N m]"]
    rows = [[plain(a), number(sr.E_drawn[(one, a)]), number(sr.E_cw[(one, a)]),
             number(sr.balance_error[(one, a)], 2), number(ar.W_adjust[(one, a)]),
             number(ar.E_drawn_q[(one, a)]), number(ar.balance_error[(one, a)], 2)]
            for a in angles]
    hanging = angles[0]
    sr_hanging = sr.xs(hanging, level="regulation_angle")
    work = ar.W_adjust.xs(one, level="payload")
    cheapest, dearest = work.idxmin(), work.idxmax()
    opposite = (cheapest == angles[-1] and dearest == hanging
                and sr.E_drawn.xs(one, level="payload").idxmin() == hanging)
    return [
        "### Where to regulate (`regulation`)", "",
        "The franchetti2021 task with the payload put on and regulated at another link angle "
        f"(0 deg: upright), then the move of phase V ({runs_note(table, 'regulation')}; "
        f"{plain(one)} kg below, payloads {plain(payloads[0])}-{plain(payloads[-1])} kg in the "
        "plot [`regulation_lines.png`](../results/sweeps/regulation_lines.png)):", "",
        *markdown_table(header, rows), "",
        f"Self-regulation works with the link hanging: at {plain(hanging)} deg the "
        "counterweight supplies the regulation (E_cw falls by "
        + ", ".join(f"{number(-sr.E_cw[(p, hanging)], 3)} J for {plain(p)} kg"
                    for p in (payloads[0], one, heaviest))
        + "), the balance error left is below "
        f"{number(sr_hanging.balance_error.abs().max(), 1)} N m and the drive draws "
        f"{span(sr_hanging.E_drawn, 2)} J for the whole task. Anywhere else the released "
        "slider settles where the wire's pull meets the spring's along the link, which is not "
        f"where the link balances: for {plain(one)} kg the balance left grows from "
        f"{number(abs(sr.balance_error[(one, angles[1])]), 2)} N m at {plain(angles[1])} "
        f"deg to {number(abs(sr.balance_error[(one, angles[-1])]), 3)} N m at "
        f"{plain(angles[-1])} deg, and the drive then draws up to "
        f"{number(sr.E_drawn.xs(one, level='payload').max())} J. Active relocation balances at "
        f"every angle to within {number(ar.balance_error.abs().max(), 2)} N m, but its actuator "
        "pays the spring's energy through the screw's efficiency: for "
        f"{plain(one)} kg W_adjust is {number(work[cheapest], 4)} J at {plain(cheapest)}"
        f" deg (the cheapest) and {number(work[dearest], 4)} J at {plain(dearest)} deg (the "
        f"dearest), its motor draws {number(ar.E_drawn_q[(one, cheapest)], 4)} J and "
        f"{number(ar.E_drawn_q[(one, dearest)], 4)} J "
        f"({number(ar.E_drawn_q[(heaviest, cheapest)], 4)} J and "
        f"{number(ar.E_drawn_q[(heaviest, dearest)], 4)} J for {plain(heaviest)} kg). "
        + ("So the two are best at opposite ends: regulate actively with the link upright, "
           "self-regulate with it hanging. " if opposite else "")
        + "Even at its cheapest, active regulation of "
        f"{plain(one)} kg draws {number(ar.E_drawn[(one, cheapest)], 4)} J, "
        f"{number(ar.E_drawn[(one, cheapest)] / sr.E_drawn[(one, hanging)])} times the "
        f"{number(sr.E_drawn[(one, hanging)], 2)} J of self-regulation at "
        f"{plain(hanging)} deg.", ""]


def sweeps_section(results: Results) -> list[str]:
    return ["## Sweeps", "",
            "Parameter sweeps of the franchetti2021 task (`make sweep` runs `table1` and "
            "`regulation`; `python -m harness sweep harness/sweeps/<name>.toml` any of them; "
            "[sweeps.md](sweeps.md)).", "",
            *sweep_table1(results), *sweep_real_spring(results), *sweep_design_rule(results),
            *sweep_slider_friction(results), *sweep_regulation(results)]


def findings_markdown(results: Results) -> str:
    """docs/findings.md."""
    lines = [
        "# Findings: what the committed results say", "",
        "Generated by `make docs` (`harness/run/report.py`) from the CSV files under "
        "[`results/`](../results/) that `make cosim`, `make sweep` and `make bench` write; "
        "`tests/test_docs.py` fails when this page differs from what they give, so edit the "
        "generator, not the page. Columns and metrics: [results.md](results.md); the losses "
        "of the realistic sets: [losses.md](losses.md).", "",
        one_line_answer(results), "",
        "Every scenario runs each variant twice in the FMPy master: with the ideal parts its "
        "file describes and with the losses of real parts (\"realistic\"). eps = 1 - E_drawn / "
        "E_drawn(baseline) on the energy drawn from a supply that takes nothing back; several "
        "joints show their values as \"a / b\" in the order of the column's title.", ""]
    lines += study_section(results)
    for name in results.scenarios():
        lines += scenario_section(results, name)
    lines += accuracy_section(results) + sweeps_section(results)
    return "\n".join(wrapped(lines)).rstrip("\n") + "\n"


def study_section(results: Results) -> list[str]:
    """docs/findings.md's study: each scenario's answer, its firm and its open comparisons
    (neighbours in the ranking), and the median ratios by quartile of the task figures."""
    names = results.studies()
    if not names:
        return []
    lines = ["## Over random tasks: the study", "",
             "From `results/study/<scenario>/` ([study.md](study.md)): per scenario, every "
             "variant over the same random tasks, in both loss sets; E_drawn medians with the "
             "5 % and 95 % quantiles over the tasks, paired differences as means over the tasks "
             "with 95 % percentile-bootstrap intervals "
             f"({int(results.csv(f'study/{names[0]}/paired').resamples.iloc[0]):,} resamples "
             "of the tasks, a fixed seed). A comparison is firm when its interval excludes 0.",
             ""]
    for name in names:
        lines += [f"### {name}", "",
                  study.scenario_sentence(name, results.csv), ""]
        lines += study.firmness(name, results.csv)
        header, rows = study.dependence_table(name, results.csv)
        if rows:
            lines += ["Median E_drawn over the reference variant's, by quartile of the tasks "
                      "(realistic set):", "", *markdown_table(header, rows), ""]
    return lines
