"""The documentation inside every FMU, `documentation/index.html`, generated at build time.

It comes from the same sources as the model description: the docstrings of the slave script
(module and classes) and of the model modules it imports give the equations; the built
modelDescription.xml gives the variables with their units, start values and bounds and the
default experiment. The reference plot (`documentation/reference.png`) is a simulation of the
built FMU with FMPy: the model's reference run (`reference_run`, from the FMU's registration:
input signals, stop time and the variables to record; `harness.fmu.cross_check` publishes the same
run as the FMI cross-check reference), or for a model without one its default experiment with
the inputs at their start values.
"""

from __future__ import annotations

import ast
import html
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy
import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.model_description import ModelDescription, ModelVariable

from fmu_src.mechanism import DocumentedRun
from harness import registry

OUTPUT_INTERVAL = 0.01  # default spacing of the recorded reference result [s]
RELATIVE_TOLERANCE = 1e-4  # passed to fmi2SetupExperiment; the FMUs step with fixed schemes
ME_RELATIVE_TOLERANCE = 1e-8  # CVode's, for a Model Exchange reference result
# fmu_src modules that carry FMI plumbing, not model equations
PLUMBING = ("fmi", "mechanism.py", "parameters.py")  # a folder or module of fmu_src


@dataclass(frozen=True)
class ReferenceRun:
    """A documented simulation of a model.

    inputs: structured array, `time` first then one column per input, in the FMI cross-check
    input convention (linear interpolation; a repeated time is a step); the run ends at its
    last time (without inputs, at the default experiment's stop time). outputs: the
    variables to record (None: all outputs), every output_interval [s] (at least every step).
    """

    description: str
    inputs: np.ndarray | None = None
    outputs: tuple[str, ...] | None = None
    output_interval: float = OUTPUT_INTERVAL


def input_table(names: tuple[str, ...], rows: list[tuple[float, ...]]) -> np.ndarray:
    """Input signals from rows (time, value per name); Booleans as 0/1."""
    return np.array(rows, dtype=[("time", np.float64)] + [(n, np.float64) for n in names])


def reference_run(model: str) -> ReferenceRun:
    """The reference run the model's registration declares (harness.registry); the default
    experiment for a model without one."""
    found = registry.registration(model)
    run = DocumentedRun() if found is None else found.reference_run
    return ReferenceRun(run.description,
                        input_table(run.input_names, list(run.input_rows)) if run.input_rows
                        else None, run.outputs, run.output_interval or OUTPUT_INTERVAL)


def step_size(md: ModelDescription) -> float:
    """The default experiment's step size [s] (1 ms if it has none)."""
    experiment = md.defaultExperiment
    return float(experiment.stepSize) if experiment and experiment.stepSize else 1e-3


def stop_time(md: ModelDescription, run: ReferenceRun) -> float:
    """The run's stop time [s]: its inputs' last time, else the default experiment's, else 1 s."""
    experiment = md.defaultExperiment
    if run.inputs is not None:
        return float(run.inputs["time"][-1])
    return float(experiment.stopTime) if experiment and experiment.stopTime else 1.0


def output_interval(md: ModelDescription, run: ReferenceRun) -> float:
    """The spacing of the run's recorded result [s]: its own, at least one step."""
    return max(run.output_interval, step_size(md))


def simulate_reference(fmu: Path, run: ReferenceRun, fmi_type: str = "CoSimulation"
                       ) -> np.ndarray:
    """The run simulated with FMPy at the default step size (Co-Simulation; Model Exchange:
    CVode at ME_RELATIVE_TOLERANCE, its outputs at every such step) and recorded every
    output_interval, and at the steps before and after every switch of a Boolean (so a
    switch between two recorded times keeps its time); Booleans as 0/1."""
    md = read_model_description(str(fmu))
    tolerance = RELATIVE_TOLERANCE if fmi_type == "CoSimulation" else ME_RELATIVE_TOLERANCE
    result = simulate_fmu(str(fmu), fmi_type=fmi_type, stop_time=stop_time(md, run),
                          output_interval=step_size(md), relative_tolerance=tolerance,
                          input=run.inputs,
                          output=None if run.outputs is None else list(run.outputs))
    interval = output_interval(md, run)
    time = result["time"]
    keep = np.abs(time - np.round(time / interval) * interval) < 1e-9 * interval
    keep[[0, -1]] = True
    for name in result.dtype.names[1:]:
        if result.dtype[name] == np.bool_:
            switch = np.flatnonzero(np.diff(result[name])) + 1
            keep[switch] = keep[switch - 1] = True
    return result[keep].astype([(n, np.float64) for n in result.dtype.names])


# ---- HTML ----------------------------------------------------------------------------------
def docstring_html(text: str) -> str:
    """A docstring as HTML: blocks indented by four spaces preformatted, lines starting with
    "- " (continued by indented lines) as list items, other text as paragraphs."""
    parts = []
    for block in text.strip().split("\n\n"):
        lines = block.split("\n")
        if all(line.startswith("    ") for line in lines):
            parts.append("<pre>" + html.escape("\n".join(line[4:] for line in lines)) + "</pre>")
            continue
        pieces: list[tuple[str, list[str]]] = []  # ("li" or "p", lines)
        for line in lines:
            if line.startswith("- "):
                pieces.append(("li", [line[2:]]))
            elif pieces and (pieces[-1][0] == "p" or line.startswith("  ")):
                pieces[-1][1].append(line)
            else:
                pieces.append(("p", [line]))
        in_list = False
        for kind, text in pieces:
            if (kind == "li") != in_list:
                parts.append("<ul>" if kind == "li" else "</ul>")
                in_list = kind == "li"
            parts.append(f"<{kind}>{html.escape(' '.join(t.strip() for t in text))}</{kind}>")
        if in_list:
            parts.append("</ul>")
    return "\n".join(parts)


def model_sections(script: Path, modules: list[Path], stage: Path) -> list[tuple[str, str]]:
    """(title, docstring) of the slave script, its classes, and the model modules among the
    fmu_src modules it uses (staged in stage/fmu_src)."""
    tree = ast.parse(script.read_text())
    sections = [(script.name, ast.get_docstring(tree) or "")]
    sections += [(f"class {node.name}", ast.get_docstring(node))
                 for node in tree.body
                 if isinstance(node, ast.ClassDef) and ast.get_docstring(node)]
    for path in modules:
        name = path.relative_to(stage)
        if name.parts[1] not in PLUMBING:
            docstring = ast.get_docstring(ast.parse(path.read_text()))
            if docstring:
                sections.append((name.as_posix(), docstring))
    return sections


VARIABLE_COLUMNS = ("Name", "Causality", "Variability", "Type", "Unit", "Start", "Min", "Max",
                    "Depends on", "Description")


def unit_of(variable: ModelVariable) -> str:
    """The variable's unit, declared on it or on its type ('' for none)."""
    declared = variable.declaredType
    return variable.unit or (declared.unit if declared is not None else None) or ""


def variable_cells(md: ModelDescription) -> list[tuple[str, ...]]:
    """Per model variable, its VARIABLE_COLUMNS as text ('' where not given); an output's
    'Depends on' names the inputs it depends on (not the continuous states that Model
    Exchange lists too)."""
    depends_on = {u.variable.name: ", ".join(d.name for d in u.dependencies or ()
                                             if d.causality == "input")
                  for u in md.outputs}
    rows = []
    for v in md.modelVariables:
        declared = v.declaredType
        low = v.min if v.min is not None else getattr(declared, "min", None)
        high = v.max if v.max is not None else getattr(declared, "max", None)
        rows.append(tuple("" if c is None else str(c) for c in (
            v.name, v.causality, v.variability, v.type, unit_of(v), v.start, low, high,
            depends_on.get(v.name), v.description)))
    return rows


def variables_html(md: ModelDescription) -> str:
    """One table row per model variable."""
    rows = ["<tr>" + "".join(
        f"<td>{f'<code>{html.escape(c)}</code>' if i == 0 else html.escape(c)}</td>"
        for i, c in enumerate(cells)) + "</tr>" for cells in variable_cells(md)]
    header = "".join(f"<th>{c}</th>" for c in VARIABLE_COLUMNS)
    return f'<table class="variables">\n<tr>{header}</tr>\n' + "\n".join(rows) + "\n</table>"


def plot_reference(md: ModelDescription, run: ReferenceRun, result: np.ndarray,
                   path: Path) -> None:
    """Inputs and recorded variables against time, one panel per unit, as a PNG."""
    variables = {v.name: v for v in md.modelVariables}
    names = ([] if run.inputs is None else list(run.inputs.dtype.names[1:])) + list(
        result.dtype.names[1:])
    panels: dict[str, list[str]] = {}
    for name in names:
        panels.setdefault(unit_of(variables[name]) or variables[name].type, []).append(name)
    from matplotlib.figure import Figure  # the FMUs' build draws; the rest of fmu does not

    figure = Figure(figsize=(8.0, 1.9 * len(panels) + 0.6), layout="constrained")
    axes = figure.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (unit, members) in zip(axes, panels.items()):
        for name in members:
            if run.inputs is not None and name in run.inputs.dtype.names:
                ax.plot(run.inputs["time"], run.inputs[name], "--", label=f"{name} (input)")
            else:  # a Boolean holds its value until the next recorded time
                ax.plot(result["time"], result[name], label=name, drawstyle=(
                    "steps-post" if variables[name].type == "Boolean" else "default"))
        ax.set_ylabel(unit)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time [s]")
    figure.suptitle(f"{md.modelName}: reference run")
    figure.savefig(path, dpi=80)


def interfaces(md: ModelDescription) -> str:
    """The FMI interfaces the FMU offers, in words."""
    if md.modelExchange is None:
        return "Co-Simulation"
    return ("Co-Simulation and Model Exchange (continuous states: the physics' state with "
            f"its energy account; {md.numberOfEventIndicators} event indicators)")


def index_html(md: ModelDescription, run: ReferenceRun, sections: list[tuple[str, str]]) -> str:
    """The documentation page."""
    experiment = md.defaultExperiment
    default = ("none" if experiment is None else
               f"start {experiment.startTime} s, stop {experiment.stopTime} s, "
               f"step {experiment.stepSize} s")
    model = "\n".join(f"<h3>{html.escape(title)}</h3>\n{docstring_html(text)}"
                      for title, text in sections)
    name = html.escape(md.modelName)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{name}</title>
<style>
body {{ font-family: sans-serif; max-width: 60em; margin: auto; }}
table {{ border-collapse: collapse; font-size: small; }}
td, th {{ border: 1px solid #ccc; padding: 0.2em 0.4em; text-align: left; }}
pre {{ background: #f4f4f4; padding: 0.5em; }}
</style>
</head>
<body>
<h1>{name}</h1>
<p>{html.escape(md.description or "")}</p>
<p>FMI {md.fmiVersion} {interfaces(md)}, generated by {html.escape(md.generationTool or "")};
GUID {html.escape(md.guid)}. The FMU runs Python code with the
standard library only; it does not bundle Python: the machine must have a CPython 3.8 or
later shared library, which the linux64 binary loads by itself in a host that is not a Python
process (override: the environment variable BALANCER_FMU_LIBPYTHON).
needsExecutionTool is false: the FMU contains its whole model, the Python code of its slave
and of every module it imports, which its own binary runs; it needs a CPython library as a C
FMU needs its C runtime, and no tool.</p>
<h2>Model</h2>
{model}
<h2>Variables</h2>
<p>SI units; angles in radians (displayed in degrees where a display unit is declared).</p>
{variables_html(md)}
<h2>Default experiment</h2>
<p>{default}.</p>
<h2>Reference result</h2>
<p>{html.escape(run.description)} Simulated with FMPy {fmpy.__version__} from 0 to
{stop_time(md, run)} s with a communication step of {step_size(md)} s, recorded every
{output_interval(md, run)} s: the FMI cross-check reference of this model, written by
<code>python -m harness cross-check</code>.</p>
<img src="reference.png" alt="Reference result of {name}">
</body>
</html>
"""


def write_documentation(fmu: Path, script: Path, modules: list[Path], stage: Path,
                        folder: Path) -> None:
    """index.html and reference.png into folder, for the FMU built from the slave script
    and the fmu_src modules it uses (staged in stage/fmu_src)."""
    md = read_model_description(str(fmu))
    run = reference_run(md.modelName)
    result = simulate_reference(fmu, run)
    plot_reference(md, run, result, folder / "reference.png")
    (folder / "index.html").write_text(index_html(md, run, model_sections(script, modules, stage)))


def add_documentation(fmu: Path, script: Path, modules: list[Path], stage: Path) -> None:
    """Generate the documentation of the FMU built from the slave script and the fmu_src
    modules it uses (staged in stage/fmu_src), and add it to the FMU's archive as
    documentation/."""
    with tempfile.TemporaryDirectory(prefix=f"doc_{script.stem}_") as tmp:
        folder = Path(tmp)
        write_documentation(fmu, script, modules, stage, folder)
        with zipfile.ZipFile(fmu, "a", compression=zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(folder.iterdir()):
                archive.write(path, f"documentation/{path.name}")
