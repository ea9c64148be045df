"""Controllers and the protocol they follow.

Every name is imported from its module on first use, so that a scene without a controller
loads neither casadi (:class:`BrogliatoController`) nor scipy.interpolate
(:class:`SplinePath`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names

if TYPE_CHECKING:
    from ucontrol.control.brogliato_controller import BrogliatoController, BrogliatoGains
    from ucontrol.control.circle_path import CirclePath
    from ucontrol.control.controller import ContactState, Controller, LoggingController
    from ucontrol.control.desired_cycle import (
        ContactPhase,
        DesiredCycle,
        NominalPath,
        read_designed_cycle,
    )
    from ucontrol.control.flexible_brogliato_controller import FlexibleBrogliatoController
    from ucontrol.control.friction_compensation import FrictionCompensation
    from ucontrol.control.hzd_controller import HZDController, HZDSettings
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
    from ucontrol.control.raibert_controller import RaibertController, RaibertSettings
    from ucontrol.control.segment_path import SegmentPath
    from ucontrol.control.spline_path import SplinePath
    from ucontrol.control.task_coordinates import TaskCoordinates, TaskState
    from ucontrol.control.zero_torque import ZeroTorque

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
    "HZDController",
    "HZDSettings",
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
    "RaibertController",
    "RaibertSettings",
    "SegmentPath",
    "SplinePath",
    "TaskCoordinates",
    "TaskState",
    "ZeroTorque",
    "check_reach",
    "path_from_table",
    "read_designed_cycle",
]


#: Where each public name lives; imported on first use (PEP 562).
_MODULES = {
    "PATH_TYPES": "ucontrol.control.path_table",
    "ArmJugglingController": "ucontrol.control.juggling_controller",
    "BrogliatoController": "ucontrol.control.brogliato_controller",
    "BrogliatoGains": "ucontrol.control.brogliato_controller",
    "CirclePath": "ucontrol.control.circle_path",
    "ContactPhase": "ucontrol.control.desired_cycle",
    "ContactState": "ucontrol.control.controller",
    "Controller": "ucontrol.control.controller",
    "DesiredCycle": "ucontrol.control.desired_cycle",
    "DesiredState": "ucontrol.control.phase_machine",
    "Event": "ucontrol.control.phase",
    "FlexibleBrogliatoController": "ucontrol.control.flexible_brogliato_controller",
    "FrictionCompensation": "ucontrol.control.friction_compensation",
    "HZDController": "ucontrol.control.hzd_controller",
    "HZDSettings": "ucontrol.control.hzd_controller",
    "ImpedanceController": "ucontrol.control.impedance_controller",
    "ImpedanceGains": "ucontrol.control.impedance_controller",
    "JointPD": "ucontrol.control.joint_pd",
    "JugglingController": "ucontrol.control.juggling_controller",
    "JugglingSettings": "ucontrol.control.juggling_controller",
    "LoggingController": "ucontrol.control.controller",
    "NominalPath": "ucontrol.control.desired_cycle",
    "Phase": "ucontrol.control.phase",
    "PhaseMachine": "ucontrol.control.phase_machine",
    "PolylinePath": "ucontrol.control.polyline_path",
    "RaibertController": "ucontrol.control.raibert_controller",
    "RaibertSettings": "ucontrol.control.raibert_controller",
    "SegmentPath": "ucontrol.control.segment_path",
    "SplinePath": "ucontrol.control.spline_path",
    "TaskCoordinates": "ucontrol.control.task_coordinates",
    "TaskState": "ucontrol.control.task_coordinates",
    "ZeroTorque": "ucontrol.control.zero_torque",
    "check_reach": "ucontrol.control.path_reach",
    "path_from_table": "ucontrol.control.path_table",
    "read_designed_cycle": "ucontrol.control.desired_cycle",
}


__getattr__ = lazy_names(__name__, _MODULES)


def __dir__() -> list[str]:
    return sorted(__all__)
