"""ucontrol: tracking control of robots under unilateral constraints."""

from ucontrol.contact import ConstraintSet, JointStop, Plane, PointContact, SphereSphereContact
from ucontrol.control import ContactState, Controller, JointPD, ZeroTorque
from ucontrol.integrators import Compliant, EventDriven, MoreauJean
from ucontrol.log import Log
from ucontrol.model import RobotModel
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import SimulationResult, simulate
from ucontrol.solvers import ContactSolution, ProxsuiteLCPSolver

__version__ = "0.1.0"

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
