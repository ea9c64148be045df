"""How time advances."""

from ucontrol.integrators.moreau_jean import MoreauJean, PlantEvaluation, StepOutcome

__all__ = ["MoreauJean", "PlantEvaluation", "StepOutcome"]
