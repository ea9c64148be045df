"""Closed-loop runs of the scenes of robots/, shared (cached) by the closed-loop tests."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any

import pytest

from ucontrol.analysis.cycles import cycle_events
from ucontrol.control import BrogliatoController, Phase
from ucontrol.log import Log
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import SimulationResult, simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"

#: Step of the acceptance runs, in [s]: the free-motion error and the V floor scale as dt and
#: dt² (measured at 2e-3, 1e-3, 5e-4 s), and 1e-3 s keeps them far below the bounds tested.
DT = 1e-3
#: Step of the robustness runs, in [s]: they check that cycles complete, not accuracy, and
#: every cycle completes alike at 1e-3 s and 2e-3 s.
DT_ROBUSTNESS = 2e-3


def scene(name: str, *, restitution: float | None = None, **controller: Any) -> Scene:
    """Scene ``robots/<name>.toml``, optionally with another restitution and controller keys."""
    loaded = load_scene(ROBOTS / f"{name}.toml")
    if restitution is not None:
        contacts = tuple(
            dataclasses.replace(contact, restitution=restitution) for contact in loaded.contacts
        )
        loaded = dataclasses.replace(loaded, contacts=contacts)
    return dataclasses.replace(loaded, controller={**loaded.controller, **controller})


@functools.cache
def run(
    name: str,
    cycles: int,
    dt: float = DT,
    restitution: float | None = None,
    mass_scale: float = 1.0,
    force_gain: float | None = None,
) -> tuple[BrogliatoController, SimulationResult]:
    """Run ``cycles`` cycles (and the last takeoff) of a scene; cached for the session."""
    gains = {} if force_gain is None else {"force_gain": force_gain}
    variant = scene(name, restitution=restitution, mass_scale=mass_scale, **gains)
    controller = variant.build_controller()
    assert isinstance(controller, BrogliatoController)
    duration = cycles * controller.cycle.period + 0.5  # [s]
    return controller, simulate(variant, controller, duration=duration, dt=dt, progress=False)


def assert_ground_and_wall_every_cycle(
    controller: BrogliatoController, log: Log, cycles: int
) -> None:
    """Each of ``cycles`` cycles completes, reaching the ground (contact 0) and the wall (1).

    Every contact goes through τ0 < first impact < end of accumulation < takeoff with over 2 s
    of constrained motion, both are held at once in the corner for over 1 s, and the cycle
    runs ground first, wall once on the ground, ground left first, wall left at the period.
    """
    ground, wall = 0, 1
    events = cycle_events(log)
    assert len(events) == cycles
    for cycle in events:
        assert cycle.complete, cycle
        rows = slice(cycle.start, cycle.stop)
        for contact in (ground, wall):
            held = log.contact_phase[rows, contact] == Phase.CONSTRAINED
            assert held.sum() * DT > 2.0  # [s] of constrained motion on each surface
            assert cycle.tau0[contact] < cycle.first_impact[contact]
            assert cycle.first_impact[contact] < cycle.accumulation_end[contact]
            assert cycle.accumulation_end[contact] < cycle.takeoff[contact]
        corner = (log.contact_phase[rows] == Phase.CONSTRAINED).all(axis=1)
        assert corner.sum() * DT > 1.0  # [s] with both contacts held, with their forces
        assert cycle.accumulation_end[ground] < cycle.tau0[wall]
        assert cycle.takeoff[ground] < cycle.takeoff[wall]
        period = controller.cycle.period
        assert cycle.takeoff[wall] == pytest.approx(period * (cycle.index + 1))
