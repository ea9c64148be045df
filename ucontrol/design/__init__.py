"""Desired cycles by optimal control (casadi Opti/IPOPT on the symbolic model).

A :class:`DesignTask` (task file) says what one cycle must do; :func:`design_cycle`
transcribes it (:class:`CycleTranscription`: multi-phase multiple shooting with free phase
durations, impact maps, constrained dynamics) and solves it with IPOPT into a
:class:`DesignedCycle` and a :class:`DesignReport`; :func:`replay_open_loop` checks the design
model against the plant.
"""

from ucontrol.design.cycle_transcription import CycleTranscription, design_cycle
from ucontrol.design.design_report import DesignReport
from ucontrol.design.design_task import DesignTask
from ucontrol.design.designed_cycle import CyclePhase, DesignedCycle
from ucontrol.design.open_loop_replay import ReplayResult, replay_open_loop
from ucontrol.design.periodic_spline_path import PeriodicSplinePath

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
