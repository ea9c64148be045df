"""What the Moreau–Jean integrator asks of a contact solver, and the solvers by name.

Scenes choose their contact solver by name (``[integrator] contact_solver``, see
:func:`build_contact_solvers`): ``"proxsuite"`` (default), ``"pinocchio-admm"``,
``"pinocchio-pgs"``, or ``"qpsolvers:<solver>"`` for the frictionless problem only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.pinocchio_constraint_solver import PinocchioContactSolver
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

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


def check_contact_solver(name: str) -> str:
    """``name`` if it names a contact solver (the qpsolvers backend is checked on build).

    Raises:
        NotFoundError: ``name`` is neither in :data:`CONTACT_SOLVERS` nor
            ``"qpsolvers:<solver>"``.
    """
    if name in CONTACT_SOLVERS or name.startswith(QPSOLVERS_PREFIX):
        return name
    raise NotFoundError("contact solver", name, [*CONTACT_SOLVERS, f"{QPSOLVERS_PREFIX}<solver>"])


def build_contact_solvers(
    name: str,
    *,
    friction: bool,
    eps_abs: float = 1e-10,
    max_iter: int = 5000,
    residual_tolerance: float = 1e-8,
    friction_max_iter: int = 100,
) -> tuple[LCPSolver, CoulombSolver | None]:
    """The frictionless solver and, if ``friction``, the friction solver named ``name``.

    Without friction no friction solver is built (nor its module imported).

    Args:
        name: ``"proxsuite"``, ``"pinocchio-admm"``, ``"pinocchio-pgs"`` or
            ``"qpsolvers:<solver>"`` (frictionless only).
        friction: Whether the constraints have friction.
        eps_abs: Absolute tolerance of the QP or of Pinocchio's solver, in [m/s].
        max_iter: Iteration cap of each QP, or of Pinocchio's solver.
        residual_tolerance: Natural-map residual accepted as solved for problems with
            friction, in [m/s] (the frictionless solvers keep their default, 1e-8 m/s).
        friction_max_iter: Cap on the fixed-point iterations of the proxsuite friction solver.

    Raises:
        NotFoundError: Unknown ``name`` or qpsolvers backend.
        InvalidParameterError: A qpsolvers backend asked for a problem with friction.
    """
    check_contact_solver(name)
    if name.startswith(QPSOLVERS_PREFIX):
        if friction:
            raise InvalidParameterError(
                "contact_solver",
                name,
                f"one of {list(CONTACT_SOLVERS)} for contacts with friction (the qpsolvers "
                "backends solve the frictionless problem)",
            )
        from ucontrol.solvers.qpsolvers_lcp import QpsolversLCPSolver  # imports qpsolvers

        return QpsolversLCPSolver(name.removeprefix(QPSOLVERS_PREFIX)), None
    if name == "proxsuite":
        lcp = ProxsuiteLCPSolver(eps_abs=eps_abs, max_iter=max_iter)
        if not friction:
            return lcp, None
        from ucontrol.solvers.proxsuite_coulomb import ProxsuiteCoulombSolver  # friction only

        coulomb = ProxsuiteCoulombSolver(
            residual_tolerance=residual_tolerance,
            max_iter=friction_max_iter,
            eps_abs=eps_abs,
            qp_max_iter=max_iter,
        )
        return lcp, coulomb
    solver = PinocchioContactSolver(
        name.removeprefix("pinocchio-"),
        tolerance=eps_abs,
        max_iter=max_iter,
        residual_tolerance=residual_tolerance,
    )
    return solver, solver if friction else None
