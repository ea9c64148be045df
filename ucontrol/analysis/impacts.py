"""Which steps of a run hold an impact."""

from __future__ import annotations

import numpy as np

from ucontrol.integrators.step_stages import IMPACT_VELOCITY_THRESHOLD, is_impact
from ucontrol.log import Log

__all__ = ["IMPACT_VELOCITY_THRESHOLD", "impact_mask"]


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
