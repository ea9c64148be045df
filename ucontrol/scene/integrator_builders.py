"""Building a scene's integrator from its settings: one builder per integrator name.

``event_driven`` and ``compliant`` are imported by their builder only, so a Moreau–Jean
scene never loads ``scipy.integrate``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.integrators.moreau_jean import MoreauJean
from ucontrol.solvers.contact_solver_choice import build_contact_solvers
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

if TYPE_CHECKING:
    from ucontrol.plant import Integrator
    from ucontrol.scene.scene_data import SceneData
    from ucontrol.solvers.contact_solver import CoulombSolver, LCPSolver


def build_integrator(
    scene: SceneData, dt: float | None = None, *, compiled: bool = True
) -> Integrator:
    """The integrator ``scene.integrator`` names, with its step or ``dt`` in [s].

    ``compiled = False`` runs Moreau–Jean's reference stages alone (no generated fast path).

    Raises:
        InvalidParameterError: The scene has friction and the integrator is compliant (it is
            frictionless) or event_driven against moving surfaces, a ``qpsolvers:`` contact
            solver was asked for a scene with friction, the compliant integrator for a
            scene with moving surfaces, bilateral constraints or clearance joints, or Coulomb
            joint friction with an integrator other than ``moreau_jean``, or a contact's
            ``closes_ahead_of`` rule with compliant.
    """
    name = scene.integrator.name
    laws = _impact_laws(scene)
    if any(law != "newton" for law in laws) and name != "event_driven":
        raise InvalidParameterError(
            "[integrator] impact_law",
            scene.integrator.impact_law,
            f"'newton' with {name} (the LZB, Poisson and energetic laws are impact laws of "
            "event_driven; Moreau–Jean and compliant apply Newton's law)",
        )
    if scene.constraints.has_friction and name != "moreau_jean" and not _frictional_impacts(scene):
        raise InvalidParameterError(
            "[integrator] name",
            name,
            "'moreau_jean' or 'event_driven' for contacts with friction (compliant is "
            "frictionless; event_driven takes friction against fixed surfaces only)",
        )
    if scene.clearances and name == "compliant":
        raise InvalidParameterError(
            "[integrator] name",
            name,
            "'moreau_jean' or 'event_driven' for scenes with [[clearance]] joints (compliant "
            "does not hold the bilateral constraints of a mechanism; docs/clearance.md)",
        )
    if scene.constraints.bilateral is not None and name == "compliant":
        raise InvalidParameterError(
            "[integrator] name",
            name,
            f"'moreau_jean' or 'event_driven' for scenes with [[bilateral]] constraints ({name} "
            "does not hold bilateral constraints)",
        )
    if scene.constraints.time_dependent and name == "compliant":
        raise InvalidParameterError(
            "[integrator] name",
            name,
            "'moreau_jean' or 'event_driven' for contacts against moving surfaces (a surface "
            f"`motion`; {name} does not handle time-dependent constraints)",
        )
    barred = [c.name for c in scene.contacts if c.closes_ahead_of]
    if barred and name == "compliant":
        raise InvalidParameterError(
            "[integrator] name",
            name,
            f"'moreau_jean' or 'event_driven' for contacts with a `closes_ahead_of` rule "
            f"({barred}; compliant does not apply it, docs/legged.md)",
        )
    if _joint_coulomb(scene) and name != "moreau_jean":
        raise InvalidParameterError(
            "[integrator] name",
            name,
            f"'moreau_jean' for scenes with Coulomb [joint_friction] ({name} has viscous joint "
            "friction only)",
        )
    h = scene.integrator.dt if dt is None else dt
    return _moreau_jean(scene, h, compiled) if name == "moreau_jean" else _BUILDERS[name](scene, h)


def contact_solvers(scene: SceneData) -> tuple[LCPSolver, CoulombSolver | None]:
    """New contact solvers of a Moreau–Jean integrator with ``scene``'s settings.

    The frictionless solver and, where the scene has friction (contacts or Coulomb joints),
    the friction solver; without their warm starts (a campaign gives a reused integrator
    fresh ones for each run).
    """
    settings = scene.integrator
    return build_contact_solvers(
        settings.contact_solver,
        friction=scene.constraints.has_friction or _joint_coulomb(scene),
        eps_abs=settings.contact_tolerance,
        max_iter=settings.max_iter,
        residual_tolerance=settings.friction_tolerance,
        friction_max_iter=settings.friction_max_iter,
    )


def _moreau_jean(scene: SceneData, dt: float, compiled: bool = True) -> Integrator:
    settings = scene.integrator
    contact_solver, friction_solver = contact_solvers(scene)
    return MoreauJean(
        scene.robot,
        scene.constraints,
        dt=dt,
        theta=settings.theta,
        solver=contact_solver,
        friction_solver=friction_solver,
        restitution_threshold=settings.restitution_threshold,
        on_unsolved=settings.on_unsolved,
        flexible=scene.flexible,
        midpoint=settings.midpoint,
        persistence_tolerance=settings.persistence_tolerance,
        persistence_speed=settings.persistence_speed,
        newton_law=settings.newton_law,
        joint_friction=scene.joint_friction,
        compiled=compiled,
    )


def _joint_coulomb(scene: SceneData) -> bool:
    """Whether some joint of the scene has Coulomb friction (it needs the friction solver)."""
    return scene.joint_friction is not None and scene.joint_friction.coulomb_index.size > 0


def _event_driven(scene: SceneData, dt: float) -> Integrator:
    from ucontrol.integrators.event_driven import EventDriven  # loads scipy.integrate

    settings = scene.integrator
    laws = _impact_laws(scene)
    return EventDriven(
        scene.robot,
        scene.constraints,
        dt=dt,
        zeno_velocity=settings.zeno_velocity,
        impact_solver=ProxsuiteLCPSolver(
            eps_abs=settings.contact_tolerance, max_iter=settings.max_iter
        ),
        acceleration_solver=ProxsuiteLCPSolver(
            eps_abs=settings.contact_tolerance, max_iter=settings.max_iter
        ),
        flexible=scene.flexible,
        impact_law=_lzb_law(scene) if {"lzb", "energetic"} & set(laws) else None,
        restitution_law=["newton" if law == "lzb" else law for law in laws],
        tangential_restitution=settings.tangential_restitution,
        joint_friction=scene.joint_friction,
        **settings.solver_options(),
    )


def _frictional_impacts(scene: SceneData) -> bool:
    """Whether event_driven may take the scene's frictional contacts (fixed surfaces)."""
    return scene.integrator.name == "event_driven" and not scene.constraints.time_dependent


def _impact_laws(scene: SceneData) -> list[str]:
    """The impact law of every constraint of the scene, shape (n,).

    Raises:
        ShapeError: A per-constraint list of another length than the constraints'.
    """
    laws = scene.integrator.impact_law
    n = scene.constraints.size
    if isinstance(laws, str):
        return [laws] * n
    if len(laws) != n:
        raise ShapeError("[integrator] impact_law", (n,), (len(laws),))
    return list(laws)


def _lzb_law(scene: SceneData) -> Any:
    """The LZB impact law of a scene: its restitutions as energetic coefficients."""
    from ucontrol.integrators.lzb_impact import LZBImpactLaw

    settings = scene.integrator
    return LZBImpactLaw(
        restitution=scene.constraints.restitution,
        stiffness=np.asarray(settings.lzb_stiffness, dtype=float),
        exponent=np.asarray(settings.lzb_exponent, dtype=float),
        impulse_step=settings.lzb_impulse_step,
        max_steps=settings.lzb_max_steps,
    )


def _compliant(scene: SceneData, dt: float) -> Integrator:
    from ucontrol.integrators.compliant import Compliant  # loads scipy.integrate

    settings = scene.integrator
    return Compliant(
        scene.robot,
        scene.constraints,
        dt=dt,
        stiffness=settings.stiffness,
        contact_model=settings.contact_model,
        reference_speed=settings.reference_speed,
        flexible=scene.flexible,
        joint_friction=scene.joint_friction,
        **settings.solver_options(),
    )


_BUILDERS: dict[str, Callable[[SceneData, float], Integrator]] = {
    "moreau_jean": _moreau_jean,
    "event_driven": _event_driven,
    "compliant": _compliant,
}
