"""The compass walker with small foot masses tends to the simplest walker as beta -> 0."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS
from scipy.integrate import solve_ivp

from ucontrol import simulate
from ucontrol.analysis.gait import Gait, find_gait
from ucontrol.analysis.simplest_walker import SimplestWalker
from ucontrol.analysis.stance_flow import StanceFlow
from ucontrol.contact import PointContact
from ucontrol.exceptions import (
    InvalidParameterError,
    NotFoundError,
    PenetrationWarning,
    StrideError,
)
from ucontrol.scene import Scene

#: The scene's gravity [m/s²]; time unit of the simplest walker sqrt(l/g), l = 1 m.
RATE_SCALE = math.sqrt(9.81)
#: Richardson extrapolation of the gaits at beta = 1e-3 and 1e-4 against the beta -> 0 walker
#: (measured: 1.4e-8 on the section's coordinates, 1.8e-8 on the period, 1.8e-5 on the
#: multipliers, which move faster with beta: 1.4e-2 at 1e-3, 1.4e-3 at 1e-4); the gaits
#: themselves differ from the limit by O(beta) (1.5e-4 at 1e-3).
LIMIT_TOLERANCE = 1e-7
MULTIPLIER_TOLERANCE = 5e-5


def _scene(tmp_path: Path, beta: float) -> Scene:
    """The shipped compass walker with feet of mass beta (the hip's is 1 kg)."""
    urdf = (ROBOTS / "compass_walker.urdf").read_text()
    urdf_path = tmp_path / f"compass_{beta:g}.urdf"
    urdf_path.write_text(urdf.replace('<mass value="0.01"/>', f'<mass value="{beta!r}"/>'))
    toml = (ROBOTS / "compass_walker.toml").read_text()
    toml_path = tmp_path / f"compass_{beta:g}.toml"
    toml_path.write_text(toml.replace('"compass_walker.urdf"', f'"{urdf_path.name}"'))
    return Scene.from_toml(toml_path)


def _chart(flow: StanceFlow) -> tuple[Any, Any]:
    """The chart z = (θ, θ̇, φ̇) after a strike, in the simplest walker's units.

    q = (x, z, hip_a, hip_b): the stance leg's rotation is -θ, the swing leg's -(θ - φ), with
    φ = 2θ after a strike; leg a is the stance leg of ``to_state``.
    """

    def to_state(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta, dtheta, dphi = z
        q = np.array([-math.sin(theta), math.cos(theta), -theta, theta])
        hip = -dtheta * np.array([math.cos(theta), math.sin(theta)])
        return q, RATE_SCALE * np.array([*hip, -dtheta, dphi - dtheta])

    def from_state(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return _section(q, v, flow.stance_of(q, v))

    return to_state, from_state


def _section(q: np.ndarray, v: np.ndarray, stance: int) -> np.ndarray:
    """The chart's z = (θ, θ̇, φ̇) of a state whose stance foot is ``stance`` (0: a, 1: b)."""
    swing = 1 - stance
    rate_stance, rate_swing = v[2 + stance], v[2 + swing]
    return np.array(
        [-q[2 + stance], -rate_stance / RATE_SCALE, (rate_swing - rate_stance) / RATE_SCALE]
    )


@pytest.fixture(scope="module")
def gaits(tmp_path_factory: pytest.TempPathFactory) -> dict[float, Gait]:
    tmp_path = tmp_path_factory.mktemp("compass")
    z0 = np.array([0.2003109, -0.1998325, -0.0158230])
    found = {}
    for beta in (1e-3, 1e-4):
        flow = StanceFlow(_scene(tmp_path, beta).constraints)
        found[beta] = find_gait(flow, *_chart(flow), z0, step=1e-6)
    return found


def test_the_gaits_tend_to_the_simplest_walker_as_the_foot_mass_vanishes(
    gaits: dict[float, Gait],
) -> None:
    walker = SimplestWalker(slope=0.009)
    limit = find_gait(walker, walker.to_state, walker.from_state, np.array([0.2, -0.2]))
    theta, dtheta = limit.z
    z_limit = np.array([theta, dtheta, (1.0 - math.cos(2.0 * theta)) * dtheta])
    small, smaller = gaits[1e-3], gaits[1e-4]
    # O(beta): a tenth of the foot mass, a tenth of the distance to the limit.
    ratio = np.linalg.norm(small.z - z_limit) / np.linalg.norm(smaller.z - z_limit)
    assert 9.5 < ratio < 10.5
    # Richardson in beta (ratio 10) removes the O(beta) term.
    extrapolated = (10.0 * smaller.z - small.z) / 9.0
    assert np.max(np.abs(extrapolated - z_limit)) <= LIMIT_TOLERANCE
    period = (10.0 * smaller.period - small.period) / 9.0 * RATE_SCALE
    assert abs(period - limit.period) <= LIMIT_TOLERANCE
    # Multipliers: the complex pair of the limit, and a third one that vanishes with beta
    # (with massless feet the strike fixes φ̇⁺ from θ̇⁺).
    pair = [np.sort_complex(gait.multipliers[:2]) for gait in (small, smaller)]
    extrapolated_pair = (10.0 * pair[1] - pair[0]) / 9.0
    reference = np.sort_complex(np.linalg.eigvals(walker.stride_jacobian(limit.z)))
    assert np.max(np.abs(extrapolated_pair - reference)) <= MULTIPLIER_TOLERANCE
    assert abs(smaller.multipliers[2]) < 1e-6 and smaller.stable


def test_the_scuff_is_ignored_and_the_swing_foot_strikes_ahead(
    tmp_path: Path, gaits: dict[float, Gait]
) -> None:
    scene = _scene(tmp_path, 1e-4)
    flow = StanceFlow(scene.constraints)
    q, v = _chart(flow)[0](gaits[1e-4].z)
    stride = flow.stride(q, v)
    # The struck foot (b) is ahead of the old stance foot (a, at x = 0), a step length away.
    assert stride.stance == 1
    assert stride.q[0] - math.sin(stride.q[3]) == pytest.approx(2.0 * math.sin(gaits[1e-4].z[0]))
    # The swing foot went below the slope on the way (the scuff that is ignored): its gap at
    # the gait's scuff time is negative.
    state = np.concatenate((q, v))
    scuff_time = 1.854 / RATE_SCALE  # [s] deepest point of the beta -> 0 walker's scuff

    solution = solve_ivp(
        lambda _, y: np.concatenate((y[4:], flow.acceleration(y[:4], y[4:], 0)[0])),
        (0.0, scuff_time),
        state,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
    )
    assert -1e-4 < scene.constraints.gaps(solution.y[:4, -1])[1] < -1e-5


@pytest.mark.slow
def test_moreau_jean_walks_the_gait_and_its_strides_converge_at_order_one() -> None:
    # The shipped scene (beta = 1e-2) released on its own gait: the event-driven strides
    # (StanceFlow) repeat the fixed point z* every period T. Moreau-Jean applies the scene's
    # scuffing rule (a foot closes only once the hip is past the other foot) and walks; its
    # post-strike states and strike times approach z* and k T at order one in h. Measured,
    # largest over the first four strides, h = 2, 1, 0.5 ms: |z - z*| 1.9e-2, 7.2e-3, 3.9e-3;
    # |t - kT| 6.6e-2, 2.7e-2, 1.5e-2 s (the first stride alone: 3.3e-3, 1.6e-3, 8.4e-4).
    scene = Scene.from_toml(ROBOTS / "compass_walker.toml")
    flow = StanceFlow(scene.constraints)
    to_state, from_state = _chart(flow)
    gait = find_gait(flow, to_state, from_state, np.array([0.2, -0.2, -0.016]), step=1e-6)
    q0, v0 = to_state(gait.z)
    strides = 4
    steps = np.array([2e-3, 1e-3, 5e-4])  # [s]
    errors, time_errors = [], []
    for h in steps:
        run = dataclasses.replace(scene, q0=q0, v0=v0)
        log = simulate(run, duration=strides * gait.period + 0.1, dt=float(h)).log
        impacts = log.impacts
        assert list(impacts.constraint) == ["foot_b/ground", "foot_a/ground"] * (strides // 2)
        assert log.q[:, 1].min() > 0.97  # the hip [m]: walking, never falling
        rows = np.rint(impacts.t / h).astype(int) + 1  # the states after the strikes
        z = [_section(log.q[k], log.v[k], 1 - i % 2) for i, k in enumerate(rows)]
        errors.append(np.max(np.abs(np.array(z) - gait.z)))
        time_errors.append(np.max(np.abs(impacts.t - gait.period * np.arange(1, strides + 1))))
    for measured in (errors, time_errors):
        order = np.polyfit(np.log(steps), np.log(measured), 1)[0]
        assert 0.75 <= order <= 1.4, (measured, order)
    assert errors[-1] <= 0.03 * abs(gait.z[0])


@pytest.mark.slow
def test_without_the_scuffing_rule_moreau_jean_catches_the_scuff_and_the_walker_falls() -> None:
    scene = Scene.from_toml(ROBOTS / "compass_walker.toml")
    contacts = tuple(
        dataclasses.replace(c, closes_ahead_of="", direction_of_travel=None, ahead_frame="")
        for c in scene.contacts
    )
    with pytest.warns(PenetrationWarning):  # the fallen walker's foot, 11 mm deep
        log = simulate(dataclasses.replace(scene, contacts=contacts), duration=3.0).log
    # The swing foot closes at the scuff (t = 0.58 s, before the strike at 1.30 s) ...
    assert log.impacts.t[0] < 1.0 and log.impacts.constraint[0] == "foot_b/ground"
    assert log.q[-1, 1] < 0.9  # ... and the hip has fallen [m]


def test_a_bad_scuffing_rule_is_refused(tmp_path: Path) -> None:
    ground = Scene.from_toml(ROBOTS / "compass_walker.toml").contacts[0].surface
    with pytest.raises(InvalidParameterError, match="direction_of_travel"):
        PointContact(frame="foot_a", surface=ground, closes_ahead_of="foot_b")
    with pytest.raises(InvalidParameterError, match=r"direction_of_travel.*non-zero"):
        PointContact(
            frame="foot_a",
            surface=ground,
            closes_ahead_of="foot_b",
            direction_of_travel=(0.0, 0.0, 0.0),
        )
    with pytest.raises(InvalidParameterError, match="closes_ahead_of"):
        PointContact(frame="foot_a", surface=ground, direction_of_travel=(1.0, 0.0, 0.0))
    toml = (ROBOTS / "compass_walker.toml").read_text()
    path = tmp_path / "knee.toml"
    path.write_text(
        toml.replace('closes_ahead_of = "foot_b"', 'closes_ahead_of = "knee"').replace(
            '"compass_walker.urdf"', f'"{ROBOTS / "compass_walker.urdf"}"'
        )
    )
    with pytest.raises(NotFoundError, match=r"closes_ahead_of of 'foot_a/ground' 'knee'"):
        Scene.from_toml(path).constraints  # built on first use


def test_compliant_refuses_a_scuffing_rule() -> None:
    """The compliant integrator does not apply ``closes_ahead_of``: refused, not ignored.

    (It refuses the walker's friction first: the feet are made frictionless here.)
    """
    scene = Scene.from_toml(ROBOTS / "compass_walker.toml")
    contacts = tuple(dataclasses.replace(c, friction=0.0) for c in scene.contacts)
    settings = dataclasses.replace(scene.integrator, name="compliant")
    with pytest.raises(InvalidParameterError, match=r"closes_ahead_of.*foot_a/ground"):
        dataclasses.replace(scene, contacts=contacts, integrator=settings).build_integrator()


def _flow_for(flow: StanceFlow, q: np.ndarray, v: np.ndarray, stance: int, duration: float) -> Any:
    """The state (q, v) flowed ``duration`` [s] on the foot ``stance`` (pinned), shape (8,)."""
    solution = solve_ivp(
        lambda _, y: np.concatenate((y[4:], flow.acceleration(y[:4], y[4:], stance)[0])),
        (0.0, duration),
        np.concatenate((q, v)),
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
    )
    return solution.y[:, -1]


#: Ten strides of the shipped scene, event_driven against the stride map: strike times and
#: states after the strikes (measured: 4.1e-11 s and 1.2e-10, rtol = atol = 1e-12, dt = 0.1 s).
EVENT_DRIVEN_TOLERANCE = 1e-9


def test_event_driven_walks_the_stride_maps_strides() -> None:
    # The shipped scene under event_driven from its start (on its gait): the scuffing rule
    # keeps the swing foot's gap event off until the hip passes the stance foot, so the
    # strikes are those of StanceFlow's strides, to the integration's tolerance.
    scene = Scene.from_toml(ROBOTS / "compass_walker.toml")
    flow = StanceFlow(scene.constraints)
    q, v, t = scene.q0, scene.v0, 0.0
    strides = []
    for _ in range(10):
        stride = flow.stride(q, v)
        t += stride.duration
        strides.append((t, stride))
        q, v = stride.q, stride.v
    h = 0.1  # [s], the sampling period: event_driven's accuracy does not depend on it
    settings = dataclasses.replace(scene.integrator, name="event_driven", rtol=1e-12, atol=1e-12)
    run = dataclasses.replace(scene, integrator=settings)
    log = simulate(run, duration=strides[-1][0] + h, dt=h).log
    impacts = log.impacts
    assert list(impacts.constraint) == ["foot_b/ground", "foot_a/ground"] * 5
    times = np.array([t for t, _ in strides])
    assert np.max(np.abs(impacts.t - times)) <= EVENT_DRIVEN_TOLERANCE
    assert np.max(np.abs(np.diff(impacts.t) - np.diff(times))) <= EVENT_DRIVEN_TOLERANCE
    for t, stride in strides:
        # The first sample after the strike against the strike's state flowed to it.
        k = int(np.searchsorted(log.t, t, side="right"))
        reference = _flow_for(flow, stride.q, stride.v, stride.stance, log.t[k] - t)
        assert np.max(np.abs(np.concatenate((log.q[k], log.v[k])) - reference)) <= (
            EVENT_DRIVEN_TOLERANCE
        )


def test_a_bar_lifting_under_the_slope_is_not_a_strike() -> None:
    # The direction of travel tilted by 0.0115 rad towards the slope normal moves the bar's
    # lifting from mid-stance to the scuff's deepest point (theta = 0.0115, the swing foot
    # 6.3e-5 m under the slope): the foot, let through below its surface, strikes at the
    # later downward crossing of its gap, as the stride map's (a strike at the lifting would
    # come 0.65 s early).
    scene = Scene.from_toml(ROBOTS / "compass_walker.toml")
    tilt = 0.0115  # [rad]
    direction = (math.cos(tilt), 0.0, math.sin(tilt))
    contacts = tuple(dataclasses.replace(c, direction_of_travel=direction) for c in scene.contacts)
    settings = dataclasses.replace(scene.integrator, name="event_driven", rtol=1e-12, atol=1e-12)
    run = dataclasses.replace(scene, contacts=contacts, integrator=settings)
    log = simulate(run, duration=1.3, dt=0.1).log
    assert log.gap[:, 1].min() < -1e-5  # sampled during the scuff, after the lifting
    stride = StanceFlow(scene.constraints).stride(scene.q0, scene.v0)
    assert list(log.impacts.constraint) == ["foot_b/ground"]
    assert abs(log.impacts.t[0] - stride.duration) <= EVENT_DRIVEN_TOLERANCE
    # StanceFlow takes the tilted rule from the scene and finds the same strike.
    tilted = StanceFlow(run.constraints).stride(scene.q0, scene.v0)
    assert abs(tilted.duration - stride.duration) <= EVENT_DRIVEN_TOLERANCE
    assert np.max(np.abs(tilted.v - stride.v)) <= EVENT_DRIVEN_TOLERANCE


def test_stance_flow_takes_the_scenes_scuffing_rule() -> None:
    # A rule measured into the slope (the hip is never "ahead" of the stance foot below it)
    # bars the swing foot for good: no strike at t = 1.238 s, and the walker falls on until
    # its stance foot would slip (t = 1.681 s).
    scene = Scene.from_toml(ROBOTS / "compass_walker.toml")
    into = (0.0, 0.0, -1.0)
    contacts = tuple(dataclasses.replace(c, direction_of_travel=into) for c in scene.contacts)
    barred = dataclasses.replace(scene, contacts=contacts)
    with pytest.raises(
        StrideError, match=r"1\.68\d* s in: the stance foot 'foot_a/ground' would slip"
    ):
        StanceFlow(barred.constraints, max_duration=3.0).stride(scene.q0, scene.v0)
