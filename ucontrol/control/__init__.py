"""Controllers and the protocol they follow.

:class:`FlexibleBrogliatoController` (casadi) is imported on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from ucontrol.control.brogliato_controller import BrogliatoController, BrogliatoGains
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.controller import ContactState, Controller, LoggingController
from ucontrol.control.desired_cycle import ContactPhase, DesiredCycle, NominalPath
from ucontrol.control.joint_pd import JointPD
from ucontrol.control.phase import Event, Phase
from ucontrol.control.phase_machine import DesiredState, PhaseMachine
from ucontrol.control.task_coordinates import TaskCoordinates, TaskState
from ucontrol.control.zero_torque import ZeroTorque

if TYPE_CHECKING:
    from ucontrol.control.flexible_brogliato_controller import FlexibleBrogliatoController

__all__ = [
    "BrogliatoController",
    "BrogliatoGains",
    "CirclePath",
    "ContactPhase",
    "ContactState",
    "Controller",
    "DesiredCycle",
    "DesiredState",
    "Event",
    "FlexibleBrogliatoController",
    "JointPD",
    "LoggingController",
    "NominalPath",
    "Phase",
    "PhaseMachine",
    "TaskCoordinates",
    "TaskState",
    "ZeroTorque",
]


def __getattr__(name: str) -> Any:
    if name == "FlexibleBrogliatoController":
        module = import_module("ucontrol.control.flexible_brogliato_controller")
        return module.FlexibleBrogliatoController
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
