"""One-step nonsmooth problems: contact LCPs and their solvers."""

from ucontrol.solvers.contact_solution import ContactSolution, complementarity_residual
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

__all__ = ["ContactSolution", "ProxsuiteLCPSolver", "complementarity_residual"]
