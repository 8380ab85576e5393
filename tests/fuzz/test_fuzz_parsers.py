"""Property tests over the scenario and sweep file parsers: any hostile value in any field
either loads or is refused with the parser's own error (ValueError from the scenario core,
UserError from the harness) naming the field; never another exception, never a hang."""

from __future__ import annotations

import copy
import math
import time
import tomllib
from pathlib import Path
from typing import Any

import fuzzing  # noqa: F401 - registers and loads the hypothesis profile
import numpy as np
import pytest
from fuzzing import hostile_floats
from hypothesis import given
from hypothesis import strategies as st

from fmu_src.units.sequencer import scenario_format
from harness import scenarios
from harness.errors import UserError
from harness.sweeps import definition

BASE = tomllib.loads((scenarios.SCENARIO_DIR / "franchetti2021.toml").read_text())


def paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path into nested tables and lists."""
    out = []
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(
        data, list) else ()
    for key, value in items:
        out.append(prefix + (key,))
        out.extend(paths(value, prefix + (key,)))
    return out


PATHS = paths(BASE)
hostile_values = st.one_of(
    hostile_floats, st.integers(-10 ** 30, 10 ** 30), st.booleans(), st.text(max_size=4),
    st.integers(10 ** 308, 10 ** 400).map(lambda n: n * (-1) ** n),  # beyond a float
    st.lists(hostile_floats, max_size=2), st.dictionaries(st.text(max_size=3), hostile_floats,
                                                          max_size=2))


@given(st.sampled_from(PATHS), hostile_values)
def test_scenario_parser_names_the_field_or_loads(path: tuple, value: Any) -> None:
    data = copy.deepcopy(BASE)
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    try:
        parsed = scenario_format.parse(data, "fuzz.toml", scenarios.Scenario)
    except ValueError as error:
        named = [str(k).removesuffix("s") for k in path if not isinstance(k, int)]
        phase = path[1] if path[0] == "phases" and len(path) > 1 else None
        if phase is not None:
            named += [f"phase {BASE['phases'][phase]['name']}", f"phase {phase + 1}"]
        assert any(name in str(error) for name in named), (path, value, str(error))
        return
    # what loads evaluates to finite references at the phase boundaries
    times = np.array([t for _, t0, t1 in parsed.phase_times() for t in (t0, t1)])
    for joint in range(len(parsed.joints)):
        assert np.all(np.isfinite(parsed.reference(times, joint))), (path, value)
    assert all(math.isfinite(p.duration) and p.duration > 0 for p in parsed.phases)


SWEEP = '''
name = "fuzz"
scenario = "franchetti2021"
variants = ["self_regulating"]
step_size = 0.001
chunk_size = 4
seed = 0
[[axes]]
name = "k"
set = "parameters.k"
values = [500.0, 981.0]
[[axes]]
name = "payload"
set = ['phases["III regulate"].inputs.payload']
range = { start = 0.0, stop = 1.0, num = 3 }
'''
FIELDS = ('name = "fuzz"', 'scenario = "franchetti2021"', 'variants = ["self_regulating"]',
          'step_size = 0.001', 'chunk_size = 4', 'seed = 0',
          'name = "k"', 'set = "parameters.k"', 'values = [500.0, 981.0]',
          'range = { start = 0.0, stop = 1.0, num = 3 }', 'start = 0.0', 'stop = 1.0',
          'num = 3')
LITERALS = ('5', '"x"', '[]', '[1, 1]', '[[1.0]]', 'nan', 'inf', '-inf', '1e300', '2.7', '0',
            '-1', '1e12', '{ a = 1 }', 'true', '"../../x"', '""', '"0:1"', '[nan]', '1e-300',
            '1' + '0' * 400, '["self_regulating", "self_regulating"]', '1e-9')


@given(st.sampled_from(FIELDS), st.sampled_from(LITERALS))
def test_sweep_parser_names_the_field_or_loads(tmp_path_factory: pytest.TempPathFactory,
                                               field: str, literal: str) -> None:
    key = field.split(" = ")[0]
    path = Path(tmp_path_factory.mktemp("sweep")) / "fuzz.toml"
    path.write_text(SWEEP.replace(field, f"{key} = {literal}", 1))
    start = time.perf_counter()
    try:
        loaded = definition.load(path)
        runs = len(definition.plan(loaded))
    except UserError as error:
        assert key in str(error) or literal.strip('"') in str(error), (field, literal, error)
        return
    finally:
        assert time.perf_counter() - start < 5.0
    assert 1 <= runs <= definition.MAX_RUNS
