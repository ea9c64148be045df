"""Analysis of runs: summaries and analytic references."""

from ucontrol.analysis.bouncing_ball import BouncingBall
from ucontrol.analysis.energy_balance import actuator_work
from ucontrol.analysis.impacts import IMPACT_VELOCITY_THRESHOLD, impact_mask
from ucontrol.analysis.summary import summarize

__all__ = [
    "IMPACT_VELOCITY_THRESHOLD",
    "BouncingBall",
    "actuator_work",
    "impact_mask",
    "summarize",
]
