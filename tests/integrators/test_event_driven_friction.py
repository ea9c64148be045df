"""Sustained Coulomb friction in event_driven: sliding and sticking phases between impacts.

References: the closed forms of a point mass on a rough incline (sliding down, sliding up then
stopping and sticking or sliding back) and on a rough floor (stopping at v0 / (μ g)), the
friction work they give, a frictionless mode problem against the LCP solver, and Painlevé's
inconsistency built by hand.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from numpy.typing import NDArray

from ucontrol.exceptions import IntegrationError, PainleveError
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.integrators.friction_modes import MAX_MODES, friction_modes
from ucontrol.scene import Scene, builtin_scene
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

Vector = NDArray[np.float64]
_G = 9.81  # [m/s²]
_MASS = 2.0  # [kg]
_URDF = f"""<?xml version="1.0"?>
<robot name="point_mass">
  <link name="world"/>
  <link name="carriage">
    <inertial><mass value="0.0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>
    </inertial>
  </link>
  <joint name="x" type="prismatic">
    <parent link="world"/><child link="carriage"/><axis xyz="1 0 0"/>
    <limit lower="-100" upper="100" effort="100" velocity="100"/>
  </joint>
  <link name="body">
    <inertial><mass value="{_MASS}"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="z" type="prismatic">
    <parent link="carriage"/><child link="body"/><axis xyz="0 0 1"/>
    <limit lower="-100" upper="100" effort="100" velocity="100"/>
  </joint>
</robot>
"""


@pytest.fixture(scope="module")
def robots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("point_mass")
    (directory / "point_mass.urdf").write_text(_URDF)
    return directory


def _incline(robots: Path, alpha: float, mu: float, speed: float, planar: bool = True) -> Scene:
    """A 2 kg point mass on an incline of angle ``alpha`` [rad], down-slope speed ``speed``."""
    table = {
        "name": "rough_incline",
        "robot": {
            "urdf": "point_mass.urdf",
            "q0": [0.0, 0.0],
            "v0": [speed * math.cos(alpha), -speed * math.sin(alpha)],
            "gravity": [0.0, 0.0, -_G],
            **({"planar_axis": [0.0, 1.0, 0.0]} if planar else {}),
        },
        "surfaces": {
            "slope": {
                "type": "plane",
                "point": [0.0, 0.0, 0.0],
                "normal": [math.sin(alpha), 0.0, math.cos(alpha)],
            }
        },
        "contacts": [{"frame": "body", "surface": "slope", "friction": mu}],
        "integrator": {"name": "event_driven", "dt": 0.01},
    }
    return Scene.from_dict(table, base_dir=robots)


def _run(scene: Scene, duration: float) -> tuple[Vector, Vector, Vector, EventDriven]:
    """Times, slope positions and speeds (down-slope, [m] and [m/s]) and the integrator."""
    integrator = scene.build_integrator()
    assert isinstance(integrator, EventDriven)
    q, v, t = scene.q0, scene.v0, 0.0
    times, states = [t], [np.concatenate((q, v))]
    for _ in range(round(duration / integrator.dt)):
        outcome = integrator.step(integrator.evaluate(q, v, t), np.zeros(2))
        q, v, t = outcome.q, outcome.v, t + integrator.dt
        times.append(t)
        states.append(np.concatenate((q, v)))
    columns = np.array(states).T  # (4, N): x, z, ẋ, ż
    return np.array(times), columns[:2], columns[2:], integrator


def _slope(values: Vector, alpha: float) -> Vector:
    """Down-slope component of (x, z) rows, shape (2, N) -> (N,)."""
    return values[0] * math.cos(alpha) - values[1] * math.sin(alpha)


def _closed_form(t: float, alpha: float, mu: float, speed: float) -> tuple[float, float]:
    """Down-slope position [m] and speed [m/s] of the point mass at t [s] (Coulomb's law)."""
    down = _G * (math.sin(alpha) - mu * math.cos(alpha))  # sliding down [m/s²]
    up = _G * (math.sin(alpha) + mu * math.cos(alpha))  # sliding up (speed < 0)
    if speed == 0.0:
        return (0.5 * down * t**2, down * t) if down > 0.0 else (0.0, 0.0)
    braking = up if speed < 0.0 else down
    stop = -speed / braking  # [s]
    if braking * speed > 0.0 or t <= stop:  # accelerating down, or before the stop
        return speed * t + 0.5 * braking * t**2, speed + braking * t
    travel = speed * stop + 0.5 * braking * stop**2
    if down <= 0.0:  # tan α <= μ: it sticks
        return travel, 0.0
    return travel + 0.5 * down * (t - stop) ** 2, down * (t - stop)


@pytest.mark.parametrize(
    ("alpha", "mu", "speed"),
    [
        (0.5, 0.3, 0.0),  # tan α = 0.546 > μ: slides down from rest
        (0.2, 0.3, 0.0),  # tan α = 0.203 < μ: sticks from rest
        (0.5, 0.3, -3.0),  # slides up, stops, slides back down (slip reversal)
        (0.2, 0.3, -3.0),  # slides up, stops and sticks
        (0.0, 0.4, 2.0),  # a floor: stops at v0 / (μ g) = 0.510 s, then sticks
    ],
)
def test_point_mass_on_a_rough_incline_follows_coulombs_closed_form(
    robots: Path, alpha: float, mu: float, speed: float
) -> None:
    """Position and speed at every sample, and the friction work, against the closed form.

    Measured to 5e-15 m and m/s; the friction work -μ m g cos α × (path length) to 1e-12.
    """
    times, q, v, integrator = _run(_incline(robots, alpha, mu, speed), 1.0)
    expected = np.array([_closed_form(t, alpha, mu, speed) for t in times])
    np.testing.assert_allclose(_slope(q, alpha), expected[:, 0], rtol=0.0, atol=1e-10)
    np.testing.assert_allclose(_slope(v, alpha), expected[:, 1], rtol=0.0, atol=1e-10)
    np.testing.assert_allclose(q[0] * math.sin(alpha) + q[1] * math.cos(alpha), 0.0, atol=1e-12)
    fine = np.linspace(0.0, 1.0, 100_001)
    speeds = np.array([_closed_form(t, alpha, mu, speed)[1] for t in fine])
    path = float(np.sum(np.abs(speeds[1:] + speeds[:-1])) * 0.5 * (fine[1] - fine[0]))  # [m]
    work = -mu * _MASS * _G * math.cos(alpha) * path  # [J]
    assert integrator.ledger.friction_work == pytest.approx(work, rel=1e-6, abs=1e-12)
    assert integrator.ledger.impact_loss == 0.0


def test_sliding_stops_at_v0_over_mu_g(robots: Path) -> None:
    """The stop is located as an event: the step holding it ends at rest, the one before not."""
    mu, speed = 0.4, 2.0
    times, _, v, _ = _run(_incline(robots, 0.0, mu, speed), 1.0)
    stop = speed / (mu * _G)  # 0.5097 s
    moving = np.abs(v[0]) > 0.0
    assert times[moving].max() < stop <= times[~moving].min()
    assert np.all(v[0][~moving] == 0.0)


def test_spatial_sustained_friction_is_refused(robots: Path) -> None:
    scene = _incline(robots, 0.2, 0.3, 0.0, planar=False)
    integrator = scene.build_integrator()
    with pytest.raises(IntegrationError, match=r"3D friction \(two\s+tangents\)"):
        integrator.step(integrator.evaluate(scene.q0, scene.v0, 0.0), np.zeros(2))


def test_frictionless_modes_solve_the_lcp() -> None:
    """Without tangential rows the enumeration is the LCP 0 <= λ ⟂ W λ + b >= 0."""
    rng = np.random.default_rng(3)
    solver = ProxsuiteLCPSolver()
    for _ in range(20):
        A = rng.normal(size=(4, 4))
        W = A @ A.T + 0.1 * np.eye(4)
        b = rng.normal(size=4)
        found = friction_modes(
            W,
            b,
            np.zeros(0),
            np.zeros(0, dtype=np.intp),
            np.zeros((0, 3), dtype=bool),
            np.zeros(0, dtype=bool),
            value_tolerance=1e-12,
        )
        reference = solver.solve(W, b)
        np.testing.assert_allclose(found.lambda_n, reference.impulses, atol=1e-7)


def test_modes_obey_coulombs_law() -> None:
    """One frictional contact at rest: the mode found satisfies its complementarity."""
    rng = np.random.default_rng(5)
    sticks = slips = 0
    for _ in range(200):
        A = rng.normal(size=(2, 2))
        W = A @ A.T + 0.1 * np.eye(2)
        b = rng.normal(size=2)
        mu = rng.uniform(0.05, 0.5)  # small μ: no Painlevé case (W_nn - μ |W_nt| > 0 not required)
        try:
            found = friction_modes(
                W,
                b,
                np.array([mu]),
                np.array([0]),
                np.ones((1, 3), dtype=bool),
                np.zeros(1, dtype=bool),
                value_tolerance=1e-12,
            )
        except PainleveError:
            assert W[0, 0] < mu * abs(W[0, 1])  # only where the slip mode turns W_nn negative
            continue
        y = W @ np.concatenate((found.lambda_n, found.lambda_t)) + b
        lam_n, lam_t = found.lambda_n[0], found.lambda_t[0]
        assert lam_n >= -1e-12 and y[0] >= -1e-12 and abs(lam_n * y[0]) <= 1e-10
        if found.stick[0]:
            sticks += 1
            assert abs(y[1]) <= 1e-10 and abs(lam_t) <= mu * lam_n + 1e-12
        elif found.closed[0]:
            slips += 1
            assert lam_t == pytest.approx(-mu * found.sign[0] * lam_n, abs=1e-12)
            assert found.sign[0] * y[1] >= -1e-12
    assert sticks > 10 and slips > 10


def test_painleve_inconsistency_and_too_many_modes_raise() -> None:
    """Sliding with μ W_nt > W_nn under a pull into the surface: no mode is consistent."""
    W = np.array([[1.0, 2.0], [2.0, 5.0]])
    with pytest.raises(PainleveError, match="Painlevé"):
        friction_modes(
            W,
            np.array([-1.0, 0.0]),
            np.array([1.0]),
            np.array([0]),
            np.array([[False, True, False]]),
            np.array([True]),
            value_tolerance=1e-12,
        )
    size = int(math.log2(MAX_MODES)) + 1
    with pytest.raises(PainleveError, match="contact modes to enumerate"):
        friction_modes(
            np.eye(size),
            np.ones(size),
            np.zeros(0),
            np.zeros(0, dtype=np.intp),
            np.zeros((0, 3), dtype=bool),
            np.zeros(0, dtype=bool),
            value_tolerance=1e-12,
        )


def test_tangent_drift_of_a_rolling_point_contact_against_finite_differences() -> None:
    """J̇_t v of a sphere's contact point (lever r t × n) on a rod: central differences."""
    table = {
        "name": "rod_sphere",
        "robot": {
            "urdf": "rod.urdf",
            "q0": [0.1, 0.6, 0.4],
            "v0": [0.3, -0.7, 2.0],
            "planar_axis": [0.0, 1.0, 0.0],
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0.2, 0, 1]}},
        "contacts": [{"frame": "rod_end", "surface": "ground", "friction": 0.5, "radius": 0.05}],
    }
    scene = Scene.from_dict(table, base_dir=builtin_scene().parent)
    model, constraints = scene.robot.model, scene.constraints
    q, v = scene.q0, scene.v0
    data = pin.Data(model)
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    assert constraints.sustains_friction(0)
    drift = constraints.tangent_drift(data, [0], v)[0]

    def row(q_: Vector) -> Vector:
        data_ = pin.Data(model)
        pin.computeJointJacobians(model, data_, q_)
        pin.updateFramePlacements(model, data_)
        return constraints.tangent_rows(data_, [0])[0][0]

    finite = row(pin.integrate(model, q, 1e-7 * v)) - row(pin.integrate(model, q, -1e-7 * v))
    assert abs(drift) > 0.1
    np.testing.assert_allclose(drift, finite @ v / 2e-7, rtol=1e-6)


def test_pushed_block_actuator_and_friction_work_close_the_balance(robots: Path) -> None:
    """A 10 N push along a rough floor: ∫ τ·v dt = F s, ∫ λ_t u_t dt = -μ m g s, ΔT their sum."""
    scene = _incline(robots, 0.0, 0.3, 0.0)
    integrator = scene.build_integrator()
    assert isinstance(integrator, EventDriven)
    push = np.array([10.0, 0.0])  # [N]
    q, v, t = scene.q0, scene.v0, 0.0
    for _ in range(50):  # 0.5 s
        outcome = integrator.step(integrator.evaluate(q, v, t), push)
        q, v, t = outcome.q, outcome.v, t + integrator.dt
    acceleration = push[0] / _MASS - 0.3 * _G  # [m/s²]
    distance = 0.5 * acceleration * t**2  # [m]
    ledger = integrator.ledger
    assert q[0] == pytest.approx(distance, rel=1e-12)
    assert ledger.actuator_work == pytest.approx(push[0] * distance, rel=1e-10)
    assert ledger.friction_work == pytest.approx(-0.3 * _MASS * _G * distance, rel=1e-10)
    kinetic = 0.5 * _MASS * float(v @ v)
    assert kinetic == pytest.approx(ledger.balance, rel=1e-10)
