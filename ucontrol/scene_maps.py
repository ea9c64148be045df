"""Poincaré maps of a scene's closed loop, each evaluation a run of :func:`ucontrol.simulate`.

The maps of :mod:`ucontrol.analysis.poincare` (its :func:`~ucontrol.analysis.poincare.fixed_point`,
:func:`~ucontrol.analysis.poincare.finite_difference_jacobian`, ...) applied to a whole scene:
the stroboscopic map over a forcing period and the impact map from one hit to the next. Above
:mod:`ucontrol.simulate` in the layers, as the analysis below it runs no closed loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ucontrol.analysis.poincare import Map, Vector
from ucontrol.control.controller import Controller
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene
from ucontrol.simulate import simulate


def scene_stroboscopic_map(scene: Scene, controller: Controller, period: float) -> Map:
    """The stroboscopic map (q, v) -> (q, v) of a scene, by :func:`ucontrol.simulate`.

    The state one ``period`` later. The scene's integrator step should divide ``period``; the
    controller must depend on time only through t (each evaluation restarts at t = 0).
    """

    def P(x: Vector) -> Vector:
        nq = scene.q0.size
        start = replace(scene, q0=x[:nq], v0=x[nq:])
        log = simulate(start, controller, duration=period, progress=False).log
        return np.concatenate((log.q[-1], log.v[-1]))

    return P


def scene_impact_map(
    scene: Scene, controller: Callable[[], Controller], constraint: str, horizon: float
) -> Map:
    """The impact map of a scene, by :func:`ucontrol.simulate`: state after a hit -> the next.

    x = (q, v) starts a run with a fresh controller (``controller()``, so that a controller's
    memory starts anew); the image is the state at the first sample after the first step in
    which ``constraint`` takes an impulse. The section is that sampling instant: a closed loop
    that is autonomous has the trivial multiplier 1 along its flow.

    Raises:
        InvalidParameterError: No impact on ``constraint`` within ``horizon`` [s] (the section
            is never crossed).
    """

    def P(x: Vector) -> Vector:
        nq = scene.q0.size
        start = replace(scene, q0=x[:nq], v0=x[nq:])
        log = simulate(start, controller(), duration=horizon, progress=False).log
        hits = np.flatnonzero(log.impulse_of(constraint) > 0.0)
        if hits.size == 0 or hits[0] + 1 >= log.t.size:
            raise InvalidParameterError(
                "section", f"no impact on {constraint!r} within {horizon:g} s", "crossed"
            )
        row = int(hits[0]) + 1
        return np.concatenate((log.q[row], log.v[row]))

    return P
