"""`python -m harness study` (issue 33): tasks drawn from the task model as scenario files
(their figures inside the model's ranges, their moves within the speed limit, each variant's
procedure, the balancing targets of both loss sets), the drives pinned in them, the stored
runs a study resumes from, the statistics against closed forms, the command's one-line
errors; and, marked slow, whole studies: their tables, a task rerun alone in `cosim`, a part
deleted and a study interrupted, then resumed."""

from __future__ import annotations

import dataclasses
import math
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import harness.study as study
from harness import cli, scenarios
from harness.drive import catalogue
from harness.errors import UserError
from harness.io import write_csv
from harness.run.sizing import stored_pins
from harness.scenarios import losses
from harness.study import execution, model, statistics, tasks

ROOT = Path(__file__).resolve().parents[1]
SHORT = ROOT / "tests" / "data" / "study"  # a task model of ~1 s tasks (its comments)
MODEL = model.load("franchetti2021")
THETA = MODEL.joints["theta"]
VARIANTS = list(MODEL.template.variants)
LOSS_SETS = ["ideal", "realistic"]
# franchetti2021's ActiveSpringBalancer defaults (Table 1 link, ideal spring): the carriage
# travel that balances a payload at 180 deg, q = payload w g / (k x1A) [m/kg]
Q_PER_KG = 0.35 * 9.81 / (981.0 * 0.06)
# harness/scenarios/realistic/franchetti2021.toml: `active-design` for the real spring, 1 kg
Q_REALISTIC_1KG = 0.0601210158
PROCEDURE_PHASES = (" to posture", " regulate", " settle")
QUINTIC_PEAK = 15.0 / 8.0  # the quintic's peak speed over its mean: 30 s^2 (1 - s)^2 at s = 1/2


def written(task: tasks.Task, folder: Path) -> scenarios.Scenario:
    """The task as `cosim` loads it: its file written into folder and read back."""
    return scenarios.load(tasks.write(task, folder))


def phase_spans(scenario: scenarios.Scenario) -> dict[str, tuple[float, float]]:
    return {name: (t0, t1) for name, t0, t1 in scenario.phase_times()}


# ---- tasks ----------------------------------------------------------------------------------
def test_a_task_is_its_seed_and_index_alone() -> None:
    """Task i of seed S comes from numpy's default_rng([S, i]) (the documented generator: its
    first four draws are the task's moves, speed fraction, log-uniform mean hold and change
    probability), so its file is the same text however many tasks are drawn and in whatever
    order; another seed or index gives another task."""
    first = tasks.draw(MODEL, 7, 3)
    others = [tasks.draw(MODEL, 7, i) for i in (5, 0, 4)]
    again = tasks.draw(MODEL, 7, 3)
    assert tasks.text(again.data) == tasks.text(first.data)
    assert tasks.text(again.realistic) == tasks.text(first.realistic)
    assert again.row == first.row and first.name == "franchetti2021-task-0003"
    assert all(tasks.text(o.data) != tasks.text(first.data) for o in others)
    assert tasks.text(tasks.draw(MODEL, 8, 3).data) != tasks.text(first.data)
    rng = np.random.default_rng([7, 3])
    assert first.row["moves"] == int(rng.integers(MODEL.moves[0], MODEL.moves[1] + 1))
    assert first.row["speed_fraction"] == rng.uniform(*MODEL.speed_fraction)
    assert first.row["mean_hold_s"] == math.exp(rng.uniform(*np.log(MODEL.mean_hold_s)))
    assert first.row["change_probability"] == rng.uniform(*MODEL.change_probability)


def test_the_drawn_figures_are_inside_the_task_model() -> None:
    """Over 40 tasks: the figures in their ranges (harness/study/franchetti2021.toml), every
    target between 20 and 340 deg, every hold at least MIN_HOLD_S, a payload change before
    the first move and every new payload within [0, 2] kg."""
    low, high = (math.degrees(x) for x in (THETA.low, THETA.high))
    for index in range(40):
        task = tasks.draw(MODEL, 1, index)
        row, phases = task.row, task.data["phases"]
        assert MODEL.moves[0] <= row["moves"] <= MODEL.moves[1]
        for key in ("speed_fraction", "mean_hold_s", "change_probability"):
            ends = getattr(MODEL, key)
            assert ends[0] <= row[key] <= ends[1], (index, key)
        common = [p for p in phases if "variants" not in p]
        assert low <= task.data["initial_angle_deg"] <= high
        assert all(low <= p["target_deg"] <= high for p in common), index
        assert all(p["duration"] >= tasks.MIN_HOLD_S for p in common
                   if p["name"].endswith(" hold"))
        changes = [p for p in common if p["name"].endswith(" change")]
        assert changes[0]["name"] == "1 change" and len(changes) == row["changes"]
        assert all(MODEL.payload_kg[0] <= p["inputs"]["payload"]["ramp"]
                   <= MODEL.payload_kg[1] for p in changes)
        assert all(p["duration"] == MODEL.change_s for p in changes)


def test_every_move_keeps_to_the_speed_limit(tmp_path: Path) -> None:
    """In every variant's scenario of 30 tasks, a phase that moves the link over d in T has
    the quintic's peak speed 15/8 d / T within the task's speed (speed_limit x speed
    fraction), or lasts min_move_s; and each move is as fast as that allows for the variant
    that starts farthest (the peak equals the speed, or T = min_move_s), so the limit is the
    binding one. Tolerance 1e-9 relative: the file keeps degrees, so d is back in radians to
    a few ulp; a move too fast by any real margin is far outside it."""
    for index in range(30):
        task = tasks.draw(MODEL, 1, index)
        speed = THETA.speed_limit * task.row["speed_fraction"]
        scenario = written(task, tmp_path)
        fastest: dict[str, float] = {}
        for name in scenario.variants:
            resolved = scenario.for_variant(scenario.variant(name))
            for phase, (_, _, start, end) in zip(resolved.phases,
                                                 resolved.reference_segments("theta")):
                peak = QUINTIC_PEAK * abs(end - start) / phase.duration
                assert peak <= speed * (1 + 1e-9) or phase.duration == THETA.min_move_s, (
                    index, name, phase.name)
                fastest[phase.name] = max(fastest.get(phase.name, 0.0), peak)
        for phase in scenario.phases:
            if phase.name.endswith((" move", " to posture")):
                assert (fastest[phase.name] == pytest.approx(speed, rel=1e-9)
                        or phase.duration == THETA.min_move_s), (index, phase.name)


def test_the_self_regulating_variant_regulates_at_180_deg(tmp_path: Path) -> None:
    """Task 0 of seed 1 (3 moves, each after a payload change): self_regulating goes to 180
    deg, where its `k regulate` phases hold the link with the pulley connected and the slider
    free while the counterweight ramps (linearly) to the payload that `k change` brought
    (eq. 10: counterweight = payload at the end), then locks both for its move. The other
    variants perform none of those phases and stand where the link was; unregulated never
    adds counterweight."""
    task = tasks.draw(MODEL, 1, 0)
    assert task.row["moves"] == task.row["changes"] == 3
    scenario = written(task, tmp_path)
    variant = scenario.variant("self_regulating")
    resolved = scenario.for_variant(variant)
    names = [p.name for p in resolved.phases]
    segments = dict(zip(names, resolved.input_segments(variant)))
    references = dict(zip(names, resolved.reference_segments("theta")))
    regulated = [n for n in names if n.endswith(" regulate")]
    assert len(regulated) == 3
    for name in regulated:
        k = name.split()[0]
        _, _, start, end = references[name]
        assert start == end == pytest.approx(math.pi, abs=1e-15)  # 180 deg, held
        payload = segments[f"{k} change"]["payload"]
        assert segments[f"{k} change"]["slider_locked"][1] is True  # locked meanwhile
        _, counterweight, shape = segments[name]["counterweight_added"]
        assert (counterweight, shape) == (payload[1], "linear")
        assert segments[name]["payload"][1] == payload[1]  # the payload arrived before
        assert segments[name]["pulley_locked"][1] is segments[name]["slider_locked"][1] is False
        assert segments[f"{k} move"]["slider_locked"][1] is True
        assert segments[f"{k} move"]["pulley_locked"][1] is True
    span = phase_spans(resolved)
    assert resolved.duration == pytest.approx(task.row["duration"] + sum(
        t1 - t0 for n, (t0, t1) in span.items() if n.endswith(PROCEDURE_PHASES)), rel=1e-12)
    for name in VARIANTS[1:]:
        other = scenario.for_variant(scenario.variant(name))
        assert not [p.name for p in other.phases if p.name.endswith(PROCEDURE_PHASES)], name
        assert other.duration == pytest.approx(task.row["duration"], rel=1e-12)
    unregulated = scenario.variant("unregulated")
    assert all(s["counterweight_added"][:2] == (0.0, 0.0)
               for s in scenario.for_variant(unregulated).input_segments(unregulated))


def test_the_row_is_what_the_written_phases_give(tmp_path: Path) -> None:
    """tasks.csv's figures recomputed from 20 written files: duration = the phases every
    variant performs, hold fraction = their `hold` phases over it, payload changes per minute
    = the `change` phases over it (sums in the same few terms: 1e-12 relative)."""
    for index in range(20):
        task = tasks.draw(MODEL, 3, index)
        data = tomllib.loads(tasks.write(task, tmp_path).read_text())
        common = [p for p in data["phases"] if "variants" not in p]
        duration = sum(p["duration"] for p in common)
        holds = sum(p["duration"] for p in common if p["name"].endswith(" hold"))
        changes = sum(p["name"].endswith(" change") for p in common)
        assert task.row["moves"] == sum(p["name"].endswith(" move") for p in common)
        assert task.row["changes"] == changes >= 1
        assert task.row["duration"] == pytest.approx(duration, rel=1e-12)
        assert task.row["hold_fraction"] == pytest.approx(holds / duration, rel=1e-12)
        assert task.row["changes_per_min"] == pytest.approx(changes * 60.0 / duration,
                                                            rel=1e-12)


def test_the_carriage_balances_each_new_payload(tmp_path: Path) -> None:
    """active_relocation's carriage goes, in each `k change`, to q = payload w g / (k x1A) in
    the ideal set (0.058333 m/kg, to 1e-12: the design rule is that closed form for the ideal
    spring) while the payload arrives along the quintic; for 1 kg the realistic set's q is
    the 0.0601210158 m of harness/scenarios/realistic/franchetti2021.toml (which gives 10
    decimals: 1e-10). The lossless-screw variant gets the same targets."""
    task = tasks.draw(MODEL, 1, 2)
    for variant in ("active_relocation", "active_relocation_lossless_screw"):
        table = task.data["variants"][variant]
        assert set(table["phase_targets"]) == {p["name"] for p in task.data["phases"]
                                               if p["name"].endswith(" change")}
        for phase, target in table["phase_targets"].items():
            payload = table["phase_inputs"][phase]["payload"]
            assert payload["shape"] == "quintic"
            assert target["q"] == pytest.approx(payload["ramp"] * Q_PER_KG, rel=1e-12)
    one_kg = tasks.draw(dataclasses.replace(MODEL, payload_kg=(1.0, 1.0)), 1, 2)
    scenario = written(one_kg, tmp_path)
    (_, ideal), (_, realistic) = losses.loss_sets(scenario, "all")
    for variant in ("active_relocation", "active_relocation_lossless_screw"):
        for loss_set, expected, tolerance in ((ideal, Q_PER_KG, 1e-15),
                                              (realistic, Q_REALISTIC_1KG, 1e-10)):
            targets = loss_set.variant(variant).phase_targets
            assert len(targets) == one_kg.row["changes"]
            for target in targets.values():
                assert target["q"] == pytest.approx(expected, abs=tolerance), variant


def test_a_task_file_finds_its_loss_file_beside_it(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The written task loads with `scenarios.load` and finds realistic/<task>.toml beside
    it: its two loss sets are those the study runs (`Task.loss_sets`); a shipped scenario
    keeps harness/scenarios/realistic (LOSSES_DIR, which test_losses points elsewhere); a
    task without its loss file has the ideal set only."""
    task = tasks.draw(MODEL, 1, 0)
    path = tasks.write(task, tmp_path / "tasks")
    beside = tmp_path / "tasks" / losses.REALISTIC_FOLDER / f"{task.name}.toml"
    scenario = scenarios.load(path)
    assert scenario.folder == path.parent.resolve()
    assert losses.loss_file(scenario) == beside.resolve()
    sets = losses.loss_sets(scenario, "all")
    assert [name for name, _ in sets] == LOSS_SETS
    assert sets == task.loss_sets()  # what the study runs is what cosim loads
    realistic = sets[1][1]
    assert realistic.variant("self_regulating").parameters["d_link"] == 0.042
    assert realistic.variant("unbalanced").parameters["m_slider"] == 0.0
    shipped = scenarios.load("franchetti2021")
    assert losses.loss_file(shipped) == losses.LOSSES_DIR / "franchetti2021.toml"
    monkeypatch.setattr(losses, "LOSSES_DIR", tmp_path / "elsewhere")
    assert losses.loss_file(shipped) == tmp_path / "elsewhere" / "franchetti2021.toml"
    assert losses.loss_file(scenario) == beside.resolve()
    beside.unlink()
    assert [name for name, _ in losses.loss_sets(scenarios.load(path), "all")] == ["ideal"]


def test_the_sized_drives_are_pinned_in_every_task(tmp_path: Path) -> None:
    """drives.csv read into pins (a geared drive: motor, gearhead, ratio; a direct one: the
    motor alone), pinned in a task: each variant's joints carry its pins in the written file,
    the catalogue gives back the drive they name (`Drive.pin` is the pin), and a variant
    without a row keeps the legacy drives."""
    path = tmp_path / "drives.csv"
    write_csv(pd.DataFrame([
        ("self_regulating", "theta", "RE25", "GP32C", "", 246.0),
        ("unbalanced", "theta", "RE40", "", "", 1.0),
        ("active_relocation", "theta", "RE25", "GP32C", "", 111.0),
        ("active_relocation", "q", "RE25", "GP32C", "Tr10x2", 3.7)],
        columns=["variant", "joint", "motor", "gearhead", "screw", "gear_ratio"]), path)
    pins = stored_pins(path)
    assert pins == {
        "self_regulating": {"theta": {"motor": "RE25", "gearhead": "GP32C", "ratio": 246.0}},
        "unbalanced": {"theta": {"motor": "RE40"}},
        "active_relocation": {"theta": {"motor": "RE25", "gearhead": "GP32C", "ratio": 111.0},
                              "q": {"motor": "RE25", "gearhead": "GP32C", "ratio": 3.7}}}
    scenario = written(tasks.pinned(tasks.draw(MODEL, 1, 0), pins), tmp_path)
    for name in VARIANTS:
        resolved = scenario.for_variant(scenario.variant(name))
        for joint in resolved.joints:
            pin = pins.get(name, {}).get(joint.name)
            if pin is None:
                assert joint.drive == (), (name, joint.name)
                continue
            assert dict(joint.drive) == pin
            drive = catalogue.pinned(dict(joint.drive), joint.screw, name)
            assert drive.pin() == pin and (drive.screw is None) == (joint.screw is None)


# ---- stored runs -------------------------------------------------------------------------
def run_rows(task: int, keys: list[tuple[str, str]], energy: float) -> list[dict]:
    return [{"task": task, "variant": v, "losses": ls, "status": "ok", "error": "",
             "E_drawn": energy * (1 + i), "seconds": 0.1} for i, (v, ls) in enumerate(keys)]


def test_stored_runs_leave_only_the_missing_ones_to_run(tmp_path: Path) -> None:
    """Parts store rows per task; what is left is every planned (task, variant, loss set)
    without a row; a key stored twice keeps its later row; the runs table holds the stored
    rows in plan order (task, loss set, variant) with eps = 1 - E_drawn / E_drawn(baseline)
    of the same task and loss set."""
    drawn = [tasks.draw(MODEL, 1, i) for i in range(3)]
    variants, sets = ["a", "b"], ["ideal", "realistic"]
    keys = [(v, ls) for v in variants for ls in sets]
    assert execution.pending(tmp_path, drawn, variants, sets) == {0: keys, 1: keys, 2: keys}
    execution.write_part(tmp_path, run_rows(0, keys, 1.0))
    execution.write_part(tmp_path, run_rows(1, [("a", "ideal")], 5.0))
    assert execution.pending(tmp_path, drawn, variants, sets) == {1: keys[1:], 2: keys}
    execution.write_part(tmp_path, run_rows(1, [("a", "ideal")], 7.0))  # again, later
    table = execution.stored(tmp_path)
    assert len(table) == 5 and not table.duplicated(list(execution.KEY)).any()
    runs = execution.runs_table(tmp_path, drawn, variants, sets, {"a": "b", "b": "b"})
    assert list(zip(runs.task, runs.losses, runs.variant)) == [
        (0, "ideal", "a"), (0, "ideal", "b"), (0, "realistic", "a"), (0, "realistic", "b"),
        (1, "ideal", "a")]
    assert runs.E_drawn.tolist() == [1.0, 3.0, 2.0, 4.0, 7.0]
    eps = runs.eps.to_numpy()
    np.testing.assert_allclose(eps[:4], [1 - 1 / 3, 0.0, 1 - 2 / 4, 0.0], rtol=1e-15)
    assert math.isnan(eps[4])  # its baseline has no row


# ---- statistics -----------------------------------------------------------------------------
def runs_of(energies: dict[str, np.ndarray], **columns: dict[str, np.ndarray]) -> pd.DataFrame:
    """A runs table of one loss set: E_drawn by variant over tasks 0..n-1, all ok."""
    rows = []
    for variant, values in energies.items():
        for task, value in enumerate(values):
            row = {"task": task, "variant": variant, "losses": "ideal", "status": "ok",
                   "E_drawn": value, "eps": 0.0, "drive_ok": True}
            row.update({name: column[variant][task] for name, column in columns.items()
                        if variant in column})
            rows.append(row)
    return pd.DataFrame(rows)


def test_the_summary_quantiles_ratios_and_least_fractions() -> None:
    """101 tasks: R draws 100 + t, so its 5 %, 50 % and 95 % quantiles are 105, 150, 195
    (linear interpolation at p (n - 1)); B draws 0.9 R (ratio 0.9); A draws 50 in tasks 0-29
    and 500 after, so it draws least in 30 tasks and B in 71, and its median ratio is that of
    the 51st smallest, 500 / 180. A task in which one variant failed counts for none."""
    t = np.arange(101.0)
    r = 100.0 + t
    a = np.where(t < 30, 50.0, 500.0)
    runs = runs_of({"R": r, "A": a, "B": 0.9 * r},
                   eps={"A": t / 100.0}, drive_ok={"A": t % 10 != 0})
    failed = runs_of({"R": [1.0], "A": [1.0], "B": [math.nan]}).assign(task=101)
    failed.loc[failed.variant == "B", "status"] = "failed"
    summary = statistics.summary(pd.concat([runs, failed]), ["R", "A", "B"], "R")
    rows = summary.set_index("variant")
    assert (rows.tasks == 101).all()
    assert rows.loc["R", ["E_drawn_q05", "E_drawn_median", "E_drawn_q95"]].tolist() == \
        pytest.approx([105.0, 150.0, 195.0], rel=1e-12)
    assert rows.loc["A", ["eps_q05", "eps_median", "eps_q95"]].tolist() == pytest.approx(
        [0.05, 0.5, 0.95], rel=1e-12)
    assert rows.ratio_median.tolist() == pytest.approx([1.0, 500.0 / 180.0, 0.9], rel=1e-12)
    assert rows.least_fraction.tolist() == pytest.approx([0.0, 30 / 101, 71 / 101], rel=1e-12)
    assert rows.loc["A", "drive_ok_fraction"] == pytest.approx(90 / 101, rel=1e-12)


def test_the_paired_interval_is_the_mean_difference_and_its_spread() -> None:
    """200 tasks whose differences A - R are normal (mean 0.3, sd 1): the mean difference is
    the mean of the differences; the 95 % bootstrap interval holds it and is 2 x 1.96 x sd /
    sqrt(n) wide within 15 % (the percentile interval of a mean of 200 is that to about 3 %,
    sqrt((n-1)/n) and 10 000 resamples' quantile error); 0.3 is 4 standard errors from 0, so
    the difference is firm, and the interval of R - A is the mirror image (same resamples).
    The same differences centred on 0 are not firm."""
    rng = np.random.default_rng(33)
    r = 10.0 + rng.uniform(0.0, 5.0, 200)
    d = rng.normal(0.3, 1.0, 200)
    for shift, firm in ((0.0, True), (-d.mean(), False)):
        differences = d + shift
        paired = statistics.paired(runs_of({"R": r, "A": r + differences}), ["R", "A"])
        rows = paired.set_index(["variant", "other"])
        a_r, r_a = rows.loc[("A", "R")], rows.loc[("R", "A")]
        mean = differences.mean()
        assert a_r.mean_difference == pytest.approx(mean, rel=1e-12, abs=1e-12)
        assert a_r.ci_low < mean < a_r.ci_high
        width = 2 * 1.96 * differences.std(ddof=1) / math.sqrt(200)
        assert a_r.ci_high - a_r.ci_low == pytest.approx(width, rel=0.15)
        assert bool(a_r.firm) is firm and bool(r_a.firm) is firm
        assert (a_r.tasks, a_r.resamples) == (200, statistics.RESAMPLES)
        assert (r_a.mean_difference, r_a.ci_low, r_a.ci_high) == pytest.approx(
            (-mean, -a_r.ci_high, -a_r.ci_low), rel=1e-9, abs=1e-12)


def test_dependence_bins_hold_equal_counts() -> None:
    """200 tasks with distinct, unevenly spread figures fall into 4 bins of 50 per figure
    (bins of equal width would not hold equal counts); A's ratio to R is 1.5 + i / 100 with
    changes_per_min = i^2 / 100 for task i, so the bins' median ratios are 1.5 + (24.5, 74.5,
    124.5, 174.5) / 100, and R draws the least in each."""
    n = 200
    index = np.arange(n)
    task_table = pd.DataFrame({"task": index, "changes_per_min": index ** 2 / 100.0,
                               "hold_fraction": ((index * 7 % n) / n) ** 3})  # permuted
    r = np.full(n, 2.0)
    runs = runs_of({"R": r, "A": r * (1.5 + index / 100.0)})
    table = statistics.dependence(runs, task_table, ["R", "A"], "R")
    for axis in statistics.TASK_AXES:
        rows = table[(table.axis == axis) & (table.variant == "A")]
        assert rows.tasks.tolist() == [50] * 4, axis
        assert (rows.high.to_numpy()[:-1] == rows.low.to_numpy()[1:]).all()
    by_count = table[(table.axis == "changes_per_min")]
    a = by_count[by_count.variant == "A"]
    assert a.ratio_median.tolist() == pytest.approx(1.5 + np.array([24.5, 74.5, 124.5,
                                                                    174.5]) / 100, rel=1e-12)
    assert (by_count[by_count.variant == "R"].least_fraction == 1.0).all()
    assert (a.least_fraction == 0.0).all()


# ---- the command ----------------------------------------------------------------------------
@pytest.mark.parametrize("options, message", [
    (["--tasks", "0"], "--tasks = 0 is outside [1, 100,000]"),
    (["--seed", "-1"], "--seed = -1 is outside [0, 2**63 - 1]"),
    (["--workers", "0"], "--workers = 0 must be at least 1"),
    (["--scenario", "nosuch"],
     "no task model for scenario 'nosuch' (known: ciupitu2018, demian2022, franchetti2021)"),
])
def test_a_bad_option_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                  options: list[str], message: str) -> None:
    """Exit 2, one line naming the option, and nothing written."""
    assert cli.main(["study", "--scenario", "franchetti2021", "--out", str(tmp_path),
                     "--quiet", *options]) == 2
    assert capsys.readouterr().err.splitlines() == [f"error: {message}"]
    assert list(tmp_path.iterdir()) == []


def test_a_study_folder_holds_one_seed(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    """A folder with a study of seed 1 (its settings.json): --seed 2 there is one line, exit
    2, before anything is drawn or sized (the folder unchanged); a task file of another study
    in its place is refused naming it."""
    folder = tmp_path / "franchetti2021"
    task = tasks.draw(MODEL, 1, 0)
    study.check_settings(folder, study.settings(MODEL, 1, MODEL.tasks))
    tasks.write(task, folder / "tasks")
    write_csv(study.task_rows([task], folder, MODEL.step), folder / "tasks.csv")
    before = sorted(folder.rglob("*"))
    assert cli.main(["study", "--scenario", "franchetti2021", "--seed", "2", "--out",
                     str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"error: {folder} holds a study made with other settings (seed 1 -> 2): "
                   "write to another --out (runs the committed study holds are reused), or "
                   "add --replace"]
    assert sorted(folder.rglob("*")) == before
    with pytest.raises(UserError, match=f"{task.name}.toml holds another task"):
        tasks.write(tasks.draw(MODEL, 2, 0), folder / "tasks")


# ---- whole studies (slow) ----------------------------------------------------------------
@pytest.fixture(scope="module")
def two_tasks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`python -m harness study --scenario franchetti2021 --tasks 2 --workers 1` into a fresh
    folder (about 40 s on one core: 24 sizing runs, then 24 runs of 40-100 s tasks)."""
    out = tmp_path_factory.mktemp("study")
    with pytest.MonkeyPatch.context() as patch:  # runs every run: no committed one reused
        patch.setattr(study, "STUDY_DIR", out / "no-committed-study")
        assert cli.main(["study", "--scenario", "franchetti2021", "--tasks", "2", "--out",
                         str(out), "--workers", "1", "--quiet"]) == 0
    return out / "franchetti2021"


def assert_whole(folder: Path, n_tasks: int) -> pd.DataFrame:
    """runs.csv holds one ok row per planned (task, variant, loss set) and the parts hold
    each key once (none computed twice); returns runs.csv."""
    runs = pd.read_csv(folder / "runs.csv")
    planned = {(t, v, ls) for t in range(n_tasks) for v in VARIANTS for ls in LOSS_SETS}
    assert len(runs) == len(planned) == n_tasks * 12
    assert set(zip(runs.task, runs.variant, runs.losses)) == planned
    assert (runs.status == "ok").all(), runs.error.dropna().tolist()
    parts = pd.concat([pd.read_parquet(p)
                       for p in execution.parts_dir(folder).glob("part-*.parquet")])
    assert not parts.duplicated(list(execution.KEY)).any()
    assert len(parts) == len(planned)
    return runs


@pytest.mark.slow  # about 40 s: the two_tasks study
def test_a_study_writes_its_runs_and_tables(two_tasks: Path) -> None:
    """tasks.csv, drives.csv (pinned in every task file), 24 ok runs, summary.csv and
    paired.csv against the runs: with 2 tasks, the median is the mean of the two, the mean
    difference the difference of means, and the bootstrap interval runs from the smaller
    difference to the larger (each resample of 2 is both of one task with probability 1/4,
    above the 2.5 % tails); eps against unbalanced, each CSV number to 10 digits."""
    task_table = pd.read_csv(two_tasks / "tasks.csv")
    assert task_table.task.tolist() == [0, 1] and set(task_table.seed) == {1}
    assert all(cmd.startswith("python -m harness cosim --scenario ")
               for cmd in task_table.rerun)
    runs = assert_whole(two_tasks, 2)
    pins = stored_pins(two_tasks / "drives.csv")
    assert sorted(pins) == sorted(VARIANTS)
    for file in task_table.file:
        scenario = scenarios.load(two_tasks / file)
        for name in VARIANTS:
            joints = scenario.for_variant(scenario.variant(name)).joints
            assert {j.name: dict(j.drive) for j in joints} == pins[name]
    assert (runs.E_drawn > 0).all()
    wide = runs.pivot_table(index=["losses", "task"], columns="variant", values="E_drawn")
    eps = runs.set_index(["losses", "task", "variant"]).eps
    for (loss_set, task), energies in wide.iterrows():
        for variant in VARIANTS:
            assert eps[loss_set, task, variant] == pytest.approx(
                1.0 - energies[variant] / energies["unbalanced"], abs=1e-8)
    summary = pd.read_csv(two_tasks / "summary.csv")
    assert len(summary) == 12 and (summary.tasks == 2).all()
    for row in summary.itertuples():
        assert row.E_drawn_median == pytest.approx(wide.loc[row.losses][row.variant].mean(),
                                                   rel=1e-9)
    for loss_set in LOSS_SETS:
        assert summary[summary.losses == loss_set].least_fraction.sum() == pytest.approx(1.0)
    paired = pd.read_csv(two_tasks / "paired.csv")
    assert len(paired) == 2 * 6 * 5
    for row in paired.itertuples():
        mine, other = wide.loc[row.losses][row.variant], wide.loc[row.losses][row.other]
        d = (mine - other).to_numpy()
        # from runs.csv's 10 digits: each energy to 5e-10 of itself, so the difference to
        # 1e-9 of the larger energies
        tolerance = 1e-9 * (mine.abs().max() + other.abs().max())
        assert (row.mean_difference, row.ci_low, row.ci_high) == pytest.approx(
            (d.mean(), d.min(), d.max()), rel=0.0, abs=tolerance)
    for name in ("dependence.csv", "energy.png"):
        assert (two_tasks / name).stat().st_size > 0


@pytest.mark.slow  # about 20 s: a task's 12 runs in cosim (and its drives' sizing runs)
def test_a_task_reruns_alone_in_cosim(two_tasks: Path, tmp_path: Path) -> None:
    """The rerun command of tasks.csv (its --out to a fresh folder, one worker, quiet) gives
    the E_drawn of runs.csv for every variant in both loss sets: the same file, drives, step
    and engine make the same numbers, so they agree to the CSVs' 10 digits (1e-9)."""
    task_table = pd.read_csv(two_tasks / "tasks.csv")
    row = task_table.loc[task_table.duration.idxmin()]  # the shorter task
    words = shlex.split(row.rerun)
    assert words[:4] == ["python", "-m", "harness", "cosim"]
    argv = words[3:]
    argv[argv.index("--out") + 1] = str(tmp_path)
    assert cli.main([*argv, "--workers", "1", "--quiet"]) == 0
    runs = pd.read_csv(two_tasks / "runs.csv")
    for loss_set in LOSS_SETS:
        folder = losses.set_folders(tmp_path / row["name"])[loss_set]
        rerun = pd.read_csv(folder / "summary.csv").set_index("variant").E_drawn
        stored = runs[(runs.task == row.task) & (runs.losses == loss_set)]
        assert sorted(rerun.index) == sorted(VARIANTS)
        for variant, energy in zip(stored.variant, stored.E_drawn):
            assert rerun[variant] == pytest.approx(energy, rel=1e-9), (loss_set, variant)


@pytest.mark.slow  # about 10 s: one task's 12 runs again
def test_a_study_runs_again_only_what_is_missing(two_tasks: Path, tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The study copied, task 1's part deleted, the same command again: the other part is
    left as it was, one new part holds task 1's 12 rows, with the same E_drawn as before (the
    same runs), drives.csv is not sized again, and runs.csv has each key once."""
    folder = tmp_path / "franchetti2021"
    shutil.copytree(two_tasks, folder)
    parts = sorted(execution.parts_dir(folder).iterdir())
    assert len(parts) == 2
    tables = {path: pd.read_parquet(path) for path in parts}
    (gone,) = [path for path, table in tables.items() if set(table.task) == {1}]
    (kept,) = set(parts) - {gone}
    gone.unlink()
    drives = (folder / "drives.csv").read_bytes()
    monkeypatch.setattr(study, "STUDY_DIR", tmp_path / "no-committed-study")
    assert cli.main(["study", "--scenario", "franchetti2021", "--tasks", "2", "--out",
                     str(tmp_path), "--workers", "1", "--quiet"]) == 0
    now = sorted(execution.parts_dir(folder).iterdir())
    (new,) = set(now) - {kept}
    assert pd.read_parquet(kept).equals(tables[kept])
    again = pd.read_parquet(new).set_index(list(execution.KEY)).sort_index()
    before = tables[gone].set_index(list(execution.KEY)).sort_index()
    assert list(again.index) == list(before.index)
    np.testing.assert_allclose(again.E_drawn, before.E_drawn, rtol=1e-12)
    assert (folder / "drives.csv").read_bytes() == drives
    assert_whole(folder, 2)


KILL_SCRIPT = """
import sys
from pathlib import Path
from harness import cli
from harness.study import model
model.STUDY_DIR = Path(sys.argv[1])
sys.exit(cli.main(["study", "--scenario", "franchetti2021", "--tasks", sys.argv[2], "--out",
                   sys.argv[3], "--workers", "1", "--quiet"]))
"""


@pytest.mark.slow  # about 16 s: a study of 8 short tasks, interrupted, then resumed
def test_an_interrupted_study_resumes_without_losing_or_repeating_runs(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C (SIGINT to the process group) once the first task's part is stored: exit 130
    with the line saying how to resume, the stored parts kept and the study unfinished; the
    same command then runs the rest: every run once, the first session's rows unchanged."""
    n = 8
    folder = tmp_path / "franchetti2021"
    parts = execution.parts_dir(folder)
    process = subprocess.Popen(
        [sys.executable, "-c", KILL_SCRIPT, str(SHORT), str(n), str(tmp_path)], cwd=ROOT,
        text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120.0
        while not (parts.exists() and any(parts.glob("part-*.parquet"))):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.02)
        os.killpg(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 130, err
    assert err.splitlines()[-1] == ("interrupted: the finished tasks' runs are stored; run "
                                    "the same command to resume")
    first = execution.stored(folder)
    assert 12 <= len(first) < 12 * n and len(first) % 12 == 0
    assert not (folder / "runs.csv").exists()

    monkeypatch.setattr(model, "STUDY_DIR", SHORT)
    assert cli.main(["study", "--scenario", "franchetti2021", "--tasks", str(n), "--out",
                     str(tmp_path), "--workers", "1", "--quiet"]) == 0
    runs = assert_whole(folder, n).set_index(list(execution.KEY))
    kept = first.set_index(list(execution.KEY))
    assert runs.loc[kept.index, "seconds"].tolist() == pytest.approx(kept.seconds.tolist(),
                                                                     rel=1e-9)


def test_a_study_whose_runs_failed_still_writes_its_tables(tmp_path: Path) -> None:
    """Two tasks stored with ciupitu failed in both in the realistic set (a run an FMU
    refuses is a failed row): runs.csv holds all 24 rows, the failed ones with their error;
    the statistics cover the loss set in which a task has every variant (the ideal one), as
    no realistic task compares them all; the figure is drawn."""
    drawn = [tasks.draw(MODEL, 1, i) for i in range(2)]
    write_csv(study.task_rows(drawn, tmp_path, MODEL.step), tmp_path / "tasks.csv")
    for task in drawn:
        rows = run_rows(task.row["task"], [(v, ls) for v in VARIANTS for ls in LOSS_SETS], 1.0)
        for row in rows:
            row.update(drive_ok=True, duration=10.0)
            if (row["variant"], row["losses"]) == ("ciupitu", "realistic"):
                row.update(status="failed", error="UserError: refused", E_drawn=math.nan)
        execution.write_part(tmp_path, rows)
    study.write_tables(MODEL, drawn, tmp_path, VARIANTS, LOSS_SETS, quiet=True)
    runs, summary = (pd.read_csv(tmp_path / f"{name}.csv") for name in ("runs", "summary"))
    assert len(runs) == 24 and (runs.status == "failed").sum() == 2
    assert set(runs[runs.status == "failed"].error) == {"UserError: refused"}
    assert list(summary.losses.unique()) == ["ideal"] and len(summary) == 6
    assert set(pd.read_csv(tmp_path / "paired.csv").losses) == {"ideal"}
    assert (tmp_path / "energy.png").stat().st_size > 0


@pytest.mark.parametrize("step", [0.004, 1.0 / 300.0])
def test_the_rerun_command_runs_the_task_file_at_the_study_step(tmp_path: Path,
                                                                step: float) -> None:
    """tasks.csv's rerun command names the task's file and the study's step exactly (a step
    of 1/300 s written to 6 digits would rerun at another step, with other numbers)."""
    task = tasks.draw(MODEL, 1, 0)
    (rerun,) = study.task_rows([task], tmp_path, step).rerun
    words = shlex.split(rerun)
    assert words[:4] == ["python", "-m", "harness", "cosim"]
    assert Path(words[words.index("--scenario") + 1]) == tmp_path / "tasks" / f"{task.name}.toml"
    assert float(words[words.index("--step") + 1]) == step


# ---- the committed study ------------------------------------------------------------------
COMMITTED = study.STUDY_DIR


def test_a_smaller_study_reuses_the_committed_one_and_leaves_it_alone(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`study --tasks 3` into the committed folder is refused in one line naming --out and
    --replace, the folder untouched; into another folder it runs nothing: the committed drives
    and the 36 runs of its first 3 tasks are reused, and its runs.csv holds their rows as
    committed (eps recomputed from the stored 10-digit E_drawn)."""
    folder = COMMITTED / "franchetti2021"
    before = {p: p.stat().st_mtime_ns for p in folder.rglob("*")}
    assert cli.main(["study", "--scenario", "franchetti2021", "--tasks", "3", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tasks 200 -> 3" in err and "--out" in err \
        and "--replace" in err
    assert {p: p.stat().st_mtime_ns for p in folder.rglob("*")} == before
    assert cli.main(["study", "--scenario", "franchetti2021", "--tasks", "3", "--out",
                     str(tmp_path)]) == 0
    assert "36 runs, 36 stored (36 from results/study/franchetti2021), 0 to do" in \
        capsys.readouterr().out
    assert (tmp_path / "franchetti2021" / "drives.csv").read_bytes() == (
        folder / "drives.csv").read_bytes()
    fresh = pd.read_csv(tmp_path / "franchetti2021" / "runs.csv")
    committed = pd.read_csv(folder / "runs.csv")
    committed = committed[committed.task < 3].reset_index(drop=True)
    pd.testing.assert_frame_equal(fresh.drop(columns="eps"), committed.drop(columns="eps"))
    np.testing.assert_allclose(fresh.eps, committed.eps, rtol=1e-9)
KEPT = ["E_drawn", "E_in", "E_copper", "E_gear", "E_mech", "W_link"]


def committed_rows(name: str, task: int, variants: list[str] | None = None) -> pd.DataFrame:
    runs = pd.read_csv(COMMITTED / name / "runs.csv")
    rows = runs[runs.task == task]
    return rows if variants is None else rows[rows.variant.isin(variants)]


def rerun(name: str, task: int, variant: str, loss_set: str) -> dict:
    """One run of the committed study's task from its committed file, as the study ran it."""
    task_model = model.load(name)
    path = COMMITTED / name / "tasks" / f"{tasks.task_name(task_model, task)}.toml"
    drawn = tasks.draw(task_model, 1, task)
    pins = stored_pins(COMMITTED / name / "drives.csv")
    pinned = tasks.pinned(drawn, pins)
    assert tasks.text(pinned.data) == path.read_text()   # the committed file is the draw
    return execution.run_one(pinned, variant, loss_set, task_model.step)


def test_a_committed_study_run_reproduces() -> None:
    """demian2022's task 0, compensated, realistic, run again: its committed row to 1e-6 (the
    cross-machine tolerance of docs/results.md; bit for bit on the machine that made it)."""
    row = rerun("demian2022", 0, "compensated", "realistic")
    stored = committed_rows("demian2022", 0, ["compensated"])
    stored = stored[stored.losses == "realistic"].iloc[0]
    assert row["status"] == "ok"
    for name in KEPT:
        assert row[name] == pytest.approx(stored[name], rel=1e-6, abs=1e-9), name


@pytest.mark.slow   # about 30 s: 30 runs
@pytest.mark.parametrize("name", ["franchetti2021", "ciupitu2018", "demian2022"])
def test_every_committed_study_reproduces_its_first_task(name: str) -> None:
    """Task 0 of each committed study, every variant in both loss sets: the rows of runs.csv
    to 1e-6, and the summary's statistics are those of runs.csv (recomputed)."""
    task_model = model.load(name)
    stored = committed_rows(name, 0)
    for row in stored.itertuples():
        fresh = rerun(name, 0, row.variant, row.losses)
        for metric in KEPT:
            assert fresh[metric] == pytest.approx(getattr(row, metric), rel=1e-6, abs=1e-9)
    runs = pd.read_csv(COMMITTED / name / "runs.csv")
    variants = list(task_model.template.variants)
    pd.testing.assert_frame_equal(
        statistics.summary(runs, variants, task_model.reference),
        pd.read_csv(COMMITTED / name / "summary.csv"), rtol=1e-9, check_dtype=False)
