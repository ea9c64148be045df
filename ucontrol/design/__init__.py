"""Desired cycles by optimal control (casadi Opti/IPOPT on the symbolic model).

A :class:`DesignTask` (task file) says what one cycle must do; :func:`design_cycle`
transcribes it (:class:`CycleTranscription`: multi-phase multiple shooting with free phase
durations, impact maps, constrained dynamics) and solves it with IPOPT into a
:class:`DesignedCycle` and a :class:`DesignReport`; :func:`replay_open_loop` checks the design
model against the plant.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names

if TYPE_CHECKING:
    from ucontrol.design.cycle_transcription import CycleTranscription, design_cycle
    from ucontrol.design.design_report import DesignReport
    from ucontrol.design.design_task import DesignTask
    from ucontrol.design.designed_cycle import CyclePhase, DesignedCycle
    from ucontrol.design.open_loop_replay import ReplayResult, replay_open_loop
    from ucontrol.design.periodic_spline_path import PeriodicSplinePath

#: Each public name and its module, imported on first use (casadi loads with the first).
_EXPORTS = {
    "CyclePhase": "ucontrol.design.designed_cycle",
    "CycleTranscription": "ucontrol.design.cycle_transcription",
    "DesignReport": "ucontrol.design.design_report",
    "DesignTask": "ucontrol.design.design_task",
    "DesignedCycle": "ucontrol.design.designed_cycle",
    "PeriodicSplinePath": "ucontrol.design.periodic_spline_path",
    "ReplayResult": "ucontrol.design.open_loop_replay",
    "design_cycle": "ucontrol.design.cycle_transcription",
    "replay_open_loop": "ucontrol.design.open_loop_replay",
}

__all__ = [
    "CyclePhase",
    "CycleTranscription",
    "DesignReport",
    "DesignTask",
    "DesignedCycle",
    "PeriodicSplinePath",
    "ReplayResult",
    "design_cycle",
    "replay_open_loop",
]


__getattr__ = lazy_names(__name__, _EXPORTS)
