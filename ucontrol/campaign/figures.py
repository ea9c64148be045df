"""Figures and worst cases of a campaign directory (``ucontrol plot DIR``).

- ``success_<key>.png``: success rate against each swept parameter (bins of the values, the
  95 % Wilson interval as error bars, the number of runs written over each bar);
- ``success_map.png``: success rate against the first two swept parameters, a heat map with
  ``successes/runs`` written in each cell, cells without runs hatched grey;
- ``metrics.png``: a histogram of each numeric metric, successes and failures stacked;
- ``worst.md`` and ``worst.csv``: the worst runs with their parameters and the ``ucontrol run``
  command that re-runs each one alone.
"""

from __future__ import annotations

import itertools
import math
import shlex
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol.campaign.overrides import format_assignment
from ucontrol.campaign.table import load, read_campaign, wilson_interval

#: Bins of a continuous parameter in the success figures.
BINS = 6
#: Worst runs listed by default.
N_WORST = 5
#: Look of a cell of the success map without runs: hatched grey, outside the colour scale.
EMPTY_CELL: dict[str, Any] = {"facecolor": "0.85", "edgecolor": "0.45", "hatch": "///", "lw": 0.0}


def plot_campaign(directory: str | Path, out: str | Path | None = None) -> list[Path]:
    """Draw the figures of a campaign directory and write its worst cases.

    Args:
        directory: The campaign directory (``--out`` of ``ucontrol sweep``).
        out: Folder of the figures; default ``DIR/figures``.

    Returns:
        The files written.
    """
    import matplotlib

    matplotlib.use("Agg")
    directory = Path(directory)
    info = read_campaign(directory)
    frame = load(directory)
    out = directory / "figures" if out is None else Path(out)
    out.mkdir(parents=True, exist_ok=True)
    swept = [key for key in info["parameters"] if _numeric(frame[key]).nunique() > 1]
    paths = [_success_1d(frame, key, info, out) for key in swept]
    if len(swept) >= 2:
        paths.append(_success_map(frame, swept[0], swept[1], info, out))
    metrics = [m for m in info["metrics"] if _numeric(frame[m]).notna().any()]
    if metrics:
        paths.append(_histograms(frame, metrics, out))
    worst = worst_cases(directory, N_WORST)
    paths.extend(write_worst(worst, out))
    return paths


def worst_cases(directory: str | Path, n: int = N_WORST) -> Any:
    """The ``n`` worst runs: failed runs first, then by the campaign's ``worst`` metric.

    Without ``worst`` in the campaign file, runs are ranked by their first metric, largest
    first. A column ``rerun`` holds the ``ucontrol run`` command of each run.
    """
    info = read_campaign(directory)
    frame = load(directory)
    if frame.empty:
        return frame.assign(rerun=[])
    metrics = list(info["metrics"])
    worst = info.get("worst") or (metrics[0] if metrics else None)
    keys: list[Any] = [frame["status"] != "ok", ~frame["success"].astype(bool)]
    ascending = [False, False]
    if worst is not None:
        name = worst.removeprefix("-")
        values = _numeric(frame[name])
        keys.append(values.fillna(-np.inf if worst.startswith("-") else np.inf))
        ascending.append(worst.startswith("-"))
    order = np.lexsort(
        [
            np.asarray(k, dtype=float) * (1 if a else -1)
            for k, a in zip(reversed(keys), reversed(ascending), strict=True)
        ]
    )
    chosen = frame.iloc[order[:n]].copy()
    chosen["rerun"] = [_rerun(info, row) for _, row in chosen.iterrows()]
    chosen = chosen.reset_index(drop=True)
    chosen.attrs["worst"] = None if worst is None else worst.removeprefix("-")
    return chosen


def write_worst(worst: Any, out: Path) -> list[Path]:
    """Write the worst cases to ``worst.csv`` and ``worst.md``; return both paths."""
    csv_path, md_path = out / "worst.csv", out / "worst.md"
    worst.to_csv(csv_path, index=False)
    md_path.write_text(worst_markdown(worst) + "\n")
    return [csv_path, md_path]


def worst_markdown(worst: Any) -> str:
    """The worst cases as a markdown list, each with its re-run command."""
    lines = []
    for _, row in worst.iterrows():
        if row["status"] != "ok":
            state = f"failed ({row['status']})"
        else:
            state = "passed" if row["success"] else "completed, success criterion not met"
        error = f": {row['error']}" if row["error"] else ""
        metric = worst.attrs.get("worst")
        value = f", {metric} = {row[metric]:.4g}" if metric and _finite(row[metric]) else ""
        lines.append(f"- `{row['run_id']}` {state}{value}{error}")
        lines.append(f"  `{row['rerun']}`")
    return "\n".join(lines) if lines else "(no finished runs)"


def _short_path(path: str) -> str:
    """``path`` relative to the working directory when it lies inside it."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return path


def _finite(value: Any) -> bool:
    return math.isfinite(_as_number(value))


def _rerun(info: dict[str, Any], row: Any) -> str:
    reference = info.get("scene", {})
    if "builtin" in reference:  # by name: the command works in any installation
        scene = Path(reference["builtin"]).stem
    else:
        scene = _short_path(info.get("scene_path", "SCENE"))
    words = ["ucontrol", "run", scene]
    if info.get("duration") is not None:
        words += ["--duration", repr(info["duration"])]
    if info.get("dt") is not None:
        words += ["--dt", repr(info["dt"])]
    for key in info["parameters"]:
        value = row[key]
        if isinstance(value, np.generic):
            value = value.item()
        words += ["--set", format_assignment(key, value)]
    return shlex.join(words)


def _numeric(series: Any) -> Any:
    import pandas as pd

    return pd.to_numeric(series.map(_as_number), errors="coerce")


def _as_number(value: Any) -> float:
    if isinstance(value, bool | np.bool_):
        return float(value)
    if isinstance(value, int | float | np.integer | np.floating):
        return float(value)
    return math.nan


def _bins(values: Any) -> tuple[Any, list[str]]:
    """Bin labels of a parameter: its distinct values when few, else equal-width bins."""
    import pandas as pd

    distinct = np.unique(values.dropna())
    if distinct.size <= BINS:
        codes = pd.Categorical(values, categories=distinct)
        return codes.codes, [f"{v:.3g}" for v in distinct]
    edges = np.linspace(distinct.min(), distinct.max(), BINS + 1)
    codes = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, BINS - 1)
    return codes, [f"[{a:.3g}, {b:.3g}]" for a, b in itertools.pairwise(edges)]


def _success_1d(frame: Any, key: str, info: dict[str, Any], out: Path) -> Path:
    import matplotlib.pyplot as plt

    codes, labels = _bins(_numeric(frame[key]))
    success = frame["success"].to_numpy(dtype=bool)
    rates, lows, highs, counts = [], [], [], []
    for i in range(len(labels)):
        mask = np.asarray(codes) == i
        n, k = int(mask.sum()), int(success[mask].sum())
        low, high = wilson_interval(k, n)
        rate = k / n if n else math.nan
        rates.append(rate)
        lows.append(max(rate - low, 0.0) if n else 0.0)  # rounding may cross the rate
        highs.append(max(high - rate, 0.0) if n else 0.0)
        counts.append((k, n))
    fig, ax = plt.subplots(figsize=(7, 4))
    x = np.arange(len(labels))
    ax.bar(x, rates, yerr=[lows, highs], capsize=4, color="tab:green", alpha=0.7)
    for i, (k, n) in enumerate(counts):
        ax.text(i, 1.02, f"{k}/{n}", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
    ax.set_ylim(0, 1.12)
    ax.set_xlabel(key)
    ax.set_ylabel("success rate (95 % Wilson)")
    ax.set_title(f"{info['name']}: success against {key}")
    fig.tight_layout()
    path = out / f"success_{key.replace('.', '_')}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _success_map(frame: Any, x_key: str, y_key: str, info: dict[str, Any], out: Path) -> Path:
    figure = success_map_figure(frame, x_key, y_key, info["name"])
    path = out / "success_map.png"
    figure.savefig(path, dpi=110)
    return path


def success_map_figure(frame: Any, x_key: str, y_key: str, name: str) -> Any:
    """The success rate of each cell of two binned parameters, a heat map.

    Each cell says ``successes/runs``; a cell without runs is hatched grey (with its legend
    entry), never painted with a colour of the rate's scale.

    Args:
        frame: The campaign table (:func:`ucontrol.campaign.table.load`).
        x_key: Parameter along x.
        y_key: Parameter along y.
        name: Name of the campaign, in the title.

    Returns:
        The matplotlib figure, unsaved.
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch, Rectangle

    x_codes, x_labels = _bins(_numeric(frame[x_key]))
    y_codes, y_labels = _bins(_numeric(frame[y_key]))
    success = frame["success"].to_numpy(dtype=bool)
    rate = np.full((len(y_labels), len(x_labels)), np.nan)
    figure = Figure(figsize=(7.5, 5.8), layout="constrained")
    ax = figure.add_subplot()
    for i in range(len(y_labels)):
        for j in range(len(x_labels)):
            mask = (np.asarray(y_codes) == i) & (np.asarray(x_codes) == j)
            n, k = int(mask.sum()), int(success[mask].sum())
            if n:
                rate[i, j] = k / n
            else:
                ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, **EMPTY_CELL))
            ax.text(j, i, f"{k}/{n}", ha="center", va="center", fontsize=8)
    image = ax.imshow(rate, origin="lower", cmap="RdYlGn", vmin=0, vmax=1, aspect="auto")
    figure.colorbar(image, ax=ax, label="success rate")
    if np.isnan(rate).any():
        figure.legend(
            handles=[Patch(**EMPTY_CELL, label="no runs in the cell")],
            loc="outside lower right",
            fontsize=8,
        )
    ax.set_xticks(range(len(x_labels)), x_labels, rotation=30, ha="right", fontsize=8)
    ax.set_yticks(range(len(y_labels)), y_labels, fontsize=8)
    ax.set_xlabel(x_key)
    ax.set_ylabel(y_key)
    ax.set_title(f"{name}: successes/runs per cell")
    return figure


def _histograms(frame: Any, metrics: list[str], out: Path) -> Path:
    import matplotlib.pyplot as plt

    columns = min(3, len(metrics))
    rows = math.ceil(len(metrics) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.2 * rows), squeeze=False)
    success = frame["success"].to_numpy(dtype=bool)
    for ax, name in zip(axes.flat, metrics, strict=False):
        values = _numeric(frame[name]).to_numpy()
        finite = np.isfinite(values)
        data = [values[finite & success], values[finite & ~success]]
        ax.hist(data, bins=15, stacked=True, color=["tab:green", "tab:red"], label=["pass", "fail"])
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=8)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
    for ax in list(axes.flat)[len(metrics) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=8)
    fig.tight_layout()
    path = out / "metrics.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
