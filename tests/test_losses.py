"""The realistic loss set (docs/losses.md): its values are the documented ones, its design
rules are what the rules give, and its committed runs obey the energy ledger.

Nothing runs but the design rules: the committed results are read.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import assert_reproduces_committed_summary, fair_run

from fmu_src.mechanisms.active_spring import physics as active_spring
from fmu_src.mechanisms.self_regulating import design as self_regulating_design
from fmu_src.mechanisms.self_regulating import physics as self_regulating
from harness import cli, registry, scenarios
from harness.design import active_spring as active_design
from harness.errors import UserError
from harness.scenarios import losses

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
DOC = ROOT / "docs" / "losses.md"
SCENARIOS = ("franchetti2021", "ciupitu2018", "demian2022")
# the friction parameters the rule d = F_c integral |v| dt / integral v^2 dt gives: (scenario,
# model, parameter) -> (ideal run, the part's coordinate there, F_c [N m or N], factor: the
# pulley turns by b / r, so its d over the slider's b takes r = 0.01 m)
FRICTION_RULE = {
    ("franchetti2021", "SelfRegulatingBalancer", "d_link"):
        ("self_regulating", "theta", 0.015, 1.0),
    ("franchetti2021", "SelfRegulatingBalancer", "d_pulley"):
        ("self_regulating", "b", 0.002, 0.01),
    ("franchetti2021", "CiupituBalancer", "d_link"): ("ciupitu", "theta", 0.015, 1.0),
    ("franchetti2021", "ActiveSpringBalancer", "d_link"):
        ("active_relocation", "theta", 0.015, 1.0),
    ("ciupitu2018", "CiupituBalancer", "d_link"): ("parabolic_balanced", "theta", 0.015, 1.0),
    ("ciupitu2018", "CiupituBalancer", "d_cw"): ("parabolic_balanced", "OB", 0.3, 1.0),
    ("ciupitu2018", "RockingCounterweightBalancer", "d_link"):
        ("parabolic_rocking", "theta", 0.015, 1.0),
    ("demian2022", "PrismaticCompensator", "d1"): ("compensated", "q1", 0.015, 1.0),
    ("demian2022", "PrismaticCompensator", "d2"): ("compensated", "q2", 0.3, 1.0),
}
# parameters that only dissipate: a variant whose realistic set changes nothing else has the
# ideal run's conservative mechanism
FRICTION = {"d_link", "d_cw", "d1", "d2", "d_pulley", "mu_slider"}


def documented_rows() -> list[list[str]]:
    """The rows of docs/losses.md's table of values (scenario, model, parameter, ideal,
    realistic, unit, reasoning)."""
    rows = []
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 7 and cells[0] in SCENARIOS:
            rows.append(cells)
    return rows


def loss_data(scenario: str) -> dict:
    return scenarios.read_toml(losses.LOSSES_DIR / f"{scenario}.toml")


def ideal_value(scenario: scenarios.Scenario, model: str, parameter: str) -> float:
    """A parameter as the ideal set runs it: the scenario's value, else the model's default."""
    if parameter in scenario.parameters:
        return scenario.parameters[parameter]
    return getattr(registry.registration(model).physics.Parameters(), parameter)


def test_the_loss_files_hold_the_documented_values() -> None:
    """Every model parameter of the loss files is a row of the doc's table, with its value,
    and the table's ideal column is what the ideal set runs."""
    rows = documented_rows()
    documented = {(s, m, p.strip("`")): (float(ideal), float(real))
                  for s, m, p, ideal, real, _, _ in rows}
    in_files = {(s, model, name): value for s in SCENARIOS
                for model, values in loss_data(s)["models"].items()
                for name, value in values.items()}
    assert set(documented) == set(in_files)
    for (s, model, name), value in in_files.items():
        ideal, real = documented[s, model, name]
        assert real == value, (s, model, name)
        assert ideal == ideal_value(scenarios.load(s), model, name), (s, model, name)


def test_the_variant_overrides_are_the_documented_ones() -> None:
    table = [c for c in (line.strip().strip("|").split("|") for line in
                         DOC.read_text().splitlines()) if len(c) == 5 and c[0].strip() in SCENARIOS]
    assert len(table) == 3
    for scenario_name, variants, what, value, _ in table:
        realistic = losses.realistic(scenarios.load(scenario_name.strip()))
        name = re.search(r"`(\w+)`", what).group(1)
        number = float(value.split()[0])
        for variant in (v.strip() for v in variants.split(",")):
            resolved = realistic.variant(variant)
            if "target" in what:
                assert resolved.phase_targets["III regulate"][name] == number
            else:
                assert resolved.parameters[name] == number


@pytest.mark.parametrize("key", FRICTION_RULE, ids="/".join)
def test_friction_is_the_viscous_equivalent_of_the_documented_drag(key: tuple) -> None:
    """d = F_c integral |v| dt / integral v^2 dt over the part's motion in the committed
    ideal run (the 10 ms series), to the 2-3 significant digits the loss file gives."""
    scenario, model, parameter = key
    variant, column, drag, factor = FRICTION_RULE[key]
    series = pd.read_csv(RESULTS / scenario / f"{variant}.csv")
    travel = np.diff(series[column].to_numpy())
    dt = np.diff(series.time.to_numpy())
    rule = drag * factor * np.sum(np.abs(travel)) / np.sum(travel ** 2 / dt)
    assert loss_data(scenario)["models"][model][parameter] == pytest.approx(rule, rel=0.025)


def test_the_slider_sits_where_the_design_rule_puts_it() -> None:
    """b0 is the fixed point of the general design rule's b_design for the real spring and
    slider (docs/energy_ledger.md), to the 1e-10 m the file gives."""
    variant = losses.realistic(scenarios.load("franchetti2021")).variant("self_regulating")
    p = self_regulating.Parameters(**variant.parameters)
    assert p.b_design == pytest.approx(p.b0, abs=1e-9)
    assert p.b0 > self_regulating.Parameters().b0 + 0.02  # a free length moves it out
    # regulating 1 kg adds 1 kg to the counterweight, as in the ideal set: the rule's M0
    assert self_regulating_design.counterweight_for(
        p, p.b_design + p.g * p.R / (p.r * p.k)) == pytest.approx(1.0, rel=1e-12)


def test_the_carriage_goes_where_active_design_puts_it() -> None:
    """Y_B0 balances the unloaded link and the phase III target 1 kg at 180 deg (eq. 27's
    limit), for the real spring."""
    scenario = losses.realistic(scenarios.load("franchetti2021"))
    variant = scenario.variant("active_relocation")
    p = active_spring.Parameters(**variant.parameters)
    assert p.free_length == 0.02
    assert active_design.design(p, 0.0, math.pi).Y_B_new == pytest.approx(p.Y_B0, abs=1e-9)
    payload = variant.phase_inputs["III regulate"]["payload"].target
    assert payload == 1.0
    assert active_design.design(p, payload, math.pi).delta_Y_B == pytest.approx(
        variant.phase_targets["III regulate"]["q"], abs=1e-9)


def runs(scenario: str, loss_set: str) -> list[tuple[str, str, pd.Series, pd.Series, pd.Series]]:
    """(variant, model, summary row, first and last series rows) of a committed result set."""
    folder = losses.result_folder(RESULTS, scenarios.load(scenario), loss_set)
    table = pd.read_csv(folder / "summary.csv").set_index("variant")
    out = []
    for variant, row in table.iterrows():
        series = pd.read_csv(folder / f"{variant}.csv")
        out.append((variant, row.model, row, series.iloc[0], series.iloc[-1]))
    return out


ALL_RUNS = [(s, loss_set, run) for s in SCENARIOS for loss_set in losses.LOSS_SETS
            for run in runs(s, loss_set)]


@pytest.mark.parametrize("scenario, loss_set, run", ALL_RUNS,
                         ids=lambda v: v[0] if isinstance(v, tuple) else v)
def test_the_drive_pays_what_the_ledger_stores_and_dissipates(scenario: str, loss_set: str,
                                                              run: tuple) -> None:
    """Energy ledger (docs/energy_ledger.md): the drives' mechanical work W = W_drive
    (+ W_adjust) = change of stored energy + E_loss - E_added (- W_worm). The drives' summed
    W_link is that W, and E_drawn >= E_in = E_copper + E_gear + W + change of E_inductor, the
    drive's own balance, which holds to the first-order step error of its back-EMF and its
    gear's loss (both see the held speed: docs/results.md, 2.3e-4 J of 10.3 J), an error that
    grows with the energy the drive converts and with its transmission ratio: 5e-4 J +
    2e-4 E_in bounds it (the largest, the unbalanced link on its 285:1 drive, 1.4e-3 J of
    11.9 J: 0.5 of the bound); the inductor ends with 1e-9 J at most. So E_drawn >= E_copper
    + E_gear + stored change + E_loss - E_added - W_worm."""
    _, model, row, first, last = run
    ledger = registry.registration(model).ledger
    drives = [k for k in ("W_drive", "W_adjust") if k in ledger]
    work = sum(last[k] - first[k] for k in drives)
    assert row.W_link == pytest.approx(work, abs=1e-8)
    others = sum(sign * (last[k] - first[k]) for k, sign in ledger.items()
                 if k not in drives)   # stored, E_loss, -E_added, -W_worm
    assert work == pytest.approx(others, abs=1e-8)
    tolerance = 5e-4 + 2e-4 * row.E_in  # [J] the drive's balance (docstring)
    assert row.E_drawn >= row.E_in - 1e-12
    assert row.E_in == pytest.approx(row.E_copper + row.E_gear + work, abs=tolerance)
    assert row.E_drawn >= row.E_copper + row.E_gear + others - tolerance


def dissipation_only(scenario: scenarios.Scenario) -> list[str]:
    """The variants whose realistic set changes only FRICTION parameters."""
    realistic = losses.realistic(scenario)
    return [name for name, variant in scenario.variants.items()
            if {k for k, v in realistic.variant(name).parameters.items()
                if variant.parameters.get(k, scenario.parameters.get(k)) != v} <= FRICTION
            and realistic.variant(name).phase_targets == variant.phase_targets]


@pytest.mark.parametrize("scenario_name", ["franchetti2021", "ciupitu2018"])
def test_added_friction_costs_the_drive_what_it_dissipates(scenario_name: str) -> None:
    """Where the realistic set only adds friction, the mechanism stores what it stored
    ideally at the end (the same end state, to the tracking error), so the drives' extra
    work is the extra dissipation, and the drive draws more. (demian2022's springs get a
    free length too, so its variants change more than friction.)"""
    scenario = scenarios.load(scenario_name)
    names = dissipation_only(scenario)
    assert names, scenario_name
    ideal = {v: r for v, *r in runs(scenario_name, "ideal")}
    real = {v: r for v, *r in runs(scenario_name, "realistic")}
    for name in names:
        (model, row_i, first_i, last_i), (_, row_r, first_r, last_r) = ideal[name], real[name]
        ledger = registry.registration(model).ledger
        stored = [k for k, sign in ledger.items() if sign > 0 and k != "E_loss"]
        assert sum(last_r[k] for k in stored) == pytest.approx(
            sum(last_i[k] for k in stored), abs=2e-3), name
        extra_loss = (last_r.E_loss - first_r.E_loss) - (last_i.E_loss - first_i.E_loss)
        assert extra_loss > 0.01, name
        extra_in = {k: (last_r[k] - first_r[k]) - (last_i[k] - first_i[k])
                    for k in ledger if ledger[k] < 0 and k not in ("W_drive", "W_adjust")}
        assert row_r.W_link - row_i.W_link == pytest.approx(
            extra_loss - sum(extra_in.values()), abs=2e-3), name
        assert row_r.E_drawn > row_i.E_drawn, name


def test_cosim_writes_the_realistic_set_beside_the_ideal_one(tmp_path: Path) -> None:
    """The committed layout: results/<scenario>/realistic/ holds a result set with every
    variant, and a loss file naming what the scenario does not have is one line."""
    for scenario in SCENARIOS:
        ideal = pd.read_csv(RESULTS / scenario / "summary.csv")
        real = pd.read_csv(RESULTS / scenario / losses.REALISTIC_FOLDER / "summary.csv")
        assert list(real.variant) == list(ideal.variant)
        assert list(real.columns) == list(ideal.columns)
    assert losses.loss_sets(scenarios.load("franchetti2021"), "ideal")[0][0] == "ideal"
    with pytest.raises(UserError, match="--losses"):
        losses.loss_sets(scenarios.load("franchetti2021"), "real")
    own = tmp_path / "own.toml"  # a scenario of the user's has no loss file: ideal only
    own.write_text((scenarios.SCENARIO_DIR / "franchetti2021.toml").read_text().replace(
        'name = "franchetti2021"', 'name = "own"'))
    assert [name for name, _ in losses.loss_sets(scenarios.load(own), "all")] == ["ideal"]
    with pytest.raises(UserError, match="scenario own has no loss file"):
        losses.loss_sets(scenarios.load(own), "realistic")


def test_a_wrong_loss_file_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setattr(losses, "LOSSES_DIR", tmp_path)
    (tmp_path / "franchetti2021.toml").write_text("[variants.nobody]\nparameters = {}\n")
    with pytest.raises(UserError, match="variants.nobody names no variant"):
        losses.realistic(scenarios.load("franchetti2021"))
    (tmp_path / "franchetti2021.toml").write_text("[models.SelfRegulatingBalancer]\nmu = 1\n")
    assert cli.main(["cosim", "--scenario", "franchetti2021", "--out", str(tmp_path / "o"),
                     "--quiet"]) == 2
    assert "no parameter mu" in capsys.readouterr().err


@pytest.mark.slow  # about 15 s: six runs
@pytest.mark.parametrize("scenario_name, variant", [
    ("franchetti2021", "self_regulating"), ("ciupitu2018", "parabolic_balanced"),
    ("demian2022", "compensated")])
def test_rerun_reproduces_the_committed_realistic_set(scenario_name: str, variant: str) -> None:
    """A fresh realistic run of a variant and its baseline gives the committed rows."""
    scenario = losses.realistic(scenarios.load(scenario_name))
    names = (variant, scenario.baselines[variant])
    runs = [fair_run(scenario, name, "realistic") for name in names]
    assert_reproduces_committed_summary(
        scenario, runs, losses.result_folder(RESULTS, scenario, "realistic"))
