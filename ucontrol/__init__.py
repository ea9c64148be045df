"""ucontrol: tracking control of robots under unilateral constraints.

The names below are imported on first use (``import ucontrol`` itself loads neither
Pinocchio nor scipy), so a command or a worker pays only for what it uses.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names

if TYPE_CHECKING:
    from ucontrol.contact import (
        ConstraintSet,
        JointStop,
        Plane,
        PointContact,
        SphereSphereContact,
    )
    from ucontrol.control import ContactState, Controller, JointPD, ZeroTorque
    from ucontrol.integrators import Compliant, EventDriven, MoreauJean
    from ucontrol.log import Log
    from ucontrol.model import RobotModel
    from ucontrol.scene import Scene, load_scene
    from ucontrol.simulate import SimulationResult, simulate
    from ucontrol.solvers import ContactSolution, ProxsuiteLCPSolver

__version__ = "0.1.0"

#: Each public name and the module it is imported from on first use.
_EXPORTS = {
    "Compliant": "ucontrol.integrators",
    "ConstraintSet": "ucontrol.contact",
    "ContactSolution": "ucontrol.solvers",
    "ContactState": "ucontrol.control",
    "Controller": "ucontrol.control",
    "EventDriven": "ucontrol.integrators",
    "JointPD": "ucontrol.control",
    "JointStop": "ucontrol.contact",
    "Log": "ucontrol.log",
    "MoreauJean": "ucontrol.integrators",
    "Plane": "ucontrol.contact",
    "PointContact": "ucontrol.contact",
    "ProxsuiteLCPSolver": "ucontrol.solvers",
    "RobotModel": "ucontrol.model",
    "Scene": "ucontrol.scene",
    "SimulationResult": "ucontrol.simulate",
    "SphereSphereContact": "ucontrol.contact",
    "ZeroTorque": "ucontrol.control",
    "load_scene": "ucontrol.scene",
    "simulate": "ucontrol.simulate",
}

__all__ = [
    "Compliant",
    "ConstraintSet",
    "ContactSolution",
    "ContactState",
    "Controller",
    "EventDriven",
    "JointPD",
    "JointStop",
    "Log",
    "MoreauJean",
    "Plane",
    "PointContact",
    "ProxsuiteLCPSolver",
    "RobotModel",
    "Scene",
    "SimulationResult",
    "SphereSphereContact",
    "ZeroTorque",
    "load_scene",
    "simulate",
]


__getattr__ = lazy_names(__name__, _EXPORTS)


def __dir__() -> list[str]:
    return sorted((*globals(), *_EXPORTS))
