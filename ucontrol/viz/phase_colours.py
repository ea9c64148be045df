"""One colour per phase of the phase-machine controller, shared by the figures and the viewer."""

from __future__ import annotations

from ucontrol.control.phase import Phase

#: Colour of each phase (hex RGB): background bands of the time plots, label of the viewer.
PHASE_COLOURS: dict[Phase, str] = {
    Phase.FREE: "#ffffff",
    Phase.APPROACH: "#fde0c5",
    Phase.TRANSITION: "#d9f0d3",
    Phase.CONSTRAINED: "#f9d3d3",
    Phase.TAKEOFF: "#e5d8f0",
}
