"""The 1-DoF paddle juggles a ball in closed loop (event-driven plant).

References: the commanded apex (the ball's ballistic apex between hits, measured on the log),
and the closed loop's Floquet multipliers by finite differences of its impact-to-impact map
(ucontrol.analysis.poincare), which must lie inside the unit circle.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from tests.conftest import ROBOTS
from ucontrol.analysis.poincare import finite_difference_jacobian
from ucontrol.control.juggling_controller import JugglingController, JugglingSettings
from ucontrol.exceptions import InvalidParameterError, NotFoundError, UnknownKeyError
from ucontrol.scene import Scene
from ucontrol.scene.juggling_table import juggling_from_table
from ucontrol.scene_maps import scene_impact_map
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

_APEX = 0.2  # [m], ball centre
_DT = 2e-3  # [s], sampling and control period of the event-driven plant
_CONTACT = "ball/paddle"


def juggler(restitution: float, q0: np.ndarray | None = None, v0: np.ndarray | None = None):
    scene = Scene.from_toml(ROBOTS / "juggler_paddle.toml")
    pair = dataclasses.replace(scene.sphere_contacts[0], restitution=restitution)
    changes = {"sphere_contacts": (pair,)}
    if q0 is not None:
        changes |= {"q0": q0, "v0": v0}
    scene = dataclasses.replace(scene, **changes)
    table = {"type": "juggling", "apex": _APEX, "contact": _CONTACT}
    return scene, juggling_from_table(scene, table)


def apexes(log) -> np.ndarray:
    """Highest ball centre between consecutive hits, shape (hits - 1,)."""
    hits = np.flatnonzero(log.impulse_of(_CONTACT) > 0.0)
    z_ball = log.q[:, 0]
    return np.array([z_ball[a:b].max() for a, b in itertools.pairwise(hits)])


@pytest.mark.parametrize("e", [0.6, 0.8, 0.9])
def test_paddle_keeps_the_ball_at_the_commanded_apex(e: float) -> None:
    scene, controller = juggler(e)
    result = simulate(scene, controller, duration=7.6, dt=_DT, progress=False)
    heights = apexes(result.log)
    assert heights.size >= 20
    # after the first hit (transient) every apex within 1 % of the command
    assert np.max(np.abs(heights[1:] / _APEX - 1.0)) <= 0.01
    assert result.summary["max_penetration"] <= 1e-6


def test_closed_loop_floquet_multipliers_inside_unit_circle() -> None:
    """Impact-to-impact map of the closed loop: state at the replanning after a hit -> next.

    The section is the sampling instant after a hit (the controller's replanning), so a
    perturbation along the flow moves the sampled state along the orbit: multiplier 1.
    """
    scene, controller = juggler(0.8)
    result = simulate(scene, controller, duration=1.2, dt=_DT, progress=False)
    log = result.log
    hits = np.flatnonzero(log.impulse_of(_CONTACT) > 0.0)
    row = hits[1] + 1  # the controller replans on the row after the impact's step
    x_star = np.concatenate((log.q[row], log.v[row]))

    def next_hit(x: np.ndarray) -> np.ndarray:
        scene_x, _ = juggler(0.8, x[:2], x[2:])
        table = {"type": "juggling", "apex": _APEX, "contact": _CONTACT}
        P = scene_impact_map(scene_x, lambda: juggling_from_table(scene_x, table), _CONTACT, 0.5)
        return P(x)

    image = next_hit(x_star)
    # period-1 up to the sampling of the replanning instant: the hit falls anywhere in a step,
    # so the ball is sampled up to one step after it (its velocity differs by up to g dt)
    assert np.max(np.abs(image - x_star)) <= 9.81 * _DT
    jacobian = finite_difference_jacobian(next_hit, x_star, step=1e-6)
    multipliers = np.linalg.eigvals(jacobian)
    # the closed loop is autonomous: a shift along the orbit stays a shift (the trivial
    # multiplier 1, eigenvector along the flow); the others are the orbit's Floquet multipliers
    trivial = int(np.argmin(np.abs(multipliers - 1.0)))
    assert abs(multipliers[trivial] - 1.0) <= 0.02
    floquet = np.delete(multipliers, trivial)
    assert np.max(np.abs(floquet)) < 0.5  # dead-beat design: well inside the unit circle


def test_apex_out_of_reach_is_refused() -> None:
    scene, _ = juggler(0.8)
    with pytest.raises(InvalidParameterError, match="apex") as error:
        juggling_from_table(scene, {"type": "juggling", "apex": 0.04})
    assert error.value.value == 0.04
    with pytest.raises(InvalidParameterError, match="paddle speed"):
        juggling_from_table(scene, {"type": "juggling", "apex": 500.0})


def test_scene_impact_map_without_impact_is_refused() -> None:
    scene, _ = juggler(0.8)
    table = {"type": "juggling", "apex": _APEX, "contact": _CONTACT}
    P = scene_impact_map(scene, lambda: juggling_from_table(scene, table), _CONTACT, 0.05)
    with pytest.raises(InvalidParameterError, match="section"):
        P(np.concatenate((scene.q0, scene.v0)))


def test_bad_tables_are_refused() -> None:
    scene, _ = juggler(0.8)
    with pytest.raises(UnknownKeyError):
        juggling_from_table(scene, {"type": "juggling", "apex": 0.3, "apogee": 1})
    with pytest.raises(NotFoundError):
        juggling_from_table(scene, {"type": "juggling", "apex": 0.3, "contact": "nope"})
    with pytest.raises(InvalidParameterError, match="restitution"):
        JugglingSettings(apex=0.3, restitution=1.0)


def test_plan_reaches_the_hit_state() -> None:
    """The cubic ends at the hit height with the paddle velocity Newton's law asks for."""
    scene, controller = juggler(0.8)
    assert isinstance(controller, JugglingController)
    q, v = scene.initial_state()
    controller._replan(0.0, q, v)
    hit = controller.hits[-1]
    z, dz, _ = controller.reference(hit.hit_time - 1e-12)
    assert abs(z - controller.settings.hit_height) <= 1e-9
    assert abs(dz - hit.paddle_velocity) <= 1e-9
    # Newton's law with momentum conservation sends the ball up at the take-off speed
    e, mu = 0.8, controller.mass_ratio
    ball_out = ((mu - e) * hit.ball_velocity + (1 + e) * hit.paddle_velocity) / (1 + mu)
    assert abs(ball_out - controller.takeoff_speed) <= 1e-12


def test_measured_restitution_removes_the_apex_offset() -> None:
    """The controller assumes e = 0.8, the ball has 0.7: measuring e at each hit recovers."""
    scene, _ = juggler(0.7)
    table = {"type": "juggling", "apex": _APEX, "contact": _CONTACT, "restitution": 0.8}
    plain = juggling_from_table(scene, table)
    adaptive = juggling_from_table(scene, {**table, "estimate_restitution": True})
    offsets = []
    for controller in (plain, adaptive):
        heights = apexes(simulate(scene, controller, duration=2.4, dt=_DT, progress=False).log)
        offsets.append(abs(heights[-1] / _APEX - 1.0))
    assert offsets[0] > 0.05  # a wrong e leaves an offset (no integral action)
    assert offsets[1] <= 1e-3
    assert abs(adaptive.restitution - 0.7) <= 1e-3


def test_two_link_arm_juggles_with_its_tip() -> None:
    """robots/juggler_arm.toml: the tip tracks the plan in task space, 20 hits at the apex."""
    scene = Scene.from_toml(ROBOTS / "juggler_arm.toml")
    apex = 0.35
    table = {
        "type": "juggling",
        "frame": "end_effector",
        "apex": apex,
        "hit_height": 0.2,
        "hit_x": 0.6,
        "contact": "ball/tip",
    }
    log = simulate(scene, juggling_from_table(scene, table), duration=6.3, progress=False).log
    hits = np.flatnonzero(log.impulse_of("ball/tip") > 0.0)
    heights = np.array([log.q[a:b, 0].max() for a, b in itertools.pairwise(hits)])
    assert heights.size >= 20
    assert np.max(np.abs(heights[1:] / apex - 1.0)) <= 0.01


@pytest.mark.parametrize(("name", "apex"), [("juggler_paddle", 0.3), ("juggler_arm", 0.5)])
def test_shipped_juggling_scenes_declare_their_controller(name: str, apex: float) -> None:
    from ucontrol.scene import load_scene

    scene = load_scene(name)
    log = simulate(scene, duration=6.0).log
    contact = scene.constraints.names[0]
    hits = np.flatnonzero(log.impulse_of(contact) > 0.0)
    assert hits.size >= 8
    late = log.t >= log.t[hits[3]]  # after the first hits settle the cycle
    # The ball's centre height is its first coordinate (the URDFs' joint order).
    assert np.max(log.q[late, 0]) == pytest.approx(apex, abs=1e-3)
