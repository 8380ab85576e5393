"""A study's statistics from its runs (docs/study.md): per loss set and variant, over the
tasks in which every variant ran.

- summary: E_drawn and eps, median and the 5 % and 95 % quantiles; E_drawn over that of the
  reference variant (median); the fraction of tasks in which the variant draws the least;
  the fraction in which its drives stay within their nominal current;
- paired: for each pair (variant, other), the mean over tasks of E_drawn(variant) -
  E_drawn(other) with a 95 % percentile-bootstrap confidence interval: RESAMPLES resamples of
  the tasks (the same resamples for every pair of a loss set) from numpy's default_rng(SEED);
  `firm` when the interval excludes 0;
- dependence: the tasks in BINS bins of equal count of a task figure (payload changes per
  minute, hold fraction), and per bin and variant the median E_drawn ratio to the reference
  and the fraction of tasks in which it draws the least.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

RESAMPLES = 10_000
SEED = 20261206
LEVEL = 0.95
QUANTILES = {0.05: "q05", 0.5: "median", 0.95: "q95"}   # quantile: its column's suffix
BINS = 4
TASK_AXES = {"changes_per_min": "payload changes per minute [1/min]",
             "hold_fraction": "fraction of the task spent holding [-]"}


def energies(runs: pd.DataFrame, variants: list[str]) -> dict[str, pd.DataFrame]:
    """Per loss set, E_drawn [J] by task (rows) and variant (columns), of the tasks in which
    every variant ran; a loss set without such a task has none (nothing to compare)."""
    ok = runs[runs.status == "ok"]
    tables = {}
    for loss_set, group in ok.groupby("losses", sort=False):
        wide = group.pivot(index="task", columns="variant", values="E_drawn")
        wide = wide.reindex(columns=variants).dropna()
        if len(wide):
            tables[loss_set] = wide
    return tables


def least_fractions(wide: pd.DataFrame) -> pd.Series:
    """The fraction of tasks in which each variant draws the least."""
    winners = wide.idxmin(axis=1)
    return pd.Series({v: float((winners == v).mean()) for v in wide.columns})


def summary(runs: pd.DataFrame, variants: list[str], reference: str) -> pd.DataFrame:
    """One row per (loss set, variant): see the module docstring."""
    rows = []
    for loss_set, wide in energies(runs, variants).items():
        tasks = wide.index
        ok = runs[(runs.losses == loss_set) & runs.task.isin(tasks)]
        least = least_fractions(wide)
        for variant in variants:
            mine = ok[ok.variant == variant]
            drawn, eps = wide[variant].to_numpy(), mine.eps.to_numpy(dtype=float)
            row = {"losses": loss_set, "variant": variant, "tasks": len(tasks)}
            for name, values in (("E_drawn", drawn), ("eps", eps)):
                for suffix, value in zip(QUANTILES.values(),
                                         np.quantile(values, list(QUANTILES))):
                    row[f"{name}_{suffix}"] = value
            row["ratio_median"] = float(np.median(drawn / wide[reference].to_numpy()))
            row["least_fraction"] = least[variant]
            row["drive_ok_fraction"] = float(mine.drive_ok.astype(bool).mean())
            rows.append(row)
    return pd.DataFrame(rows)


def bootstrap_means(differences: np.ndarray, resamples: np.ndarray) -> np.ndarray:
    """The mean of each resample (rows of task indices) of the differences."""
    return differences[resamples].mean(axis=1)


def paired(runs: pd.DataFrame, variants: list[str]) -> pd.DataFrame:
    """One row per (loss set, variant, other variant): see the module docstring."""
    rows = []
    tail = (1.0 - LEVEL) / 2.0
    for loss_set, wide in energies(runs, variants).items():
        n = len(wide)
        resamples = np.random.default_rng(SEED).integers(0, n, size=(RESAMPLES, n))
        for variant in variants:
            for other in variants:
                if other == variant:
                    continue
                d = (wide[variant] - wide[other]).to_numpy()
                low, high = np.quantile(bootstrap_means(d, resamples), (tail, 1.0 - tail))
                rows.append({"losses": loss_set, "variant": variant, "other": other,
                             "tasks": n, "mean_difference": float(d.mean()),
                             "ci_low": float(low), "ci_high": float(high),
                             "resamples": RESAMPLES, "firm": bool(low > 0.0 or high < 0.0)})
    return pd.DataFrame(rows)


def dependence(runs: pd.DataFrame, tasks: pd.DataFrame, variants: list[str],
               reference: str) -> pd.DataFrame:
    """One row per (loss set, task figure, bin, variant): see the module docstring. A task
    figure that takes fewer than two values (no payload) has no rows."""
    rows = []
    for loss_set, wide in energies(runs, variants).items():
        figures = tasks.set_index("task").loc[wide.index]
        ratios = wide.div(wide[reference], axis=0)
        for axis in TASK_AXES:
            values = figures[axis]
            if values.nunique() < 2:
                continue
            bins = pd.qcut(values, BINS, duplicates="drop")
            for interval, members in wide.groupby(bins.to_numpy(), observed=True):
                least = least_fractions(members)
                for variant in variants:
                    rows.append({"losses": loss_set, "axis": axis, "low": interval.left,
                                 "high": interval.right, "tasks": len(members),
                                 "variant": variant,
                                 "ratio_median": float(ratios.loc[members.index,
                                                                  variant].median()),
                                 "least_fraction": least[variant]})
    return pd.DataFrame(rows)
