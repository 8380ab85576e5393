"""The scenario plot's panels come from the registrations (harness.run.plots)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from harness import registry
from harness import scenarios as scenario_files
from harness.run import plots

MECHANISMS = registry.mechanisms()


@pytest.mark.parametrize("model", sorted(MECHANISMS))
def test_every_plot_panel_draws_variables_of_its_model_in_the_panel_unit(model: str) -> None:
    """Every name of a registration's plot_panels is an input or output of its physics, and
    the unit it is drawn in (mm for m, deg for rad) is one of its panel's units."""
    physics = MECHANISMS[model].physics
    units = {v.name: v.unit for v in (*physics.INPUT_VARIABLES, *physics.OUTPUT_VARIABLES)}
    for title, unit, names in MECHANISMS[model].plot_panels:
        assert names, title
        for name in names:
            assert name in units, (title, name)
            drawn = plots.DRAWN_IN.get(units[name], (units[name].replace(".", " "), None))[0]
            assert drawn in unit.split(" | "), (title, name, units[name])


def test_panels_of_one_title_are_one_panel_in_order_of_appearance() -> None:
    """The one-link models' panels merge by title: each name once, first model first, metres
    drawn in mm and kilograms as they are."""
    merged = plots.declared_panels(["SelfRegulatingBalancer", "CiupituBalancer",
                                    "SelfRegulatingBalancer", "ActiveSpringBalancer"])
    names = {title: [name for name, _ in signals] for title, _, signals in merged}
    assert list(names) == ["(b) energies", "(c) adjuster travel and payload",
                           "(d) spring length or counterweight position"]
    assert names["(b) energies"] == ["E_p", "E_e", "E_t"]
    assert names["(c) adjuster travel and payload"] == ["delta_b", "payload", "q"]
    assert names["(d) spring length or counterweight position"] == ["x", "OB", "l_s"]
    conversions = {name: convert for _, _, signals in merged for name, convert in signals}
    assert conversions["x"](np.array([0.25])) == pytest.approx([250.0])
    assert conversions["payload"] is None and conversions["E_p"] is None
    reversed_order = plots.declared_panels(["CiupituBalancer", "SelfRegulatingBalancer"])
    assert [name for name, _ in reversed_order[2][2]] == ["OB", "x"]


def test_plot_draws_each_variant_signal_it_has_in_its_panel(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """In the one-joint figure, each variant draws the panel signals its series has (colour
    per variant, line style per signal), the reference once, in the units of the panel."""
    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figures.append(fig) or path)
    time = np.linspace(0.0, 1.0, 5)
    common = {"time": time, "theta": time, "theta_ref": time, "E_p": time, "payload": 0 * time,
              "tau_drive": time, "i": time, "P_elec": time, "E_drawn": time}
    runs = [SimpleNamespace(variant="a", model="SelfRegulatingBalancer",
                            series=pd.DataFrame({**common, "x": 0.1 + 0 * time})),
            SimpleNamespace(variant="b", model="CiupituBalancer",
                            series=pd.DataFrame({**common, "OB": 0.2 + 0 * time}))]
    plots.plot(runs, scenario_files.load("franchetti2021"), tmp_path / "p.png")
    axes = {ax.get_title(loc="left"): ax for ax in figures[0].axes if ax.get_visible()}
    geometry = axes["(d) spring length or counterweight position"]
    drawn = [(line.get_linestyle(), line.get_ydata()[0]) for line in geometry.get_lines()]
    assert drawn == [("-", pytest.approx(100.0)), ("--", pytest.approx(200.0))]
    angle = axes["(a) link angle"]
    assert len(angle.get_lines()) == 3  # theta of each variant, the reference of the first
    assert angle.get_lines()[1].get_ydata()[-1] == pytest.approx(np.degrees(1.0))
    assert axes["(c) adjuster travel and payload"].get_ylabel() == "mm | kg"
