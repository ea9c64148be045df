"""Controllers and the protocol they follow.

:class:`FlexibleBrogliatoController` (casadi) is imported on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from ucontrol.control.brogliato_controller import BrogliatoController, BrogliatoGains
from ucontrol.control.circle_path import CirclePath
from ucontrol.control.controller import ContactState, Controller, LoggingController
from ucontrol.control.desired_cycle import (
    ContactPhase,
    DesiredCycle,
    NominalPath,
    read_designed_cycle,
)
from ucontrol.control.friction_compensation import FrictionCompensation
from ucontrol.control.impedance_controller import ImpedanceController, ImpedanceGains
from ucontrol.control.joint_pd import JointPD
from ucontrol.control.juggling_controller import (
    ArmJugglingController,
    JugglingController,
    JugglingSettings,
)
from ucontrol.control.path_reach import check_reach
from ucontrol.control.path_table import PATH_TYPES, path_from_table
from ucontrol.control.phase import Event, Phase
from ucontrol.control.phase_machine import DesiredState, PhaseMachine
from ucontrol.control.polyline_path import PolylinePath
from ucontrol.control.segment_path import SegmentPath
from ucontrol.control.spline_path import SplinePath
from ucontrol.control.task_coordinates import TaskCoordinates, TaskState
from ucontrol.control.zero_torque import ZeroTorque

if TYPE_CHECKING:
    from ucontrol.control.flexible_brogliato_controller import FlexibleBrogliatoController

__all__ = [
    "PATH_TYPES",
    "ArmJugglingController",
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
    "FrictionCompensation",
    "ImpedanceController",
    "ImpedanceGains",
    "JointPD",
    "JugglingController",
    "JugglingSettings",
    "LoggingController",
    "NominalPath",
    "Phase",
    "PhaseMachine",
    "PolylinePath",
    "SegmentPath",
    "SplinePath",
    "TaskCoordinates",
    "TaskState",
    "ZeroTorque",
    "check_reach",
    "path_from_table",
    "read_designed_cycle",
]


def __getattr__(name: str) -> Any:
    if name == "FlexibleBrogliatoController":
        module = import_module("ucontrol.control.flexible_brogliato_controller")
        return module.FlexibleBrogliatoController
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
