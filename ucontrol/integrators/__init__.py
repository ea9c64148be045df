"""How time advances."""

from ucontrol.integrators.compliant import Compliant
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.integrators.moreau_jean import MoreauJean, PlantEvaluation, StepOutcome

__all__ = ["Compliant", "EventDriven", "MoreauJean", "PlantEvaluation", "StepOutcome"]
