"""docs/performance.md's section of the current figures (`make docs`), from the committed
benchmarks under results/bench/."""

from __future__ import annotations

from harness import registry
from harness.fmu.variable_pages import GENERATED_END
from harness.report.committed import Results
from harness.report.text import (
    GENERATED_START,
    markdown_table,
    number,
    percent,
    plain,
    span,
    wrapped,
)


def performance_section(results: Results) -> str:
    """docs/performance.md's section of the current figures, from results/bench/."""
    step = results.csv("bench/fmu_step").set_index("model")
    native = results.csv("bench/native_step").set_index("model")
    cosim = results.csv("bench/cosim")
    share = results.csv("bench/master_share")
    sweep = results.csv("bench/sweep")
    cli_help = results.csv("bench/cli_help")
    mechanisms = sorted(m for m in step.index if m in registry.mechanisms())
    floor = next(m for m in step.index if m not in mechanisms and step.ratio_to_floor[m] == 1)
    runtime = next(m for m in step.index if m not in (*mechanisms, floor))
    one_run = cosim[cosim.scenario != "all"]
    franchetti = one_run[one_run.scenario == "franchetti2021"].set_index("variant")
    total = cosim[cosim.scenario == "all"].iloc[0]
    shares = (share.us_per_step - share.fmu_calls_us_per_step) / share.us_per_step
    targets = [
        ("our runtime's floor / stock floor, FMPy (`fmu_step.csv`)", "<= 0.6",
         number(step.ratio_to_floor[runtime], 2)),
        ("our runtime's floor / stock floor, C host (`native_step.csv`)", "<= 0.4",
         number(native.ratio_c_host_to_floor[runtime], 2)),
        ("franchetti2021 self_regulating's FMU step / stock floor step (`fmu_step.csv`)",
         "<= 1.4", number(step.ratio_to_floor[franchetti.model.self_regulating], 3)),
        ("closed-loop step / stock floor step, franchetti2021 (`cosim.csv`)", "<= 2.5",
         span(franchetti.ratio_to_floor, 3)),
    ]
    lines = [
        "## The figures now", "", GENERATED_START, "",
        f"From the committed `results/bench/` (`make bench`): the stock floor's step costs "
        f"{number(step.us_per_step[floor])} us in FMPy and "
        f"{number(native.us_per_step_c_host[floor])} us in the C host; the ratios, measured "
        "within one run, are the figures to compare between runs.", "",
        *markdown_table(["ratio", "target", "now"], targets), "",
        "One FMU step (setReal of the first joint's effort, doStep of 1 ms, getReal of every "
        "joint's position and speed):", "",
        *markdown_table(["model", "FMPy [us]", "/ stock floor", "C host [us]", "C host / FMPy"],
                        [[f"`{m}`", number(step.us_per_step[m]),
                          number(step.ratio_to_floor[m], 3),
                          number(native.us_per_step_c_host[m]),
                          number(native.ratio_c_host_to_fmpy[m], 2)]
                         for m in [floor, runtime, *mechanisms]]), "",
        "Closed loop (`cosim.csv`: every variant at 1 ms in one process; CPU time of one step "
        "with the controller, motor, FMU calls, recording and the run's set-up spread over "
        "its steps):", "",
        *markdown_table(["scenario", "variant", "real-time factor", "us per step",
                         "/ stock floor"],
                        [[r.scenario, f"`{r.variant}`", number(r.real_time_factor),
                          number(r.us_per_step), number(r.ratio_to_floor, 3)]
                         for r in one_run.itertuples()]), "",
        f"All {len(one_run)} variants: {number(total.simulated_s)} s simulated in "
        f"{number(total.wall_s)} s of wall time on one core (real-time factor "
        f"{number(total.real_time_factor)}).", "",
        "The master's share of a closed-loop step (`master_share.csv`, franchetti2021; a "
        "reported figure, not a check: the run and its FMU calls are timed seconds apart):",
        "",
        *markdown_table(["variant", "step [us]", "FMU calls [us]", "master [us]", "share [%]"],
                        [[f"`{r.variant}`", number(r.us_per_step),
                          number(r.fmu_calls_us_per_step), number(r.master_us_per_step, 2),
                          percent(s, 2)] for r, s in zip(share.itertuples(), shares)]), "",
        "Sweep throughput (`sweep.csv`): "
        + ", ".join(f"{number(r.runs_per_s)} runs/s with {r.workers} worker"
                    + ("s" if r.workers > 1 else "") for r in sweep.itertuples())
        + f" (speed-up {number(sweep.speed_up.iloc[-1])}). The top-level help "
        f"(`cli_help.csv`) takes {number(cli_help.best_s.iloc[0], 2)} s.", "",
        *study_performance(results), GENERATED_END, ""]
    return "\n".join(wrapped(lines))


def study_performance(results: Results) -> list[str]:
    """The study's throughput (`study.csv`) and its step's error (`study_step.csv`), where
    `make bench` wrote them."""
    folder = results.folder / "bench"
    if not (folder / "study.csv").is_file() or not (folder / "study_step.csv").is_file():
        return []
    table, steps = results.csv("bench/study"), results.csv("bench/study_step")
    one = table[table.setting == "one process"].iloc[0]
    dask = table[table.setting != "one process"]
    worst = steps.groupby(["step_size", "losses"]).rel_error.max().unstack()
    return [
        f"A study (`study.csv`: the {int(one.runs)} runs of franchetti2021's first study tasks, "
        "every variant in both loss sets): in one process "
        f"{number(one.runs_per_cpu_s)} runs per CPU-second, "
        f"{number(one.simulated_s_per_cpu_s)} simulated seconds per CPU-second, "
        f"{number(one.us_per_step)} us of CPU per step of 2 ms; a fresh FMU instance would add "
        f"{number(one.start_up_s, 2)} s, {percent(one.start_up_share, 2)} % of a run, which the "
        "study saves by reusing one instance per model in each worker. On local Dask "
        "clusters reached through their scheduler's address (as `--scheduler` reaches one): "
        + ", ".join(f"{number(r.runs_per_s)} runs/s with {int(r.workers)} worker"
                    + ("s" if r.workers > 1 else "")
                    + f" ({number(r.runs_per_s_per_worker)} per worker)"
                    for r in dask.itertuples()) + " on 2 cores.", "",
        "The error the study's step leaves in E_drawn (`study_step.csv`: the first "
        f"{steps.task.nunique()} tasks of each study, every variant, relative to 0.5 ms; the "
        "largest):", "",
        *markdown_table(["step [ms]", *[f"{s} set" for s in worst.columns]],
                        [[plain(1e3 * step), *[number(v, 2) for v in row]]
                         for step, row in worst.iterrows() if step > steps.step_size.min()]),
        ""]
