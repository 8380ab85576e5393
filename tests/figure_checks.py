"""Checks of a drawn matplotlib figure, read from its artists' display extents once it is
laid out (`draw`: `fig.draw_without_rendering()` on an Agg canvas, the draw of
`fig.canvas.draw()` without painting). Each check returns the defects it finds, one line
each (none: the figure passes); `defects` runs them all.

These live with the tests, not in the harness's save_figure: a figure is a view of results
that took hours to compute, and a check that refused to save it over a label a pixel too
long would lose the view and keep nothing. The tests run them on every committed figure's
producer and on made-up data.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from weakref import WeakSet

import numpy as np
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.backend_bases import RendererBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PathCollection
from matplotlib.colors import to_hex
from matplotlib.container import BarContainer
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.lines import Line2D
from matplotlib.text import Annotation, Text
from matplotlib.transforms import Bbox

from harness.run.plots import NO_MARKER

SLACK = 0.5          # [px] what an extent may pass an edge or overlap by, rounding
COINCIDE_PX = 1.5    # [px] a line within this of a later one at HIDDEN_SHARE of its points
HIDDEN_SHARE = 0.9   # is hidden by it (unless markers or gaps of its own show)
LEAST_LOG_TICKS = 3


_DRAWN: WeakSet[Figure] = WeakSet()  # the figures laid out once (reading ticks marks stale)


def draw(fig: Figure) -> RendererBase:
    """Lay the figure out on an Agg canvas as its PNG would be (every extent placed, no
    pixel painted), the first time it is checked; its renderer."""
    if fig not in _DRAWN or not isinstance(fig.canvas, FigureCanvasAgg):
        if not isinstance(fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(fig)
        fig.draw_without_rendering()
        _DRAWN.add(fig)
    return fig.canvas.get_renderer()


def _where(ax: Axes) -> str:
    """An axes named for a finding: its title, or its place."""
    title = ax.get_title(loc="left") or ax.get_title()
    x, y = ax.get_position().p0
    return repr(title) if title else f"the axes at ({x:.2f}, {y:.2f}) of the figure"


def drawn_axes(fig: Figure) -> list[Axes]:
    """The visible axes, their child axes (a secondary axis) included."""
    found: list[Axes] = []

    def add(axes: list[Axes]) -> None:
        for ax in axes:
            if ax.get_visible() and ax not in found:
                found.append(ax)
                add(ax.child_axes)

    add(fig.axes)
    return found


def drawn_tick_labels(axis: Axis) -> list[Text]:
    """The tick labels an axis draws: its ticks inside the view, labels switched on and not
    empty (matplotlib keeps the Text of a tick outside the view)."""
    ticks = axis._update_ticks()  # noqa: SLF001 - what Axis.draw draws, in matplotlib's words
    return [label for tick in ticks for label in (tick.label1, tick.label2)
            if label.get_visible() and label.get_text().strip()]


def _legend_texts(legend: Legend) -> list[Text]:
    return [*legend.get_texts(), legend.get_title()]


def drawn_texts(fig: Figure, renderer: RendererBase) -> list[tuple[str, Text, object]]:
    """Every text the figure draws, (what it is, the Text, its group: the legend it belongs
    to or None): titles, axis labels, tick labels, offsets, annotations, legend entries."""
    found: list[tuple[str, Text, object]] = []
    for text in fig.get_children():
        if isinstance(text, Text):
            found.append(("figure text", text, None))
    for legend in fig.legends:
        found += [("figure legend", t, legend) for t in _legend_texts(legend)]
    for ax in drawn_axes(fig):
        where = _where(ax)
        for child in ax.get_children():
            if isinstance(child, Text):
                found.append((f"{where}: text", child, None))
        for axis in (ax.xaxis, ax.yaxis):
            found += [(f"{where}: {axis.axis_name} label", axis.label, None),
                      (f"{where}: {axis.axis_name} offset", axis.offsetText, None)]
            found += [(f"{where}: {axis.axis_name} tick", t, None)
                      for t in drawn_tick_labels(axis)]
        if ax.get_legend() is not None:
            found += [(f"{where}: legend", t, ax.get_legend())
                      for t in _legend_texts(ax.get_legend())]
    return [(what, text, group) for what, text, group in found
            if text.get_visible() and text.get_text().strip()
            and not (isinstance(text, Annotation) and not text._check_xy(renderer))]  # noqa: SLF001


def _legends(fig: Figure) -> list[Legend]:
    return [*fig.legends, *(ax.get_legend() for ax in drawn_axes(fig) if ax.get_legend())]


def _label(text: Text) -> str:
    return repr(" ".join(text.get_text().split())[:60])


def texts_outside(fig: Figure) -> list[str]:
    """Texts whose extent leaves the figure (cut off in the PNG)."""
    renderer = draw(fig)
    box = fig.bbox
    return [f"{what} {_label(text)} leaves the figure"
            for what, text, _ in drawn_texts(fig, renderer)
            if (e := text.get_window_extent(renderer)).x0 < box.x0 - SLACK
            or e.x1 > box.x1 + SLACK or e.y0 < box.y0 - SLACK or e.y1 > box.y1 + SLACK]


def _overlapping(boxes: np.ndarray) -> Iterator[tuple[int, int]]:
    """Pairs (i < j) of boxes (rows x0, y0, x1, y1) that share more than SLACK each way."""
    x0, y0, x1, y1 = boxes.T
    width = np.minimum(x1[:, None], x1[None, :]) - np.maximum(x0[:, None], x0[None, :])
    height = np.minimum(y1[:, None], y1[None, :]) - np.maximum(y0[:, None], y0[None, :])
    hits = (width > SLACK) & (height > SLACK)
    for i, j in zip(*np.nonzero(np.triu(hits, 1)), strict=True):
        yield int(i), int(j)


def overlapping_texts(fig: Figure) -> list[str]:
    """Pairs of texts whose extents overlap, a legend's frame counted as one (its own texts
    inside it)."""
    renderer = draw(fig)
    items = [(what, _label(text), text.get_window_extent(renderer), group)
             for what, text, group in drawn_texts(fig, renderer)]
    items += [("legend frame", "", legend.get_window_extent(renderer), legend)
              for legend in _legends(fig)]
    boxes = np.array([[b.x0, b.y0, b.x1, b.y1] for _, _, b, _ in items]).reshape(-1, 4)
    found = []
    for i, j in _overlapping(boxes):
        (what_i, label_i, _, group_i), (what_j, label_j, _, group_j) = items[i], items[j]
        frames = what_i == "legend frame" or what_j == "legend frame"
        if frames and group_i is group_j:
            continue  # a legend's texts lie in its frame
        found.append(f"{what_i} {label_i} overlaps {what_j} {label_j}")
    return found


def _segments_enter(points: np.ndarray, box: Bbox) -> bool:
    """Whether the polyline through points (display, NaN breaking it) has a point in box or
    a segment crossing it (Liang-Barsky, every segment at once)."""
    finite = np.isfinite(points).all(axis=1)
    p = points[finite]
    inside = ((p[:, 0] > box.x0) & (p[:, 0] < box.x1) & (p[:, 1] > box.y0)
              & (p[:, 1] < box.y1))
    if inside.any():
        return True
    keep = finite[:-1] & finite[1:]
    start, end = points[:-1][keep], points[1:][keep]
    if not len(start):
        return False
    d = end - start
    enter, leave = np.zeros(len(d)), np.ones(len(d))
    crossing = np.ones(len(d), bool)
    for k, (low, high) in enumerate(((box.x0, box.x1), (box.y0, box.y1))):
        moving = d[:, k] != 0
        still = ~moving & ((start[:, k] <= low) | (start[:, k] >= high))
        crossing &= ~still
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = (low - start[:, k]) / d[:, k]
            t1 = (high - start[:, k]) / d[:, k]
        near, far = np.minimum(t0, t1), np.maximum(t0, t1)
        enter = np.where(moving, np.maximum(enter, near), enter)
        leave = np.where(moving, np.minimum(leave, far), leave)
    return bool((crossing & (enter < leave)).any())


def legend_over_data(fig: Figure) -> list[str]:
    """Legends over an axes' plotted data: a line's points or segments, a bar or patch, a
    scatter point, an image or other collection inside the legend's frame."""
    renderer = draw(fig)
    found = []
    for legend in _legends(fig):
        frame = legend.get_window_extent(renderer)
        for ax in drawn_axes(fig):
            area = Bbox.intersection(frame, ax.bbox)
            if area is None or area.width <= SLACK or area.height <= SLACK:
                continue
            where = _where(ax)
            for line in ax.get_lines():
                if line.get_visible() and len(line.get_xdata()) and _segments_enter(
                        line.get_transform().transform(line.get_xydata()), area):
                    found.append(f"a legend covers line {line.get_label()!r} in {where}")
            artists = [*ax.patches, *ax.images,
                       *(c for c in ax.collections if not isinstance(c, PathCollection))]
            for artist in artists:
                box = artist.get_window_extent(renderer)
                if artist.get_visible() and Bbox.intersection(box, area) is not None and (
                        min(box.x1, area.x1) - max(box.x0, area.x0) > SLACK
                        and min(box.y1, area.y1) - max(box.y0, area.y0) > SLACK):
                    found.append(f"a legend covers a {type(artist).__name__} in {where}")
            for scatter in (c for c in ax.collections if isinstance(c, PathCollection)):
                points = scatter.get_offset_transform().transform(scatter.get_offsets())
                if scatter.get_visible() and _segments_enter(
                        np.insert(points, range(1, len(points)), np.nan, axis=0), area):
                    found.append(f"a legend covers scatter points in {where}")
    return found


def sparse_log_axes(fig: Figure, least: int = LEAST_LOG_TICKS) -> list[str]:
    """Logarithmic (and symmetric log) axes that label fewer than `least` ticks in view (an
    axis whose labels are all off, the inner axis of shared panels, is not read)."""
    draw(fig)
    found = []
    for ax in drawn_axes(fig):
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() not in ("log", "symlog"):
                continue
            switched_on = any(t.label1.get_visible() or t.label2.get_visible()
                              for t in (*axis.get_major_ticks(), *axis.get_minor_ticks()))
            labelled = drawn_tick_labels(axis)
            if switched_on and len(labelled) < least:
                found.append(f"{_where(ax)}: log "
                             f"{axis.axis_name} axis labels {len(labelled)} ticks "
                             f"{[t.get_text() for t in labelled]}, fewer than {least}")
    return found


def cut_bars(fig: Figure) -> list[str]:
    """Bars that reach past their axes' view limits, or end at one (then no reader can tell
    a bar cut by the axis from one that ends there), unless that edge is the base every bar
    of the axes starts from."""
    draw(fig)
    found = []
    for ax in drawn_axes(fig):
        bars = [bar for c in ax.containers if isinstance(c, BarContainer) for bar in c.patches]
        corners = [ax.transData.transform([(bar.get_x(), bar.get_y()),
                                           (bar.get_x() + bar.get_width(),
                                            bar.get_y() + bar.get_height())]) for bar in bars]
        boxes = np.array([np.sort(c, axis=0).ravel() for c in corners]).reshape(-1, 4)
        limits = np.array([ax.bbox.x0, ax.bbox.y0, ax.bbox.x1, ax.bbox.y1])
        inward = np.array([1.0, 1.0, -1.0, -1.0])  # x0, y0 must not be below the limit...
        for bar, box in zip(bars, boxes, strict=True):
            if not np.isfinite(box).all():
                found.append(f"{_where(ax)}: a bar at ({bar.get_x():g}, {bar.get_y():g}) has "
                             "no place on its axes")
                continue
            inside = inward * (box - limits)   # > 0: inside the limit
            base = np.abs(boxes - box).max(axis=0) <= SLACK  # an edge every bar shares
            if (inside < -SLACK).any() or ((inside <= SLACK) & ~base).any():
                found.append(f"{_where(ax)}: the bar from {bar.get_x():g} to "
                             f"{bar.get_x() + bar.get_width():g} (y {bar.get_y():g}) reaches "
                             f"the limits x {ax.get_xlim()}, y {ax.get_ylim()}")
    return found


def empty_axes(fig: Figure) -> list[str]:
    """Visible axes that draw no data: no line with a finite point, no patch, collection or
    image (a panel saying 'no E_cw')."""
    draw(fig)
    found = []
    for ax in drawn_axes(fig):
        lines = [line for line in ax.get_lines() if line.get_visible()
                 and np.isfinite(np.asarray(line.get_xydata(), float)).all(axis=1).any()]
        if not (lines or ax.patches or ax.collections or ax.images):
            texts = [t.get_text() for t in ax.texts]
            found.append(f"{_where(ax)}: an empty panel{f' saying {texts}' if texts else ''}")
    return found


ONE_UNIT = re.compile(r"[^\[\]]*\[[^\[\]|;,]+\][^\[\]]*")


def _numeric(text: str) -> bool:
    """Whether a tick label is a number (mathtext '10^{-2}' too), not a category."""
    stripped = re.sub(r"\\mathdefault|\\times|[${}^\s.,+\-\u2212e%]", "", text)
    return bool(stripped) and stripped.isdigit()


def axes_without_one_unit(fig: Figure) -> list[str]:
    """Numbered axes whose label does not give exactly one unit, '[unit]' (no label, two
    brackets, 'mm | kg'); an axis of categories (variant names) or without labels is not
    read."""
    draw(fig)
    found = []
    for ax in drawn_axes(fig):
        for axis in (ax.xaxis, ax.yaxis):
            numbers = [t for t in drawn_tick_labels(axis) if _numeric(t.get_text())]
            label = axis.label.get_text() if axis.label.get_visible() else ""
            if numbers and not ONE_UNIT.fullmatch(label):
                found.append(f"{_where(ax)}: {axis.axis_name} label {label!r} is not "
                             "'quantity [one unit]'")
    return found


NUMBER = re.compile(r"[-\u2212]?(\d+)(?:\.(\d+))?(?: ?(\S+))?")


def _digits(text: str) -> tuple[range, int, str] | None:
    """A printed number's possible significant figures (an integer's trailing zeros may or
    may not count), its decimals and its unit; None for a text that is not one number."""
    match = NUMBER.fullmatch(text.strip())
    if match is None:
        return None
    whole, fraction, unit = match.group(1), match.group(2) or "", match.group(3) or ""
    digits = (whole + fraction).lstrip("0")
    if not digits:
        return range(0, 99), len(fraction), unit  # zero: any
    if fraction:
        return range(len(digits), len(digits) + 1), len(fraction), unit
    return range(len(digits.rstrip("0")), len(digits) + 1), 0, unit


def mixed_figures(fig: Figure) -> list[str]:
    """Values printed in one axes (its texts, its tick labels of one axis) with the same
    unit but neither the same significant figures nor the same decimals ('13 J' beside
    '8.92 J')."""
    renderer = draw(fig)
    found = []
    for ax in drawn_axes(fig):
        groups = [[t for t in ax.texts if t.get_visible()]]
        groups += [drawn_tick_labels(axis) for axis in (ax.xaxis, ax.yaxis)]
        for texts in groups:
            by_unit: dict[str, list[tuple[str, range, int]]] = {}
            for text in texts:
                if isinstance(text, Annotation) and not text._check_xy(renderer):  # noqa: SLF001
                    continue
                read = _digits(text.get_text())
                if read is not None:
                    by_unit.setdefault(read[2], []).append((text.get_text(), read[0], read[1]))
            for values in by_unit.values():
                figures = set.intersection(*(set(r) for _, r, _ in values))
                decimals = {d for _, _, d in values}
                if not figures and len(decimals) > 1:
                    found.append(f"{_where(ax)}: values "
                                 f"{[v for v, _, _ in values]} mix significant figures")
    return found


def _line_shows(line: Line2D, over: Line2D) -> bool:
    """Whether a line drawn under `over` still shows where they coincide: markers of another
    shape, size or place, a wider line, or gaps in `over`'s dashes."""
    if line.get_marker() not in NO_MARKER and (
            line.get_marker() != over.get_marker()
            or line.get_markersize() > over.get_markersize() + 0.5
            or line.get_markevery() != over.get_markevery()):
        return True
    if line.get_linewidth() > over.get_linewidth() + 1.0:
        return True
    return over.get_linestyle() not in ("-", "solid") and (
        line.get_linestyle() != over.get_linestyle()
        or line._unscaled_dash_pattern != over._unscaled_dash_pattern)  # noqa: SLF001


def hidden_lines(fig: Figure) -> list[str]:
    """Lines that a line drawn over them covers: within COINCIDE_PX at HIDDEN_SHARE of
    their points, and nothing of them showing (`_line_shows`)."""
    draw(fig)
    found = []
    for ax in drawn_axes(fig):
        lines = sorted((line for line in ax.get_lines()
                        if line.get_visible() and len(line.get_xdata()) > 1),
                       key=lambda line: line.get_zorder())  # stable: drawing order
        points = [line.get_transform().transform(line.get_xydata()) for line in lines]
        for i, line in enumerate(lines):
            for j in range(i + 1, len(lines)):
                if points[i].shape != points[j].shape:
                    continue
                distance = np.hypot(*(points[i] - points[j]).T)
                close = np.nan_to_num(distance, nan=np.inf) <= COINCIDE_PX
                if close.mean() >= HIDDEN_SHARE and not _line_shows(line, lines[j]):
                    found.append(f"{_where(ax)}: "
                                 f"{line.get_label()!r} (colour {to_hex(line.get_color())}) lies "
                                 f"hidden under {lines[j].get_label()!r}")
                    break
    return found


CHECKS: tuple[Callable[[Figure], list[str]], ...] = (
    texts_outside, overlapping_texts, legend_over_data, sparse_log_axes, cut_bars,
    empty_axes, axes_without_one_unit, mixed_figures, hidden_lines)


def defects(fig: Figure) -> list[str]:
    """What every check finds in the figure."""
    return [finding for check in CHECKS for finding in check(fig)]
