r"""The Zeno rule of the event-driven integrator, pinned on both sides of its thresholds.

An impact with approach speed :math:`u^- < 0` bounces with Newton's law
:math:`u^+ = -e u^-` only when the rebound speed :math:`-e u^-` reaches ``zeno_velocity``
:math:`v_z`; below it the impact is plastic (:math:`u^+ = 0`). After an impact, a constraint at
contact that leaves slower than :math:`v_z` (:math:`0 < u < v_z`) is captured: the velocity is
projected onto :math:`u = 0` in the metric of M, adding any constraint the projection sets
approaching. The scenes run without gravity, so that every flight is a straight line at
constant speed and the references are exact; the measured errors are at round-off (0 to
3e-17 m, 0 m/s), the tolerances 1e-15.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ucontrol.integrators.event_driven import EventDriven
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: Zeno velocity of the scenes, in [m/s].
V_Z = 1e-3
#: Ball radius in [m] and duration of the runs in [s].
RADIUS, DURATION = 0.1, 0.1
#: Round-off tolerance of the exact references (measured errors: 0 to 2.8e-17).
TOL = 1e-15

_GROUND = {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}


def _ball(speed: float, restitution: float) -> Scene:
    """The 1 kg ball of robots/ball.toml, 0.1 mm above the ground, falling at ``speed``."""
    table = {
        "name": "ball",
        "duration": DURATION,
        "robot": {
            "urdf": "ball.urdf",
            "q0": [RADIUS + 1e-4],
            "v0": [-speed],
            "gravity": [0.0, 0.0, 0.0],
        },
        "surfaces": {"ground": _GROUND},
        "contacts": [
            {"frame": "ball", "surface": "ground", "radius": RADIUS, "restitution": restitution}
        ],
        "integrator": {"name": "event_driven", "dt": 0.01, "zeno_velocity": V_Z},
    }
    return Scene.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize("factor", [0.95, 1.05])  # rebound speed / zeno_velocity
def test_an_impact_bounces_only_when_its_rebound_reaches_the_zeno_velocity(factor: float) -> None:
    e = 0.5
    u_minus = factor * V_Z / e  # [m/s]: the approach speed is 1.9 or 2.1 zeno_velocity
    result = simulate(_ball(u_minus, e), duration=DURATION)
    t_impact = 1e-4 / u_minus  # [s]
    u_plus = e * u_minus if factor >= 1.0 else 0.0  # [m/s]: Newton's law, or plastic
    log = result.log
    assert log.v[-1, 0] == pytest.approx(u_plus, abs=TOL)
    assert log.q[-1, 0] == pytest.approx(RADIUS + u_plus * (DURATION - t_impact), abs=TOL)
    # The impulse of the impact, m (u+ - u-), is the only one of the run.
    assert log.impulse.sum() == pytest.approx(u_plus + u_minus, abs=TOL)
    assert result.summary["n_events"] == 1


def _corner(wall_speed: float) -> Scene:
    """The free 1 kg ball landing plastically in the corner of the ground and a wall (x = 0).

    It touches both at t = 0 (gaps 0), falls onto the ground at 0.1 m/s and leaves the wall
    at ``wall_speed`` [m/s], sliding along y at 0.5 mm/s.
    """
    table = {
        "name": "corner",
        "duration": DURATION,
        "robot": {
            "urdf": "free_ball.urdf",
            "floating_base": True,
            "q0": [0.0, 0.0, RADIUS, 0.0, 0.0, 0.0, 1.0],
            "v0": [wall_speed, 5e-4, -0.1, 0.0, 0.0, 0.0],
            "gravity": [0.0, 0.0, 0.0],
        },
        "surfaces": {
            "ground": _GROUND,
            "wall": {"type": "plane", "point": [-RADIUS, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]},
        },
        "contacts": [
            {"frame": "ball", "surface": name, "radius": RADIUS, "restitution": 0.0}
            for name in ("ground", "wall")
        ],
        "integrator": {"name": "event_driven", "dt": 0.01, "zeno_velocity": V_Z},
    }
    return Scene.from_dict(table, base_dir=ROBOTS)


@pytest.mark.parametrize("factor", [0.95, 1.05])  # wall speed / zeno_velocity
def test_a_contact_leaving_slower_than_the_zeno_velocity_is_captured(factor: float) -> None:
    s = factor * V_Z  # [m/s]
    result = simulate(_corner(s), duration=DURATION)
    log = result.log
    captured = factor < 1.0
    # Captured: the velocity is projected onto u = 0 of both contacts in the metric of M (the
    # identity for a 1 kg ball): only the slide along the wall is left. Not captured: the
    # ball leaves the wall at s.
    v_expected = np.array([0.0 if captured else s, 5e-4, 0.0])  # [m/s]
    np.testing.assert_allclose(log.v[-1, :3], v_expected, atol=TOL)
    np.testing.assert_allclose(log.v[-1, 3:], 0.0, atol=TOL)
    wall_gap = 0.0 if captured else s * DURATION  # [m]
    np.testing.assert_allclose(log.gap[-1], [0.0, wall_gap], atol=TOL)
    # Impulses of the first step [N s]: the plastic landing (m 0.1 m/s on the ground), and
    # on the wall the capture's -m s, adhesive, of order m zeno_velocity.
    np.testing.assert_allclose(log.impulse[0], [0.1, -s if captured else 0.0], atol=TOL)
    assert result.summary["n_events"] == 0


PLANK_URDF = """<?xml version="1.0"?>
<robot name="plank">
  <link name="world"/>
  <link name="slider"/>
  <joint name="height" type="prismatic">
    <parent link="world"/><child link="slider"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="0" velocity="100"/>
  </joint>
  <link name="plank">
    <inertial>
      <origin xyz="0 0 0"/><mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
    </inertial>
  </link>
  <joint name="pitch" type="revolute">
    <parent link="slider"/><child link="plank"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="0" velocity="100"/>
  </joint>
{points}
</robot>
"""
#: Where the three contact points sit along the plank, in [m] from its centre of mass.
PLANK_POINTS = {"a": 0.1, "c": 1.0}


def _plank(tmp_path: Path, points_x: dict[str, float] = PLANK_POINTS, **robot: object) -> Scene:
    """A 1 kg plank (pitch inertia 0.01 kg m²) lying on the ground on two points, e = 0.5."""
    points = "\n".join(
        f'  <link name="{name}"/><joint name="{name}_joint" type="fixed"><parent link="plank"/>'
        f'<child link="{name}"/><origin xyz="{x} 0 0"/></joint>'
        for name, x in points_x.items()
    )
    (tmp_path / "plank.urdf").write_text(PLANK_URDF.format(points=points))
    table = {
        "name": "plank",
        "duration": DURATION,
        "robot": {"urdf": "plank.urdf", "q0": [0.0, 0.0], "gravity": [0.0, 0.0, 0.0], **robot},
        "surfaces": {"ground": _GROUND},
        "contacts": [{"frame": name, "surface": "ground", "restitution": 0.5} for name in points_x],
        "integrator": {"name": "event_driven", "dt": 0.01, "zeno_velocity": V_Z},
    }
    return Scene.from_dict(table, base_dir=tmp_path)


def test_a_capture_adds_the_constraints_its_projection_sets_approaching(tmp_path: Path) -> None:
    r"""Point a leaves slowly, c fast; stopping a sets c approaching, so c is captured too.

    Normal velocities :math:`u_i = \dot z - x_i \dot\theta`; Delassus
    :math:`D_{ij} = 1/m + x_i x_j / I`. Stopping a alone changes :math:`u_c` by
    :math:`-(D_{ca}/D_{aa})\,u_a = -5.5\,u_a`: with :math:`u_a = 0.5 v_z` and
    :math:`u_c = 2 v_z` the plank would then press into the ground at c. Projected onto
    :math:`u_a = u_c = 0` it stops (two independent rows, two velocities). No scene of
    robots/ reaches this case from a full run (after the impacts tried, a point slower than
    :math:`v_z` is at rest or its stop changes the others by less than :math:`v_z`), so the
    stage is called on the plank's own constraint terms, at the velocity an impact left.
    """
    scene = _plank(tmp_path)
    integrator = scene.build_integrator()
    assert isinstance(integrator, EventDriven)
    x = np.array(list(PLANK_POINTS.values()))
    u_a, u_c = 0.5 * V_Z, 2.0 * V_Z  # [m/s]
    theta_dot = -(u_c - u_a) / (x[1] - x[0])  # [rad/s], from u_i = z_dot - x_i theta_dot
    z_dot = u_a + x[0] * theta_dot  # [m/s]
    v = np.array([z_dot, theta_dot])
    terms = integrator._dynamics.constraint_terms(scene.q0, v, np.zeros(2), np.arange(2))
    u = terms.J @ v
    np.testing.assert_allclose(u, [u_a, u_c], atol=1e-18)  # the rows as derived
    assert u[1] > V_Z  # c leaves faster than the threshold: not captured by itself
    M = np.diag([1.0, 0.01])  # [kg], [kg m²]
    D = 1.0 + np.outer(x, x) / 0.01  # [1/kg], independent of the code's Delassus
    np.testing.assert_allclose(terms.delassus(), D, rtol=1e-12)
    assert u[1] - D[1, 0] / D[0, 0] * u[0] < 0.0  # stopping a alone sets c approaching

    v_after, impulse = integrator._capture(terms, v)

    np.testing.assert_allclose(v_after, 0.0, atol=1e-18)
    # Impulses: M (v+ - v) = J^T P; the kinetic energy falls to 0.
    np.testing.assert_allclose(terms.J.T @ impulse, M @ (v_after - v), atol=1e-18)


def test_a_slow_and_a_fast_landing_at_once_obey_the_zeno_rule_and_newton(tmp_path: Path) -> None:
    r"""The plank lands on both points at once: a at 1.9 v_z, c at 0.1 m/s (e = 0.5).

    Points on either side of the centre (x = -0.1 m and 1.0 m) both keep a positive impulse.
    a's rebound :math:`e |u_a^-| = 0.95 v_z` is below the threshold: a lands plastically
    (:math:`u_a^+ = 0`), c by Newton's law (:math:`u_c^+ = -e u_c^- = 0.05` m/s), both exact. A
    rebound test without e (:math:`-u^- \ge v_z`) would bounce a too; capturing it afterwards
    then lifts c to 0.0543 m/s through the coupling :math:`D_{ca} / D_{aa} = -4.5`.
    """
    x = np.array([-0.1, 1.0])  # [m]
    u_minus = np.array([-1.9 * V_Z, -0.1])  # [m/s]
    # z_dot - x theta_dot = u_minus at both points.
    theta_dot = -(u_minus[1] - u_minus[0]) / (x[1] - x[0])  # [rad/s]
    z_dot = u_minus[0] + x[0] * theta_dot  # [m/s]
    scene = _plank(tmp_path, {"a": x[0], "c": x[1]}, v0=[z_dot, theta_dot])
    # One step of 1 us: the plank's rotation over it changes the points' normal velocities by
    # O(h theta_dot^2 x) ~ 1e-14 m/s (measured 4.7e-10 m/s over a step of 10 ms).
    result = simulate(scene, dt=1e-6, duration=1e-6)
    v = result.log.v[1]  # after the step that starts with the landing
    u_plus = v[0] - x * v[1]  # [m/s]
    np.testing.assert_allclose(u_plus, [0.0, 0.05], atol=TOL)
    # Both impulses positive: J^T P = M (v+ - v-) with M = diag(1 kg, 0.01 kg m^2).
    impulse = result.log.impulse[0]
    assert np.all(impulse > 0.0)
    J = np.column_stack([np.ones(2), -x])
    np.testing.assert_allclose(
        J.T @ impulse, np.diag([1.0, 0.01]) @ (v - [z_dot, theta_dot]), atol=TOL
    )
