"""What every run figure shares: legends beside the axes, notes of the samples a scale clips."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.axes import Axes


def legend_outside(ax: Axes, **kwargs: Any) -> None:
    """Draw the legend of ``ax`` to the right of its axes, where it hides no curve.

    Args:
        ax: The axes; its figure should use the constrained layout, which makes room.
        **kwargs: Passed to :meth:`matplotlib.axes.Axes.legend` (font size 7 by default).
    """
    kwargs.setdefault("fontsize", 7)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kwargs)


def clip_note(values: np.ndarray, low: float, high: float, unit: str) -> str | None:
    """The note of the samples an axis of range [low, high] leaves out, or None.

    Args:
        values: The plotted values, any shape.
        low: Bottom of the axis, in the unit of the values.
        high: Top of the axis, in the unit of the values.
        unit: Unit of the values, e.g. ``"N"``.

    Returns:
        E.g. ``"3 samples above the axis clipped: 6.1e+03 to 8.5e+03 N"``; None when every
        sample is within the axis.
    """
    values = np.asarray(values, dtype=float).ravel()
    notes = []
    for side, out in (("above", values[values > high]), ("below", values[values < low])):
        if out.size:
            low_text, high_text = f"{out.min():.3g}", f"{out.max():.3g}"
            span = low_text if low_text == high_text else f"{low_text} to {high_text}"
            plural = "s" if out.size > 1 else ""
            notes.append(f"{out.size} sample{plural} {side} the axis clipped: {span} {unit}")
    return "; ".join(notes) or None


def annotate_clip(ax: Axes, note: str | None) -> None:
    """Write ``note`` (from :func:`clip_note`) in red in the top left corner of ``ax``."""
    if note is not None:
        ax.text(
            0.005,
            0.97,
            note,
            transform=ax.transAxes,
            va="top",
            fontsize=7,
            color="C3",
            bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1.0},
        )
