"""`python -m harness cosim`: run scenarios and variants in an engine, write OUT/<scenario>/.

Every engine (`harness.engines.ENGINES`) writes the same result set (docs/results.md): a CSV
series per variant, the summary and the plot, into OUT/<scenario>/ for the scenario as
written and OUT/<scenario>/realistic/ for its realistic loss set; after either, the
scenario's headline figure OUT/<scenario>/<scenario>_energy.png is redrawn from both sets'
summaries. OUT is results/ for the FMPy master, whose result sets are the committed ones,
and build/results/<engine>/ for the others, so that no other engine overwrites them unless
asked to.

The runs (every selected variant of every selected scenario and loss set) are independent:
with `--workers N` above 1 they run in N worker processes (pythonfmu embeds one interpreter
per process, so processes, not threads), longest first, and each result set is written (by a
worker as well: its plot costs as much as a run) as soon as its last run is done. A run's
numbers do not depend on the process it ran in.

Ctrl-C or SIGTERM (`harness.interrupts`): the runs stop at their next recorded step (a worker
process never sees the signal; its parent tells it at once through a shared flag, and waits
for it to end), a result set not yet renamed into place is left as it was (one being renamed
is renamed in full), and the command exits with 130 (143 after SIGTERM): what was written is
complete, nothing else changed.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from harness import interrupts, scenarios
from harness.engines import DEFAULT_STEP, ENGINES, Engine
from harness.engines.settings import SOURCES, EccoSettings
from harness.errors import UserError
from harness.scenarios import losses

if TYPE_CHECKING:  # the command's help imports none of what its runs need
    import pandas as pd

    from harness.drive.motor import JointDrive
    from harness.drive.sizing import Sizing
    from harness.engines.result import RunResult

BUILD_RESULTS = Path(__file__).resolve().parents[2] / "build" / "results"
# the ECCO settings as options: (field of EccoSettings, unit, meaning)
ECCO_OPTIONS = (
    ("abs_tolerance", "J", "absolute tolerance on a bond's energy residual per step"),
    ("rel_tolerance", "", "relative tolerance on it"),
    ("min_step", "s", "smallest step"),
    ("max_step", "s", "largest step"),
    ("safety_factor", "", "safety factor of the step controller"),
    ("min_change_rate", "", "smallest factor between two steps"),
    ("max_change_rate", "", "largest factor between two steps"),
    ("p_gain", "", "proportional gain of the step controller"),
    ("i_gain", "", "integral gain of the step controller"),
)
DRIVE_CONFIGURATIONS = ("sized", "legacy")
POLL_INTERVAL = 0.1  # [s] between the parent's looks at an interrupt while workers run


def scenario_catalogue() -> str:
    """The shipped scenarios and their variants, for the command's help."""
    lines = ["scenarios and their variants (--scenario, --variants):"]
    for name in scenarios.available():
        scenario = scenarios.load(name)
        realistic = " (also a realistic loss set)" if losses.has_realistic(scenario) else ""
        lines.append(f"  {name}{realistic}:")
        lines.append(f"    {', '.join(scenario.variants)}")
    lines.append("engines (--engine):")
    lines += [f"  {name}: {engine.help}" for name, engine in ENGINES.items()]
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.epilog = scenario_catalogue()
    parser.add_argument("--scenario", default="all",
                        help="a shipped scenario's name, a scenario TOML file, or 'all'")
    parser.add_argument("--variants", default="all",
                        help="'all' or a comma-separated list of variant names (their eps "
                             "baselines are added); with --scenario all, the scenarios that "
                             "have them")
    parser.add_argument("--engine", choices=ENGINES, default="fmpy",
                        help="what runs the variants (see below)")
    parser.add_argument("--step", type=float, default=DEFAULT_STEP,
                        help="communication step [s]: the reference's sampling step, ECCO's "
                             "first step")
    parser.add_argument("--out", type=Path,
                        help="results folder: files go to OUT/<scenario>/ and "
                             "OUT/<scenario>/realistic/ (default: results/ for --engine fmpy, "
                             "build/results/<engine>/ for the others)")
    parser.add_argument("--drives", choices=DRIVE_CONFIGURATIONS, default="sized",
                        help="sized: each joint's drive from the catalogue by the sizing rule "
                             "(docs/drives.md), resting while a self-locking axis holds; "
                             "legacy: one lossless maxon RE 30 drive type on every joint, "
                             "always on (the tables before the fair protocol)")
    parser.add_argument("--losses", default="all", metavar="{all,ideal,realistic}",
                        help="'all', or a comma-separated list of ideal (the scenario as "
                             "written) and realistic (with the losses of real parts, "
                             "harness/scenarios/realistic/<scenario>.toml); with all, a "
                             "scenario without a realistic set runs ideal only")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="worker processes running the variants in parallel (1 runs them "
                             "one after another in this process)")
    parser.add_argument("--replace", action="store_true",
                        help="start each result set anew, even where its folder holds one made "
                             "with another engine, drive configuration or step (without it "
                             "such a folder is refused)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    options = parser.add_argument_group("engine options")
    options.add_argument("--source", choices=SOURCES,
                         help="--engine libcosim: run the OSP description (default) or the "
                              "SSP archive")
    defaults = EccoSettings()
    for name, unit, meaning in ECCO_OPTIONS:
        options.add_argument(f"--ecco-{name.replace('_', '-')}", dest=f"ecco_{name}",
                             type=float, metavar="X",
                             help=f"--engine libcosim-ecco: {meaning} (default "
                                  f"{getattr(defaults, name)}{' ' + unit if unit else ''})")


def engine_options(args: argparse.Namespace) -> dict[str, Any]:
    """The chosen engine's options from the command line; UserError for an option of
    another engine."""
    given = {"source": args.source} if args.source is not None else {}
    ecco = {name: getattr(args, f"ecco_{name}") for name, _, _ in ECCO_OPTIONS
            if getattr(args, f"ecco_{name}") is not None}
    if ecco:
        given["ecco"] = ecco
    engine = ENGINES[args.engine]
    for option in given:
        if option not in engine.options:
            flag = (f"--ecco-{next(iter(ecco)).replace('_', '-')}" if option == "ecco"
                    else f"--{option}")
            owner = next(name for name, e in ENGINES.items() if option in e.options)
            raise UserError(f"{flag} applies to --engine {owner} only, not {args.engine}")
    if "ecco" in engine.options:
        given["ecco"] = EccoSettings(**given.get("ecco", {}))
        given["ecco"].check()
    return given


@dataclass(frozen=True)
class Plan:
    """A result set to make: the scenario (its loss set applied), the variants to run, the
    loss set's name and the folder the set goes to; loaded: the scenario as loaded, whose
    loss sets the variants' drives are sized for (None: the legacy drives)."""

    scenario: scenarios.Scenario
    variants: list[str]
    loss_set: str
    folder: Path
    loaded: scenarios.Scenario | None = None
    settings: dict[str, object] = field(default_factory=dict)  # what the set is made with
    replace: bool = False  # the set starts anew


    @property
    def scenario_folder(self) -> Path:
        """The scenario's folder, OUT/<scenario>/ (the ideal set's)."""
        return self.folder if self.loss_set == "ideal" else self.folder.parent


def selected_variants(scenario: scenarios.Scenario, spec: str) -> list[str]:
    """Variant names from 'all' or a comma-separated list; their eps baselines are always run."""
    names = list(scenario.variants) if spec == "all" else [v.strip() for v in spec.split(",")]
    for name in names:
        scenario.variant(name)  # UserError naming the choices (also for an empty name)
    baselines = [scenario.baselines[name] for name in names]
    return list(dict.fromkeys(names + baselines))


def selected_scenarios(spec: str, variants: str) -> list[scenarios.Scenario]:
    """The scenarios of --scenario: one by name or file, or every shipped one; with 'all' and
    named variants, those that have one of them (UserError naming a variant none has)."""
    if spec != "all":
        return [scenarios.load(spec)]
    shipped = [scenarios.load(name) for name in scenarios.available()]
    if variants == "all":
        return shipped
    names = [v.strip() for v in variants.split(",")]
    missing = [n for n in names if not any(n in s.variants for s in shipped)]
    if missing:
        known = ", ".join(f"{s.name}: {', '.join(s.variants)}" for s in shipped)
        raise UserError(f"--variants: no shipped scenario has {', '.join(missing)} ({known})")
    return [s for s in shipped if any(n in s.variants for n in names)]


def plan(args: argparse.Namespace, engine: Engine, out: Path) -> list[Plan]:
    """Every result set the command makes, each scenario, variant, model, option and folder
    checked before anything runs."""
    from harness.engines import plan as run_plan
    from harness.run import results

    plans = []
    for loaded in selected_scenarios(args.scenario, args.variants):
        loaded.check_step(args.step)
        sized = args.drives == "sized"
        base = loaded if sized else loaded.drives_always_on()
        spec = args.variants
        if args.scenario == "all" and spec != "all":
            spec = ",".join(v.strip() for v in spec.split(",") if v.strip() in loaded.variants)
        variants = selected_variants(loaded, spec)
        unsupported = [name for name in variants if not engine.supports(
            loaded.variant(name).model or loaded.model)]
        if unsupported:
            raise UserError(f"--engine {args.engine} cannot run {loaded.name} variant(s) "
                            f"{', '.join(unsupported)} (model "
                            f"{loaded.variant(unsupported[0]).model or loaded.model}); "
                            f"choose --variants among the others")
        for loss_set, scenario in losses.loss_sets(base, args.losses):
            for name in variants:
                run_plan.check(scenario, scenario.variant(name), args.step)
            folder = losses.result_folder(out, scenario, loss_set)
            settings = {"engine": args.engine, "drives": args.drives, "step": args.step}
            results.check_result_set(folder, settings, args.replace)
            plans.append(Plan(scenario, variants, loss_set, folder, loaded if sized else None,
                              settings, args.replace))
    return plans


def run_variant(engine: Engine, scenario: scenarios.Scenario, name: str, step: float,
                options: dict[str, Any], drives: dict[str, JointDrive] | None = None,
                progress: Callable[[int], None] | None = None) -> RunResult:
    """One run (in a worker process, or here with a progress callback) with the given drives
    (None: the legacy ones); KeyboardInterrupt at its next recorded step once an interrupt is
    requested."""
    def advance(steps: int) -> None:
        interrupts.stop_if_requested()
        if progress is not None:
            progress(steps)

    from harness.engines.plan import prepare

    interrupts.stop_if_requested()
    return engine(prepare(scenario, scenario.variant(name), step, drives), advance, **options)


def size_variant(loaded: scenarios.Scenario, name: str, step: float) -> dict[str, Sizing]:
    """A variant's sizing (harness.run.sizing) for every loss set of its scenario."""
    from harness.run import sizing

    interrupts.stop_if_requested()
    return sizing.size_variant([s for _, s in losses.loss_sets(loaded, "all")], name, step)


def run_all(plans: list[Plan], step: float, workers: int = 1, quiet: bool = False,
            engine: str = "fmpy", options: dict[str, Any] | None = None) -> None:
    """Size the drives of every planned variant that needs it (once per variant, for all its
    loss sets), run every planned variant in the engine with them and write each result set
    with its drives.csv (and print its summary) once its runs are done; with workers above 1
    all in that many processes.
    A SIGINT or SIGTERM stops the runs (none is interrupted midway in its FMU, nor a write)
    and raises
    KeyboardInterrupt."""
    import pandas as pd
    from tqdm import tqdm

    from harness.run import sizing

    runner, options = ENGINES[engine], options or {}
    sizings = list(dict.fromkeys((plan.loaded.name, name) for plan in plans
                                 if plan.loaded is not None for name in plan.variants))
    loaded = {plan.loaded.name: plan for plan in plans if plan.loaded is not None}
    sized: dict[tuple[str, str], dict[str, Sizing]] = {}
    remaining = {index: len(plan.variants) for index, plan in enumerate(plans)}
    runs: dict[tuple[int, str], RunResult] = {}
    total = (sum(round(plan.scenario.duration / step) for plan in plans for _ in plan.variants)
             + sum(len(losses.loss_sets(loaded[key[0]].loaded, "all"))
                   * round(loaded[key[0]].loaded.duration / step) for key in sizings))

    def ready(key: tuple[str, str] | None) -> list[tuple]:
        """The run jobs a finished sizing (None: none needed) makes ready: (index, plan,
        variant, drives)."""
        return [(index, plan, name, None if key is None else sizing.joint_drives(
            sized[key], plan.loss_set)) for index, plan in enumerate(plans)
            for name in plan.variants
            if (key is None and plan.loaded is None)
            or (plan.loaded is not None and (plan.loaded.name, name) == key)]


    def finished(index: int, name: str, run: RunResult) -> tuple | None:
        """Book a run; the arguments of write_result_set when it was its set's last."""
        runs[index, name] = run
        remaining[index] -= 1
        if remaining[index]:
            return None
        plan = plans[index]
        rows = None if plan.loaded is None else pd.DataFrame([
            sizing.table_row(variant, joint, s) for variant in plan.variants
            for joint, s in sized[plan.loaded.name, variant].items()])
        return plan, [runs.pop((index, n)) for n in plan.variants], rows

    with interrupts.deferred(), tqdm(total=total, unit="step", unit_scale=True,
                                     disable=quiet) as bar:
        if workers == 1 or len(sizings) + sum(remaining.values()) == 1:
            jobs = ready(None)
            for key in sizings:
                bar.set_postfix_str(f"sizing {key[0]}.{key[1]}")
                sized[key] = size_variant(loaded[key[0]].loaded, key[1], step)
                bar.update(len(losses.loss_sets(loaded[key[0]].loaded, "all"))
                           * round(loaded[key[0]].loaded.duration / step))
                jobs += ready(key)
            for index, plan, name, drives in jobs:
                bar.set_postfix_str(f"{plan.scenario.name}.{name}")
                write = finished(index, name, run_variant(runner, plan.scenario, name, step,
                                                          options, drives, bar.update))
                if write is not None:
                    tqdm.write(write_result_set(*write))
            return
        context = multiprocessing.get_context()
        stop = context.Event()  # the workers' interrupts.requested
        # a signal sets the workers' flag at once
        with interrupts.shared(stop):
            pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                       initializer=interrupts.ignore_in_worker, initargs=(stop,))

            def submit(*call: object) -> Future:
                with interrupts.blocked():  # the workers (started here) and the pool's threads
                    return pool.submit(*call)

            def submit_runs(jobs: list[tuple]) -> None:
                # longest runs first, so that the last ones to start are short
                for index, plan, name, drives in sorted(
                        jobs, key=lambda job: -job[1].scenario.duration):
                    pending[submit(run_variant, runner, plan.scenario, name, step, options,
                                   drives)] = ("run", index, plan.scenario, name)

            try:
                pending: dict[Future, tuple] = {}
                for key in sizings:
                    pending[submit(size_variant, loaded[key[0]].loaded, key[1], step)] = (
                        "size", key)
                submit_runs(ready(None))
                while pending:
                    done, _ = wait(pending, POLL_INTERVAL, return_when=FIRST_COMPLETED)
                    interrupts.stop_if_requested()
                    for future in done:
                        job = pending.pop(future)
                        if job[0] == "write":  # a result set written
                            tqdm.write(future.result())
                        elif job[0] == "size":
                            key = job[1]
                            bar.update(len(losses.loss_sets(loaded[key[0]].loaded, "all"))
                                       * round(loaded[key[0]].loaded.duration / step))
                            sized[key] = future.result()
                            submit_runs(ready(key))
                        else:
                            _, index, scenario, name = job
                            bar.update(round(scenario.duration / step))
                            bar.set_postfix_str(f"{scenario.name}.{name} done")
                            write = finished(index, name, future.result())
                            if write is not None:
                                pending[submit(write_result_set, *write)] = ("write",)
            finally:  # done, failed or interrupted: the runs still going stop at their next
                stop.set()  # recorded step, a set not yet renamed into place is dropped; the
                pool.shutdown(cancel_futures=True)  # workers are waited for


def write_result_set(plan: Plan, runs: list[RunResult], drives: pd.DataFrame | None) -> str:
    """Write one result set's files into its folder (with the sizing rows of its drives),
    then redraw the scenario's headline figure from every loss set's summary there is
    (results.write_energy_figure: the set written last, whichever it is, leaves it showing
    both); their paths and the set's summary, to print."""
    from harness.run import results

    paths = results.write_run(runs, plan.scenario, plan.folder, plan.loss_set, drives,
                              plan.settings, plan.replace)
    paths.append(results.write_energy_figure(plan.scenario,
                                             losses.set_folders(plan.scenario_folder)))
    return "\n".join([*map(str, paths), results.summary_text(
        plan.folder / "summary.csv", plan.scenario, plan.loss_set)])


def run(args: argparse.Namespace) -> int:
    if args.workers < 1:
        raise UserError(f"--workers = {args.workers} must be at least 1")
    from harness.run import results

    options = engine_options(args)
    out = args.out or (results.RESULTS_DIR if args.engine == "fmpy"
                       else BUILD_RESULTS / args.engine)
    plans = plan(args, ENGINES[args.engine], out)
    run_all(plans, args.step, args.workers, args.quiet, args.engine, options)
    return 0

