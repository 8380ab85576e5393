"""Task scenarios as data: TOML files in this folder (or any path), evaluated on arrays.

The file format, the data model and its meaning are defined once in
`fmu_src.units.sequencer.scenario` (standard library only, shared with the ScenarioSequencer
FMU; see its docstring for the format). Here a scenario is found by name and gets vectorised
evaluation: the reference of a joint and the input signals at an array of times, with the core's
shapes and `ramp`. `embedded_source` is the module holding the scenario a ScenarioSequencer
FMU plays, which its build generates (`harness.fmu.build`). """

from __future__ import annotations

import pprint
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from fmu_src.units.sequencer import scenario as core
from fmu_src.units.sequencer import scenario_format
from fmu_src.units.sequencer.scenario import RAMP_SHAPES, Joint, Phase, Ramp, Variant, ramp
from harness import registry
from harness.errors import UserError

__all__ = ["MAX_STEPS", "RAMP_SHAPES", "SCENARIO_DIR", "Joint", "Phase", "Ramp", "Scenario",
           "Variant", "available", "embedded_source", "load", "ramp", "read_toml"]

SCENARIO_DIR = Path(__file__).resolve().parent
MAX_STEPS = 10_000_000  # communication steps per run: the series stay well inside memory


@dataclass(frozen=True)
class Scenario(core.Scenario):
    """A scenario with vectorised evaluation (numpy arrays of times [s]), the file it was
    loaded from (beside which a file outside harness/scenarios may keep its realistic loss
    set) and the loss set it is (`harness.scenarios.losses`: `ideal` as written)."""

    file: Path | None = field(default=None, repr=False, compare=False)
    loss_set: str = field(default="ideal", repr=False, compare=False)

    @property
    def folder(self) -> Path | None:
        """The folder of the file it was loaded from."""
        return None if self.file is None else self.file.parent

    def check_step(self, step: float, what: str = "--step") -> None:
        """UserError unless the communication step [s] is in [duration / MAX_STEPS, duration],
        the bound of every command (what: the option or field, for the message)."""
        if not self.duration / MAX_STEPS <= step <= self.duration:
            raise UserError(f"{what} = {step} s is outside [{self.duration / MAX_STEPS:g}, "
                            f"{self.duration:g}] (the scenario's duration in 1 to "
                            f"{MAX_STEPS:,} steps)")

    def drives_always_on(self) -> Scenario:
        """The scenario with no joint resting when holding (the legacy drive configuration:
        every drive on from start to end)."""
        def on(joints: tuple[Joint, ...]) -> tuple[Joint, ...]:
            return tuple(replace(joint, rest_when_holding=False) for joint in joints)
        return replace(self, joints=on(self.joints), variants={
            name: replace(variant, joints=on(variant.joints))
            for name, variant in self.variants.items()})

    def phase_indices(self, times: np.ndarray) -> np.ndarray:
        """Index of the phase holding each time (phases hold [start, end)); -1 before 0."""
        return np.searchsorted(np.array(self._phase_starts), times, side="right") - 1

    def reference(self, times: np.ndarray, joint: int | str = 0) -> np.ndarray:
        """Reference position of one joint (default the first) [rad or m]: quintic segments
        (the last one holds its end time too), in time linear in the phases and times."""
        t0, t1, start, end = np.array(self.reference_segments(joint)).T
        k = self.phase_indices(times)
        inside = (k >= 0) & (times <= self.duration)
        ref = np.where(k < 0, start[0], end[-1])
        i = k[inside]
        moved = start[i] + (end[i] - start[i]) * core.quintic((times[inside] - t0[i])
                                                             / (t1[i] - t0[i]))
        ref[inside] = np.where(start[i] == end[i], end[i], moved)
        return ref

    def variant(self, name: str) -> Variant:
        """The named variant; UserError naming the choices."""
        try:
            return super().variant(name)
        except ValueError as error:
            raise UserError(str(error)) from None

    def inputs(self, times: np.ndarray, variant: Variant) -> dict[str, np.ndarray]:
        """Input signals at the given times (a phase's changes apply from its start; 0 or
        false before 0), in time linear in the phases and times."""
        segments = self.input_segments(variant)
        k = self.phase_indices(times)
        inside = k >= 0
        i = k[inside]
        t0, t1 = np.array(self._phase_spans).T
        s = np.clip((times[inside] - t0[i]) / (t1[i] - t0[i]), 0.0, 1.0)
        signals: dict[str, np.ndarray] = {}
        for name, (_, first_end, _) in segments[0].items():
            starts, ends, shapes = zip(*(segment[name] for segment in segments), strict=True)
            boolean = isinstance(first_end, bool)
            signal = signals[name] = np.zeros(times.shape, dtype=bool if boolean else float)
            if boolean:  # Booleans step: a phase holds its value
                signal[inside] = np.array(ends, dtype=bool)[i]
                continue
            start, end = np.array(starts, dtype=float)[i], np.array(ends, dtype=float)[i]
            shape_of = np.array(shapes)[i]
            for shape in set(shapes):
                at = shape_of == shape
                ramped = start[at] + (end[at] - start[at]) * RAMP_SHAPES[shape](s[at])
                signal[np.flatnonzero(inside)[at]] = np.where(start[at] == end[at], end[at],
                                                              ramped)
        return signals


def scenario_file(name_or_path: str | Path) -> Path:
    """The file of a scenario given by name (harness/scenarios/<name>.toml) or path."""
    path = Path(name_or_path)
    if not path.suffix:
        path = SCENARIO_DIR / f"{name_or_path}.toml"
    if not path.exists():
        known = ", ".join(available())
        raise UserError(f"no scenario {str(name_or_path)!r} (known: {known})")
    return path


def read_toml(path: Path) -> dict[str, Any]:
    """The data of a TOML file (a scenario or a sweep); UserError naming the file when it is
    not a readable file of UTF-8 TOML."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise UserError(f"{path.name}: not UTF-8 text (byte {error.start} is "
                        f"{error.object[error.start]:#04x}); TOML files are UTF-8") from None
    except OSError as error:  # a folder, no permission, ...
        raise UserError(f"{path}: cannot be read as a file ({error.strerror or error})") from None
    try:
        return tomllib.loads(text)
    except RecursionError:  # tomllib recurses into nested arrays and inline tables
        raise UserError(f"{path.name}: arrays or tables nested too deeply") from None
    except ValueError as error:  # TOMLDecodeError, or an integer of more digits than int()
        raise UserError(f"{path.name}: not valid TOML ({error})") from None  # converts


def load(name_or_path: str | Path) -> Scenario:
    """Load a scenario by name (harness/scenarios/<name>.toml) or from a TOML file."""
    path = scenario_file(name_or_path)
    data = read_toml(path)
    try:
        return replace(scenario_format.parse(data, path.name, Scenario), file=path.resolve())
    except ValueError as error:  # the core is standard library only: it raises ValueError
        raise UserError(str(error)) from None


def available() -> list[str]:
    """Names of the scenarios shipped in harness/scenarios."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


EMBEDDED_TEMPLATE = '''"""The scenario the ScenarioSequencer plays: {origin}.

Generated by `harness.scenarios.embedded_source` for a build of the ScenarioSequencer
FMU (`harness.fmu.build`), in the build's staging folder: edit the TOML file and rebuild.
TOML is the file's text; DATA is that text parsed, what the FMU reads: it needs no TOML parser
(tomllib is Python 3.11+; the FMU runs on 3.8 and later).
"""
# ruff: noqa: E501

NAME = {name!r}
TOML = "\\n".join((
{lines})) + "\\n"
DATA = {data}
# the unit of each Real input the scenario drives: that of the mechanisms' input it feeds
INPUT_UNITS = {units!r}
'''


def embedded_source(name_or_path: str | Path) -> str:
    """The source of the ScenarioSequencer's module `sequencer_scenario`, holding a scenario's
    file (by name or path) as text, its data and the units of its Real inputs.

    The file must load (ValueError naming its problem otherwise); its text is embedded as it
    is, so the FMU parses exactly what `load` parses.
    """
    path = scenario_file(name_or_path)
    units = input_units(load(path))
    text = path.read_text()
    lines = "".join(f"    {line!r},\n" for line in text.splitlines())
    origin = (f"harness/scenarios/{path.name}"
              if path.resolve() == (SCENARIO_DIR / path.name).resolve()
              else f"the file {path.resolve()}")
    data = pprint.pformat(tomllib.loads(text), width=100, sort_dicts=False)
    return EMBEDDED_TEMPLATE.format(origin=origin, name=path.stem, lines=lines, data=data,
                                    units=units)


def input_units(scenario: Scenario) -> dict[str, str]:
    """The unit of each Real input the scenario drives, that of the input it feeds in the
    mechanism FMUs its variants run (harness.registry); UserError naming an input none of
    them has, or one they give different units."""
    from fmu_src.units.sequencer.ScenarioSequencer import scenario_inputs

    models = sorted({variant.model or scenario.model for variant in scenario.variants.values()})
    unknown = [model for model in models if registry.registration(model) is None]
    if unknown:
        raise UserError(f"scenario {scenario.name}: unknown model {', '.join(unknown)}")
    declared: dict[str, set[str]] = {}
    for model in models:
        for name, unit in registry.input_units(model).items():
            declared.setdefault(name, set()).add(unit)
    real = [name for name, value in scenario_inputs(scenario).items()
            if not isinstance(value, bool)]
    problems = [name for name in real if len(declared.get(name, ())) != 1]
    if problems:
        raise UserError(f"scenario {scenario.name} drives the Real input(s) "
                        f"{', '.join(problems)}, which the models of its variants "
                        f"({', '.join(models)}) do not have (or give different units)")
    return {name: next(iter(declared[name])) for name in real}
