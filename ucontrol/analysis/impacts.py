"""Which steps of a run hold an impact."""

from __future__ import annotations

import numpy as np

from ucontrol.log import Log

#: A constraint closing faster than this at the start of a step with a positive impulse is an
#: impact, in [m/s] (or [rad/s] for stops); slower ones are persistent contact.
IMPACT_VELOCITY_THRESHOLD = 1e-6


def impact_mask(log: Log) -> np.ndarray:
    """Boolean array (N, n): constraint i had an impact in the step starting at row k."""
    return (log.impulse > 0.0) & (log.normal_velocity < -IMPACT_VELOCITY_THRESHOLD)
