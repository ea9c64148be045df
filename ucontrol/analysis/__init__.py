"""Analysis of runs: summaries and analytic references.

:class:`BouncingBall` (an analytic reference for the convergence studies) is imported on first
use: a run loads only its summary's modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names
from ucontrol.analysis.energy_balance import actuator_work
from ucontrol.analysis.impacts import IMPACT_VELOCITY_THRESHOLD, impact_mask
from ucontrol.analysis.summary import summarize

if TYPE_CHECKING:
    from ucontrol.analysis.bouncing_ball import BouncingBall

__all__ = [
    "IMPACT_VELOCITY_THRESHOLD",
    "BouncingBall",
    "actuator_work",
    "impact_mask",
    "summarize",
]


__getattr__ = lazy_names(__name__, {"BouncingBall": "ucontrol.analysis.bouncing_ball"})
