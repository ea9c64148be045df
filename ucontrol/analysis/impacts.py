"""Which steps of a run hold an impact."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import ShapeError
from ucontrol.integrators.step_stages import IMPACT_VELOCITY_THRESHOLD, is_impact
from ucontrol.log import Log

__all__ = ["IMPACT_VELOCITY_THRESHOLD", "impact_cells", "impact_mask", "impacts_of"]


def impact_mask(log: Log) -> np.ndarray:
    """Boolean array (N, n): constraint i had an impact in the step starting at row k.

    The rule of Moreau–Jean's :attr:`~ucontrol.plant.StepOutcome.impacts`
    (:func:`~ucontrol.integrators.step_stages.is_impact`) on the log: an impulse in the step
    and a closing speed at its start above :data:`IMPACT_VELOCITY_THRESHOLD`, or above
    :data:`~ucontrol.integrators.step_stages.HELD_IMPACT_VELOCITY` when the step before had an
    impulse (the constraint was held).
    """
    impulse = log.impulse
    held = np.zeros_like(impulse)
    held[1:] = impulse[:-1]
    return np.asarray(is_impact(impulse, held, log.normal_velocity), dtype=bool)


def impact_cells(impacts: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Rows (steps) and columns (constraints) of the impacts of an :func:`impact_mask`.

    The result of ``np.nonzero(impacts)``, found from the flat indices of the few impacts in one
    pass over the mask: numpy's reductions along its short second axis (``any(axis=1)``,
    ``sum(axis=0)``) and its two-dimensional ``nonzero`` visit the rows one by one.

    Args:
        impacts: Impact mask, shape (N, n).

    Returns:
        The row and the column of each impact, each of shape (K,), in row-major order (rows
        ascending; a row with several impacts appears once per impact).
    """
    rows, columns = np.divmod(np.flatnonzero(impacts), max(impacts.shape[1], 1))
    return rows, columns


def impacts_of(log: Log, impacts: NDArray[np.bool_] | None) -> NDArray[np.bool_]:
    """The impact mask of ``log``: ``impacts`` when a caller computed it already, else computed.

    Args:
        log: The run's log.
        impacts: ``impact_mask(log)``, shape (N, n), or None.

    Raises:
        ShapeError: ``impacts`` does not have the shape of ``log``'s mask.
    """
    if impacts is None:
        return impact_mask(log)
    expected = (len(log), len(log.constraint_names))
    if np.shape(impacts) != expected:
        raise ShapeError("impacts", expected, np.shape(impacts))
    return np.asarray(impacts, dtype=bool)
