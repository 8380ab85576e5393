"""Loss sets: the shipped scenarios run again with the losses of real parts (docs/losses.md).

A scenario's variants as written are the `ideal` set. A scenario with a loss file,
harness/scenarios/realistic/<scenario>.toml (or realistic/<scenario>.toml beside the
scenario's own file), also has a `realistic` set: the same variants
with the loss file's parameters. Its tables:

- `[models.<Model>]`: parameters set in every variant that runs that model (joint, slider
  and pulley friction, pulley inertia, spring free length, slider mass);
- `[variants.<variant>]`: `parameters` and `phase_targets` (the format of the scenario's
  variants) over those, for one variant: what a design rule makes of its geometry with the
  real parts (where the slider sits, where the carriage goes) and what it does not have (the
  unbalanced link has no slider).

A variant's parameters are then the scenario's, its own, its model's losses and its own
losses, each over the one before. The realistic set is a result set of its own,
results/<scenario>/realistic/, in the format of docs/results.md.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import tomli_w

from fmu_src.units.sequencer import scenario as core
from fmu_src.units.sequencer.checks import parameter_values, position, table, unknown_keys
from harness.errors import UserError
from harness.io import write_atomic
from harness.scenarios import SCENARIO_DIR, Scenario, read_toml

LOSSES_DIR = Path(__file__).resolve().parent / "realistic"
LOSS_SETS = ("ideal", "realistic")
REALISTIC_FOLDER = "realistic"   # the realistic set's folder inside results/<scenario>/
VARIANT_KEYS = ("parameters", "phase_targets")


def loss_file(scenario: Scenario) -> Path:
    """The loss file of a scenario (whether it exists or not): realistic/<scenario>.toml
    beside the scenario's file where there is one (a generated task's,
    `harness.study.tasks`), else harness/scenarios/realistic/<scenario>.toml."""
    if scenario.folder is not None and scenario.folder != SCENARIO_DIR:
        beside = scenario.folder / REALISTIC_FOLDER / f"{scenario.name}.toml"
        if beside.exists():
            return beside
    return LOSSES_DIR / f"{scenario.name}.toml"


def has_realistic(scenario: Scenario) -> bool:
    """Whether the scenario has a realistic set (a loss file of its name)."""
    return loss_file(scenario).exists()


def realistic(scenario: Scenario, data: dict[str, Any] | None = None) -> Scenario:
    """The scenario with every variant's parameters (and the phase targets the loss file
    gives) those of real parts; UserError naming the file and the key that is wrong.
    data: the loss file's tables, if not read from the scenario's loss file."""
    path = loss_file(scenario)
    data = read_toml(path) if data is None else data
    where = path.name
    try:
        unknown_keys(data, ("models", "variants"), where)
        models = {model: parameter_values(values, f"{where} models.{model}")
                  for model, values in table(data.get("models", {}), "models").items()}
        used = {variant.model or scenario.model for variant in scenario.variants.values()}
        unused = sorted(set(models) - used)
        if unused:
            raise ValueError(f"models.{unused[0]} is no model of scenario {scenario.name}'s "
                             f"variants ({', '.join(sorted(used))})")
        overrides = table(data.get("variants", {}), "variants")
        unknown = sorted(set(overrides) - set(scenario.variants))
        if unknown:
            raise ValueError(f"variants.{unknown[0]} names no variant of scenario "
                             f"{scenario.name}; choose from {', '.join(scenario.variants)}")
        variants = {}
        for name, variant in scenario.variants.items():
            raw = table(overrides.get(name, {}), f"variants.{name}")
            unknown_keys(raw, VARIANT_KEYS, f"variants.{name}")
            own = parameter_values(raw.get("parameters", {}), f"variants.{name} parameters")
            targets = _phase_targets(scenario, variant, raw.get("phase_targets", {}),
                                     f"variants.{name} phase_targets")
            variants[name] = replace(
                variant, parameters={**variant.parameters,
                                     **models.get(variant.model or scenario.model, {}), **own},
                phase_targets={**variant.phase_targets, **targets})
    except ValueError as error:
        raise UserError(f"{where}: {error}") from None
    return replace(scenario, variants=variants, loss_set="realistic")


def played_file(scenario: Scenario, folder: Path) -> Path:
    """The scenario file a ScenarioSequencer plays the scenario's loss set from: the file it
    was loaded from for the ideal set; for the realistic set that file's data with the loss
    file's phase targets over its variants' (what a loss set changes of the task itself, its
    parameters being the mechanism's), written as folder/<scenario>.toml when it differs
    from what is there. UserError when the scenario was not loaded from a file."""
    if scenario.file is None:
        raise UserError(f"scenario {scenario.name} was not loaded from a file, which a "
                        "ScenarioSequencer plays")
    if scenario.loss_set == "ideal":
        return scenario.file
    data = read_toml(scenario.file)
    for name, raw in read_toml(loss_file(scenario)).get("variants", {}).items():
        variant = data.setdefault("variants", {}).setdefault(name, {})
        targets = variant.setdefault("phase_targets", {})
        for phase, changes in raw.get("phase_targets", {}).items():
            targets[phase] = {**targets.get(phase, {}), **changes}
    path = folder / f"{scenario.name}.toml"
    text = tomli_w.dumps(data)
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path


def _phase_targets(scenario: Scenario, variant: core.Variant, raw: object, where: str
                   ) -> dict[str, dict[str, float]]:
    """Targets of the variant's own joints by phase [rad or m], checked as the scenario's."""
    phases = {phase.name for phase in scenario.phases}
    own = {joint.name for joint in variant.joints}
    targets = {}
    for phase, changes in table(raw, where).items():
        if phase not in phases:
            raise ValueError(f"{where} names no phase {phase!r}")
        changes = table(changes, f"{where} {phase}")
        unknown = sorted(set(changes) - own)
        if unknown:
            raise ValueError(f"{where} {phase}: {unknown[0]} is no joint of the variant's own "
                             f"({', '.join(sorted(own)) or 'none'})")
        targets[phase] = {joint: position(value, f"{where} {phase} {joint}")
                          for joint, value in changes.items()}
    return targets


def loss_sets(scenario: Scenario, selected: str) -> list[tuple[str, Scenario]]:
    """(loss set, scenario) for `--losses` ('all', or a comma-separated list of LOSS_SETS):
    with 'all' the realistic set where the scenario has a loss file; named, it must have
    one (UserError otherwise)."""
    names = list(LOSS_SETS) if selected == "all" else [s.strip() for s in selected.split(",")]
    wrong = [name for name in names if name not in LOSS_SETS]
    if wrong or not names:
        raise UserError(f"--losses = {selected!r} must be 'all' or a comma-separated list of "
                        f"{', '.join(LOSS_SETS)}")
    sets = []
    for name in dict.fromkeys(names):
        if name == "ideal":
            sets.append((name, scenario))
        elif has_realistic(scenario):
            sets.append((name, realistic(scenario)))
        elif selected != "all":
            raise UserError(f"--losses {name}: scenario {scenario.name} has no loss file "
                            f"{loss_file(scenario)}")
    return sets


def set_folders(scenario_folder: Path) -> dict[str, Path]:
    """Each loss set's result folder in a scenario's folder (OUT/<scenario>/), ideal first:
    the ideal set in it, the realistic set in its REALISTIC_FOLDER."""
    return {"ideal": scenario_folder, "realistic": scenario_folder / REALISTIC_FOLDER}


def result_folder(out: Path, scenario: Scenario, loss_set: str) -> Path:
    """Where a loss set's result set goes: OUT/<scenario>/, the realistic set in its
    REALISTIC_FOLDER (set_folders)."""
    return set_folders(out / scenario.name)[loss_set]
