"""One-step nonsmooth problems: contact LCPs and their solvers."""

from ucontrol.solvers.contact_solution import ContactSolution, complementarity_residual
from ucontrol.solvers.lemke import LemkeResult, solve_lcp_lemke
from ucontrol.solvers.pinocchio_constraint_solver import (
    PinocchioContactSolver,
    PinocchioStepOutcome,
    PinocchioStepper,
    pinocchio_step,
)
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

__all__ = [
    "ContactSolution",
    "LemkeResult",
    "PinocchioContactSolver",
    "PinocchioStepOutcome",
    "PinocchioStepper",
    "ProxsuiteLCPSolver",
    "complementarity_residual",
    "pinocchio_step",
    "solve_lcp_lemke",
]
