"""Phase bands of time plots: the background of each phase of the controller in its colour."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ucontrol.control.phase import Phase
from ucontrol.viz.phase_colours import PHASE_COLOURS


def phase_bands(ax: Axes, t: np.ndarray, phase: np.ndarray) -> None:
    """Shade ``ax`` behind its curves with the colour of the phase at each time.

    Args:
        ax: The axes, with time in [s] on x.
        t: Sample times in [s], shape (N,).
        phase: :class:`~ucontrol.control.Phase` of each sample (log field ``phase``), shape (N,).
    """
    edges = np.flatnonzero(np.diff(phase)) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [len(t) - 1]])
    for begin, end in zip(starts, stops, strict=True):
        colour = PHASE_COLOURS[Phase(int(phase[begin]))]
        ax.axvspan(t[begin], t[end], color=colour, lw=0, zorder=0)


def phase_legend(figure: Figure) -> None:
    """Add the legend of the phase colours above the axes of ``figure``."""
    handles = [
        Patch(facecolor=PHASE_COLOURS[phase], edgecolor="0.6", label=phase.name.lower())
        for phase in Phase
    ]
    figure.legend(handles=handles, loc="outside upper center", ncol=len(handles), fontsize=8)
