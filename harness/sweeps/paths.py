"""A sweep's set paths: the configuration a path such as `parameters.k` or
`phases[down].duration` names in a scenario, the motor or the controller design, and that
configuration with the path's value set (`configure`)."""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Iterable
from dataclasses import fields, is_dataclass, replace
from typing import Any

from harness import scenarios
from harness.drive.controller import ControllerDesign
from harness.drive.motor import MotorParameters
from harness.errors import UserError

DEGREE_FIELDS = {"target_deg": "target", "initial_angle_deg": "initial_angle"}


class PathError(UserError):
    """A set path that does not name anything in the run's configuration."""


class RefusedValueError(UserError):
    """A value the run's configuration refuses (out of its range): that run fails."""


_TOKEN = re.compile(r"\s*(?:\.?\s*([A-Za-z_]\w*)|\[([^\]]*)\])")


def _tokens(path: str) -> list[tuple[str, ...]]:
    """`phases["II move", "V move"].target_deg` -> [("phases",), ("II move", "V move"),
    ("target_deg",)]: each token names one attribute/key or a selection of names."""
    tokens, position = [], 0
    while position < len(path):
        match = _TOKEN.match(path, position)
        if not match:
            raise PathError(f"set path {path!r}: cannot read {path[position:]!r}")
        if match.group(1):
            tokens.append((match.group(1),))
        else:
            try:
                names = ast.literal_eval(f"({match.group(2)},)")
            except (ValueError, SyntaxError):
                names = None
            if not names or not all(isinstance(n, str) for n in names):
                raise PathError(f"set path {path!r}: [{match.group(2)}] is not a list of "
                                 "quoted names")
            tokens.append(tuple(names))
        position = match.end()
    return tokens


def _rebuilt(obj: Any, path: str, **changes: Any) -> Any:
    """replace(obj, **changes); RefusedValueError naming the path where obj's checks refuse."""
    try:
        return replace(obj, **changes)
    except ValueError as error:  # the class's range checks (ValueError naming the field)
        raise RefusedValueError(f"set path {path!r}: {error}") from None


def _replace(obj: Any, tokens: list[tuple[str, ...]], value: float | None, path: str) -> Any:
    """A copy of obj with the element at tokens set to value (a Ramp gets a new target);
    with value None only the path is checked (PathError) and obj returned as it is."""
    if not tokens:
        if value is None:
            return obj
        return _rebuilt(obj, path, target=value) if isinstance(obj, scenarios.Ramp) else value
    names, rest = tokens[0], tokens[1:]
    if is_dataclass(obj):
        name = names[0]
        if name in DEGREE_FIELDS and not rest:
            name, value = DEGREE_FIELDS[name], None if value is None else math.radians(value)
        known = [f.name for f in fields(obj)]
        if len(names) > 1 or name not in known:
            raise PathError(f"set path {path!r}: {type(obj).__name__} has no {names[0]!r} "
                             f"(fields: {', '.join(known)})")
        changed = _replace(getattr(obj, name), rest, value, path)
        return obj if value is None else _rebuilt(obj, path, **{name: changed})
    if isinstance(obj, dict):
        if rest and set(names) - set(obj):
            raise PathError(f"set path {path!r}: no {', '.join(set(names) - set(obj))} "
                             f"(known: {', '.join(obj)})")
        changes = {n: _replace(obj.get(n), rest, value, path) for n in names}
        return obj if value is None else {**obj, **changes}
    if isinstance(obj, tuple) and all(hasattr(item, "name") for item in obj):
        known = [item.name for item in obj]
        if set(names) - set(known):
            raise PathError(f"set path {path!r}: no {', '.join(set(names) - set(known))} "
                             f"(known: {', '.join(known)})")
        changed = tuple(_replace(item, rest, value, path) if item.name in names else item
                        for item in obj)
        return obj if value is None else changed
    raise PathError(f"set path {path!r}: cannot select {names} in a {type(obj).__name__}")


def _scaled(path: str) -> tuple[str, float]:
    """`0.5 * parameters.k` -> ("parameters.k", 0.5); a path without a factor has factor 1."""
    factor, times, rest = path.partition("*")
    if not times:
        return path, 1.0
    try:
        return rest.strip(), float(factor)
    except ValueError:
        raise PathError(f"set path {path!r}: {factor.strip()!r} is not a number (write "
                        "'<factor> * <path>')") from None


def configure(scenario: scenarios.Scenario, assignments: Iterable[tuple[str, float | None]]
              ) -> tuple[scenarios.Scenario, MotorParameters, ControllerDesign]:
    """The scenario, motor and controller design of one run: defaults with the assignments
    (path, value) applied in order, as new objects (the given scenario is not changed).

    PathError if a path names nothing; RefusedValueError if a value is out of its range.
    A value None sets nothing: it only checks its path."""
    config: dict[str, Any] = {"scenario": scenario, "motor": MotorParameters(),
                              "design": ControllerDesign()}
    for path, value in assignments:
        path, factor = _scaled(path)
        value = None if value is None else value * factor
        tokens = _tokens(path)
        head = tokens[0][0]
        if tokens == [("duration_scale",)]:
            if value is None:
                continue
            if not (value > 0.0 and math.isfinite(value)):
                raise RefusedValueError(f"duration_scale = {value} is outside (0, inf)")
            current = config["scenario"]
            config["scenario"] = _rebuilt(current, path, phases=tuple(
                _rebuilt(p, path, duration=p.duration * value) for p in current.phases))
        elif head in ("motor", "design"):
            config[head] = _replace(config[head], tokens[1:], value, path)
        else:
            config["scenario"] = _replace(config["scenario"], tokens, value, path)
    return config["scenario"], config["motor"], config["design"]
