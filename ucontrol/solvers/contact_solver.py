"""What the Moreau–Jean integrator asks of a contact solver, and the solvers' names.

Scenes choose their contact solver by name (``[integrator] contact_solver``, built by
:func:`ucontrol.solvers.contact_solver_choice.build_contact_solvers`): ``"proxsuite"``
(default), ``"pinocchio-admm"``, ``"pinocchio-pgs"``, or ``"qpsolvers:<solver>"`` for the
frictionless problem only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from ucontrol.solvers.contact_solution import ContactSolution

if TYPE_CHECKING:
    from ucontrol.solvers.coulomb_problem import CoulombProblem

#: Contact solvers selectable by name, besides ``"qpsolvers:<solver>"``.
CONTACT_SOLVERS = ("proxsuite", "pinocchio-admm", "pinocchio-pgs")
#: Prefix of the frictionless qpsolvers backends, ``"qpsolvers:<solver>"``.
QPSOLVERS_PREFIX = "qpsolvers:"


class LCPSolver(Protocol):
    r"""Solves frictionless contact problems :math:`0 \le P \perp D P + b \ge 0`.

    Implemented by :class:`~ucontrol.solvers.ProxsuiteLCPSolver` (default),
    :class:`~ucontrol.solvers.QpsolversLCPSolver` and
    :class:`~ucontrol.solvers.PinocchioContactSolver`.

    Attributes:
        name: Label used in errors and logs.
        residual_tolerance: Residual in [m/s] up to which a solve reports ``"solved"``.
    """

    name: str
    residual_tolerance: float

    def solve(self, D: NDArray[np.float64], b: NDArray[np.float64]) -> ContactSolution:
        """Impulses (m,) for the Delassus matrix D (m, m) [m/s per N s] and b (m,) [m/s]."""
        ...

    def reset(self) -> None:
        """Forget what earlier solves left (warm starts): solve as a new solver would."""
        ...


class CoulombSolver(Protocol):
    """Solves contact problems with Coulomb friction (:class:`CoulombProblem`).

    Implemented by :class:`~ucontrol.solvers.ProxsuiteCoulombSolver` (default) and
    :class:`~ucontrol.solvers.PinocchioContactSolver`.

    Attributes:
        name: Label used in errors and logs.
        residual_tolerance: Natural-map residual in [m/s] up to which a solve reports
            ``"solved"``.
    """

    name: str
    residual_tolerance: float

    def solve_coulomb(self, problem: CoulombProblem) -> ContactSolution:
        """Stacked impulses (r,) of ``problem``: normal then tangential."""
        ...

    def reset(self) -> None:
        """Forget what earlier solves left (warm starts): solve as a new solver would."""
        ...
