"""The contact solvers by name: checking a scene's choice and building it.

The friction solver, the qpsolvers backends and Pinocchio's solvers are imported only when a
scene asks for them.
"""

from __future__ import annotations

from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.solvers.contact_solver import (
    CONTACT_SOLVERS,
    QPSOLVERS_PREFIX,
    CoulombSolver,
    LCPSolver,
)
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver


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
    from ucontrol.solvers.pinocchio_constraint_solver import PinocchioContactSolver

    solver = PinocchioContactSolver(
        name.removeprefix("pinocchio-"),
        tolerance=eps_abs,
        max_iter=max_iter,
        residual_tolerance=residual_tolerance,
    )
    return solver, solver if friction else None
