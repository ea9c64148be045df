"""One-step nonsmooth problems: contact LCPs, Coulomb friction, and their solvers.

:class:`ProxsuiteCoulombSolver`, :class:`QpsolversLCPSolver`, the Lemke reference and the
Pinocchio adapters are imported on first access only: a scene without friction never loads the
friction machinery, one without a qpsolvers backend never imports qpsolvers, and a run that
solves its contacts with proxsuite loads neither Lemke's pivoting nor Pinocchio's solvers.
"""

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names
from ucontrol.solvers.contact_solution import ContactSolution, complementarity_residual
from ucontrol.solvers.contact_solver import CoulombSolver, LCPSolver
from ucontrol.solvers.coulomb_problem import CoulombProblem
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

if TYPE_CHECKING:
    from ucontrol.solvers.lemke import LemkeResult, solve_lcp_lemke
    from ucontrol.solvers.pinocchio_constraint_solver import (
        PinocchioContactSolver,
        PinocchioStepOutcome,
        PinocchioStepper,
        pinocchio_step,
    )
    from ucontrol.solvers.proxsuite_coulomb import ProxsuiteCoulombSolver
    from ucontrol.solvers.qpsolvers_lcp import QpsolversLCPSolver

#: Public classes loaded on first access, and their modules.
_LAZY = {
    "LemkeResult": "ucontrol.solvers.lemke",
    "PinocchioContactSolver": "ucontrol.solvers.pinocchio_constraint_solver",
    "PinocchioStepOutcome": "ucontrol.solvers.pinocchio_constraint_solver",
    "PinocchioStepper": "ucontrol.solvers.pinocchio_constraint_solver",
    "ProxsuiteCoulombSolver": "ucontrol.solvers.proxsuite_coulomb",
    "QpsolversLCPSolver": "ucontrol.solvers.qpsolvers_lcp",
    "pinocchio_step": "ucontrol.solvers.pinocchio_constraint_solver",
    "solve_lcp_lemke": "ucontrol.solvers.lemke",
}

__all__ = [
    "ContactSolution",
    "CoulombProblem",
    "CoulombSolver",
    "LCPSolver",
    "LemkeResult",
    "PinocchioContactSolver",
    "PinocchioStepOutcome",
    "PinocchioStepper",
    "ProxsuiteCoulombSolver",
    "ProxsuiteLCPSolver",
    "QpsolversLCPSolver",
    "complementarity_residual",
    "pinocchio_step",
    "solve_lcp_lemke",
]


__getattr__ = lazy_names(__name__, _LAZY)
