"""`python -m harness cosim`: run scenarios and variants, write results/<scenario>/."""

from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from harness import master, results, scenarios
from harness.errors import UserError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="all",
                        help="scenario name, TOML file, or 'all' (default: all shipped)")
    parser.add_argument("--variants", default="all",
                        help="'all' or a comma-separated list of variant names")
    parser.add_argument("--step", type=float, default=master.DEFAULT_STEP,
                        help="communication step [s] (default 1e-3)")
    parser.add_argument("--out", type=Path, default=results.RESULTS_DIR,
                        help="results folder; files go to OUT/<scenario>/ (default results/)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def selected_variants(scenario: scenarios.Scenario, spec: str) -> list[str]:
    """Variant names from 'all' or a comma-separated list; their eps baselines are always run."""
    names = list(scenario.variants) if spec == "all" else [v.strip() for v in spec.split(",")]
    for name in names:
        scenario.variant(name)  # UserError naming the choices (also for an empty name)
    baselines = [scenario.baselines[name] for name in names]
    return list(dict.fromkeys(names + baselines))


def run_scenario(scenario: scenarios.Scenario, variants: list[str], step: float, out: Path,
                 quiet: bool = False) -> list[master.RunResult]:
    """Run the variants of one scenario with a progress bar and write its result files."""
    steps = round(scenario.duration / step)
    runs = []
    with tqdm(total=steps * len(variants), unit="step", unit_scale=True, disable=quiet,
              desc=scenario.name) as bar:
        for name in variants:
            bar.set_postfix_str(name)
            runs.append(master.run(scenario, scenario.variant(name), step, progress=bar.update))
    for path in results.write_run(runs, scenario, out / scenario.name):
        print(path)
    return runs


MAX_STEPS = 10_000_000  # communication steps per run: the series stay well inside memory


def check_step(step: float, duration: float) -> None:
    """UserError unless --step is in [duration / MAX_STEPS, duration]."""
    if not duration / MAX_STEPS <= step <= duration:
        raise UserError(f"--step = {step} s is outside [{duration / MAX_STEPS:g}, {duration:g}] "
                        f"(the scenario's duration in 1 to {MAX_STEPS:,} steps)")


def run(args: argparse.Namespace) -> int:
    names = scenarios.available() if args.scenario == "all" else [args.scenario]
    plans = []
    for name in names:  # every scenario, option and output folder checked before any run
        scenario = scenarios.load(name)
        check_step(args.step, scenario.duration)
        variants = selected_variants(scenario, args.variants)
        for name in variants:
            variant = scenario.variant(name)
            master.check_names(scenario, variant, scenario.parameters | variant.parameters)
        results.check_writable(args.out / scenario.name)
        plans.append((scenario, variants))
    for scenario, variants in plans:
        run_scenario(scenario, variants, args.step, args.out, args.quiet)
        print(results.summary_text(args.out / scenario.name / "summary.csv", scenario))
    return 0
