"""The pronking controller on Solo-12 with Coulomb friction: statics, the laws, the closed loop."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from tests.conftest import load_experiment
from ucontrol.control import ContactState
from ucontrol.control.phase import Phase
from ucontrol.control.pronking_controller import (
    _REGULARIZATION,
    PronkingController,
    PronkSettings,
)
from ucontrol.exceptions import (
    InvalidParameterError,
    NotFoundError,
    SceneError,
    UnknownKeyError,
)
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
G = 9.81  # [m/s²]
SLIP_LIMIT = 5e-3  # [m] per stance (issue 28's acceptance)
FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


def _table(name: str) -> dict:
    return tomllib.loads((ROBOTS / f"{name}.toml").read_text())


def _scene(name: str, **controller: object) -> Scene:
    table = _table(name)
    table["controller"].update(controller)
    return Scene.from_dict(table, base_dir=ROBOTS, default_name=name)


@pytest.fixture(scope="module")
def pronk_scene() -> Scene:
    return Scene.from_toml(ROBOTS / "solo_pronk.toml")


def _with_path(controller: PronkingController, compiled: bool) -> PronkingController:
    """A controller of the same robot, feet and settings as ``controller``, on one path."""
    return PronkingController(
        controller.robot,
        feet=controller.feet,
        contacts=controller._contacts.tolist(),
        normals=controller._normals,
        posture=controller.posture,
        settings=controller.settings,
        compiled=compiled,
    )


def _contacts(scene: Scene, q: np.ndarray, impulse: float = 0.0) -> ContactState:
    names = list(scene.constraints.names)
    n = len(names)
    return ContactState(
        names,
        _gaps(scene, q),
        np.zeros(n),
        np.full(n, impulse),
        np.ones(n, dtype=bool),
        1e-3,
    )


def _gaps(scene: Scene, q: np.ndarray) -> np.ndarray:
    model = scene.robot.model
    data = pin.Data(model)
    pin.framesForwardKinematics(model, data, q)
    return np.array([data.oMf[model.getFrameId(c.frame)].translation[2] for c in scene.contacts])


def _standing(scene: Scene) -> np.ndarray:
    """The scene's q0 lowered so that the feet touch the ground."""
    q = scene.q0.copy()
    q[2] -= float(np.min(_gaps(scene, q)))
    return q


def _statics(controller: PronkingController, scene: Scene, q: np.ndarray, tau: np.ndarray):
    """Residual g(q) - S^T tau - sum J_i^T f_i of the full (18-row) static equation [N, N m]."""
    model = scene.robot.model
    data = pin.Data(model)
    gravity = pin.computeGeneralizedGravity(model, data, q)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    residual = gravity.copy()
    residual[scene.robot.actuated] -= tau
    for name, force in zip(FEET, controller.forces, strict=True):
        J = pin.getFrameJacobian(
            model, data, model.getFrameId(name), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )[:3]
        residual -= J.T @ force
    return residual


@pytest.mark.parametrize("compiled", [False, True])
def test_standing_torques_and_forces_solve_the_full_statics(pronk_scene, compiled):
    """At the standing height, at rest, S^T tau + J^T f = g(q) on all 18 rows.

    g is Pinocchio's generalized gravity: the base rows check the force distribution (the feet
    carry m g and no moment), the joint rows the torques that produce it.
    """
    q = _standing(pronk_scene)
    model = pronk_scene.robot.model
    height = pin.centerOfMass(model, pin.Data(model), q)[2]  # the feet at z = 0 [m]
    scene = _scene("solo_pronk", hops=0, stand_height=float(height))  # no height correction
    controller = _with_path(scene.build_controller(), compiled)
    tau = controller(0.0, q, np.zeros(scene.robot.nv), _contacts(scene, q))
    mass = float(pin.computeTotalMass(scene.robot.model))
    weight = mass * G  # [N]
    assert controller.phase == Phase.CONSTRAINED
    assert controller.forces[:, 2].sum() == pytest.approx(weight, rel=2e-4)
    assert np.max(np.abs(_statics(controller, scene, q, tau))) < 1e-3 * weight


@pytest.mark.parametrize("compiled", [False, True])
def test_commanded_forces_stay_in_the_friction_pyramids(pronk_scene, compiled):
    """A horizontal demand beyond friction is clipped to the pyramids |f_t| <= mu_c f_n."""
    scene = _scene("solo_pronk", hops=0, horizontal_stiffness=2000.0)
    controller = _with_path(scene.build_controller(), compiled)
    q = _standing(scene)
    v = np.zeros(scene.robot.nv)
    controller(0.0, q, v, _contacts(scene, q))  # the centre of mass to hold is this one
    shifted = q.copy()
    shifted[0] += 0.05  # [m]: asks m k_xy 0.05 = 250 N sideways, far beyond mu_c m g
    controller(1e-3, shifted, v, _contacts(scene, shifted))
    mu = controller.settings.friction
    assert mu == pytest.approx(0.8 * 0.7)  # the default margin on the scene's mu
    f = controller.forces
    tangential = np.abs(f[:, :2])
    assert np.all(tangential <= mu * f[:, 2:3] + 1e-6)
    assert np.max(tangential[:, 0] - mu * f[:, 2]) > -1e-4  # some foot at its pyramid's face
    assert f[:, 0].sum() < 0.0  # pushing the centre of mass back


def test_thrust_law_leaves_at_the_takeoff_speed(pronk_scene):
    """The thrust law, integrated from rest at the standing height, leaves at v_to.

    It reaches the touchdown height at v_to, which gives the apex by the ballistic
    h_td + v_to²/(2g).
    """
    controller = pronk_scene.build_controller()
    controller.phase = Phase.TAKEOFF
    h_td, v_to = controller.touchdown_height, controller.takeoff_speed()
    assert h_td + v_to**2 / (2.0 * G) == pytest.approx(controller.settings.apex, rel=1e-12)

    def reach(t, y):
        return y[0] - h_td

    reach.terminal = True
    solution = solve_ivp(
        lambda t, y: [y[1], controller._height_acceleration(y[0], y[1])],
        (0.0, 1.0),
        [controller.settings.stand_height, 0.0],
        events=reach,
        rtol=1e-10,
        atol=1e-12,
    )
    assert solution.t_events[0].size == 1
    assert solution.y_events[0][0][1] == pytest.approx(v_to, rel=1e-6)


def test_phases_come_from_the_gaps_not_the_impulses(pronk_scene):
    """Impulses replaced by NaN change nothing: the controller does not read them."""
    q = _standing(pronk_scene)
    v = np.zeros(pronk_scene.robot.nv)
    v[2] = -0.3  # [m/s] coming down
    with_impulses = pronk_scene.build_controller()
    without = pronk_scene.build_controller()
    for t in (0.0, 1e-3):
        a = with_impulses(t, q, v, _contacts(pronk_scene, q, impulse=0.01))
        b = without(t, q, v, _contacts(pronk_scene, q, impulse=np.nan))
        # to proxsuite's round-off (its results depend on the buffers' alignment)
        np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-9)
    assert with_impulses.phase == without.phase == Phase.CONSTRAINED


def _check_run(name: str, scene: Scene, log, hops: int, max_tilt: float = 2.0) -> None:
    experiment = load_experiment("solo_pronk")
    stances = experiment.stances(scene, log)
    worst = max(stances, key=lambda stance: stance.slip)
    assert worst.slip <= SLIP_LIMIT, f"{name}: {worst}"
    assert len(experiment.flights(log)) == hops
    tilt = experiment.tilt(log)
    assert tilt.max() < np.radians(max_tilt)  # no fall: the base stays near level [rad]
    assert tilt[-1] < np.radians(0.1)
    assert log.q[:, 2].min() > 0.15  # [m] the base never comes down to the ground
    table = scene.controller
    final = log.com_height[-1]
    assert final == pytest.approx(table["stand_height"], abs=2e-3)
    assert np.max(np.abs(log.v[-1])) < 0.05  # at rest again
    mass = float(pin.computeTotalMass(scene.robot.model))
    force = log.impulse[-50:-1].sum(axis=1) / log.metadata["dt"]  # [N]
    assert np.mean(force) == pytest.approx(mass * G, rel=0.02)  # the feet carry the weight


@pytest.mark.slow
def test_solo_lands_from_30_cm_and_stands():
    """Landing from 0.3 m on four feet with friction: no slip beyond 5 mm, no fall, stands."""
    scene = Scene.from_toml(ROBOTS / "solo_landing.toml")
    log = simulate(scene, progress=False).log
    _check_run("solo_landing", scene, log, hops=0)
    touchdown = np.flatnonzero(log.impulse.any(axis=1))[0]
    assert log.t[touchdown] == pytest.approx(np.sqrt(2 * 0.3 / G), abs=2e-3)  # free fall


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::ucontrol.exceptions.EnergyGainWarning")
def test_solo_pronks_ten_times_to_the_commanded_apex(pronk_scene):
    """Ten flights (counted from the plant's contacts), each apex within 2 % of the command."""
    log = simulate(pronk_scene, progress=False).log
    _check_run("solo_pronk", pronk_scene, log, hops=10)
    apexes = load_experiment("solo_pronk").apexes(log)
    assert np.max(np.abs(apexes / pronk_scene.controller["apex"] - 1.0)) < 0.02


@pytest.mark.parametrize(
    ("changes", "error", "match"),
    [
        ({"bounce": 1.0}, UnknownKeyError, "bounce"),
        ({"feet": ["FL_FOOT", "base_link"]}, NotFoundError, "base_link"),
        ({"stand_height": 0.3}, InvalidParameterError, "stand_height"),
        ({"apex": 0.2}, InvalidParameterError, "apex"),
        ({"kp": -1.0}, InvalidParameterError, "kp"),
        ({"hops": -2}, InvalidParameterError, "hops"),
        ({"contact_gap": 0.0}, InvalidParameterError, "contact_gap"),
    ],
)
def test_bad_tables_are_refused(changes, error, match):
    with pytest.raises(error, match=match):
        _scene("solo_pronk", **changes).build_controller()


def test_missing_stand_height_is_refused():
    table = _table("solo_landing")
    del table["controller"]["stand_height"]
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    with pytest.raises(SceneError, match="stand_height"):
        scene.build_controller()


def test_fixed_base_robot_is_refused():
    table = _table("two_link_drop")
    table["controller"] = {"type": "pronk", "stand_height": 0.1}
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    with pytest.raises(InvalidParameterError, match="free-flyer"):
        scene.build_controller()


def test_feet_and_contacts_must_pair_and_hang_below_a_joint(pronk_scene):
    settings = PronkSettings(stand_height=0.199, apex=0.3)
    common = {"normals": np.tile([0.0, 0.0, 1.0], (1, 1)), "posture": pronk_scene.q0}
    with pytest.raises(InvalidParameterError, match="contacts"):
        PronkingController(
            pronk_scene.robot, feet=["FL_FOOT"], contacts=[0, 1], settings=settings, **common
        )
    with pytest.raises(InvalidParameterError, match="base_link"):
        PronkingController(
            pronk_scene.robot, feet=["base_link"], contacts=[0], settings=settings, **common
        )


@pytest.mark.parametrize("compiled", [False, True])
def test_feasible_optimum_is_proxsuites_solution(pronk_scene, compiled):
    """Inside the pyramids the closed-form optimum equals proxsuite's solution of the QP."""
    controller = _with_path(pronk_scene.build_controller(), compiled)
    q = _standing(pronk_scene)
    v = np.zeros(pronk_scene.robot.nv)
    v[:3] = [0.1, -0.05, -0.2]  # [m/s]: a sideways, backward and downward demand
    controller(0.0, q, v, _contacts(pronk_scene, q))
    closed_form = controller.forces.copy()
    A = controller._A  # of this call's feet and centre of mass
    f = closed_form.ravel()
    # the wrench it was computed for: f = A^T y with (A A^T + eps I) y = w
    wrench = A @ f + _REGULARIZATION * np.linalg.pinv(A.T) @ f
    H = A.T @ A + _REGULARIZATION * np.eye(12)
    box = np.full(12, 1e20)
    x = controller._qp.solve(
        H, -A.T @ wrench, controller._C, controller._lower, controller._upper, -box, box
    ).x
    assert np.max(np.abs(closed_form[:, :2])) > 0.1  # [N] a demand with tangential forces
    np.testing.assert_allclose(x.reshape(4, 3), closed_form, rtol=0.0, atol=1e-6)


def test_leg_joint_with_several_coordinates_is_refused():
    """A spherical hip (nq = 4, nv = 3) has no joint-space posture error of the PD's form."""
    model = pin.Model()
    base = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base")
    model.appendBodyToJoint(base, pin.Inertia.FromBox(1.0, 0.2, 0.2, 0.1), pin.SE3.Identity())
    hip = model.addJoint(base, pin.JointModelSpherical(), pin.SE3.Identity(), "hip")
    model.appendBodyToJoint(hip, pin.Inertia.FromSphere(0.1, 0.02), pin.SE3.Identity())
    placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.2]))
    model.addFrame(pin.Frame("foot", hip, 0, placement, pin.FrameType.OP_FRAME))
    robot = RobotModel(model)
    with pytest.raises(InvalidParameterError, match="one configuration coordinate"):
        PronkingController(
            robot,
            feet=["foot"],
            contacts=[0],
            normals=np.array([[0.0, 0.0, 1.0]]),
            posture=pin.neutral(model),
            settings=PronkSettings(stand_height=0.1, apex=0.3),
        )


@pytest.mark.slow
def test_solo_lands_with_a_sideways_speed_and_a_tumble():
    """Dropped moving at 0.3 m/s and turning at 0.5 rad/s about x and y: it stands level.

    It turns by about 10 degrees in the fall, lands, holds its feet (slip <= 5 mm per stance)
    and stands level.
    """
    table = _table("solo_landing")
    table["robot"]["v0"][:6] = [0.3, 0.0, 0.0, 0.5, 0.5, 0.0]  # [m/s], [rad/s] (base frame)
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    log = simulate(scene, progress=False).log
    _check_run("solo_landing", scene, log, hops=0, max_tilt=15.0)


@pytest.mark.slow
def test_experiment_runs_briefly(tmp_path: Path) -> None:
    """experiments/solo_pronk.py's table and figure, on 0.4 s of each scene."""
    experiment = load_experiment("solo_pronk")
    experiment.main(["--duration", "0.4", "--out", str(tmp_path)])
    rows = (tmp_path / "solo_pronk.md").read_text().splitlines()
    assert [row.split("|")[1].strip() for row in rows[2:4]] == ["solo_landing", "solo_pronk"]
    speed = [row.split("|") for row in rows[9:]]  # the CPU time per step
    assert [row[1].strip() for row in speed] == ["solo_landing", "solo_pronk", experiment.STAND]
    for row in speed:  # step = controller's part + rest [µs]
        step, controller, rest = (float(cell) for cell in row[3:6])
        assert step == pytest.approx(controller + rest, abs=0.2)
        assert 0.0 < controller < step
    assert (tmp_path / "solo_pronk.png").stat().st_size > 10_000


#: Largest difference accepted between the compiled law and the numpy reference [N m], [N]:
#: the same arithmetic in another order (measured: 2e-12 over the 5 s of solo_pronk.toml).
_PATH_TOLERANCE = 1e-9


class _BothPaths:
    """Runs the compiled law (on the plant's data where the loop shares it) and the reference.

    Records the largest difference of their torques and forces, and whether their phases, hop
    counts and heights agreed, at every call; the loop is driven by the compiled law.
    """

    def __init__(self, controller: PronkingController) -> None:
        self.fast = _with_path(controller, True)
        self.reference = _with_path(controller, False)
        self.robot = controller.robot
        self.largest = 0.0
        self.agreed = True
        self.shared = False
        self.calls = 0

    def use_plant_data(self, data) -> bool:
        used = self.fast.use_plant_data(data)
        self.shared |= used  # (given back at the end of the run)
        return used

    def __call__(self, t, q, v, contacts):
        fast = self.fast(t, q, v, contacts)
        reference = self.reference(t, q, v, contacts)
        forces = np.abs(self.fast.forces - self.reference.forces).max()
        self.largest = max(self.largest, float(np.abs(fast - reference).max()), float(forces))
        self.agreed &= (self.fast.phase, self.fast.hops_done) == (
            self.reference.phase,
            self.reference.hops_done,
        )
        self.agreed &= abs(self.fast._height - self.reference._height) < 1e-12
        self.calls += 1
        return fast


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::ucontrol.exceptions.EnergyGainWarning")
def test_compiled_law_is_the_reference_law_in_closed_loop(pronk_scene):
    """On the pronking loop (stance, thrust, flights, touchdowns) both paths give one torque.

    The compiled law reads the plant's evaluation (``use_plant_data``), the reference runs
    its own Pinocchio passes: the gravity, momentum and centroidal inertia of two routes.
    """
    both = _BothPaths(pronk_scene.build_controller())
    assert both.fast.compiled and not both.reference.compiled
    simulate(pronk_scene, both, duration=1.5, progress=False)
    assert both.shared  # the loop gave the plant's data to the compiled law
    assert both.fast.hops_done >= 2  # thrusts, flights and touchdowns were met
    assert both.agreed
    assert both.largest < _PATH_TOLERANCE, both.largest


@pytest.mark.parametrize("seed", range(3))
def test_compiled_law_is_the_reference_law_on_random_states(pronk_scene, seed):
    """Random configurations, velocities and contacts: the same heights, wrench and forces.

    The states stand the robot near its posture, tilted by up to ~10 degrees and moving at up
    to ~1 m/s, with each foot in or out of contact: the closed-form optimum where it lies in
    the pyramids (both paths), the same QP data (A, wrench) where it does not.
    """
    rng = np.random.default_rng(seed)
    fast = _with_path(pronk_scene.build_controller(), True)
    reference = _with_path(pronk_scene.build_controller(), False)
    names, compared = list(pronk_scene.constraints.names), 0
    for k in range(40):
        q = _standing(pronk_scene)
        q[7:] += rng.normal(scale=0.05, size=12)  # [rad]
        q[:3] += rng.normal(scale=0.01, size=3)  # [m]
        quaternion = np.array([0.0, 0.0, 0.0, 1.0]) + rng.normal(scale=0.05, size=4)
        q[3:7] = quaternion / np.linalg.norm(quaternion)
        v = rng.normal(scale=0.3, size=pronk_scene.robot.nv)
        gap = np.where(rng.random(4) < 0.7, 0.0, 0.01)  # [m]
        contacts = ContactState(names, gap, np.zeros(4), np.zeros(4), np.ones(4, bool), 1e-3)
        tau_fast = fast(1e-3 * k, q, v, contacts)
        tau_reference = reference(1e-3 * k, q, v, contacts)
        assert fast.phase == reference.phase
        assert fast._height == pytest.approx(reference._height, abs=1e-14)
        stance = reference.phase != Phase.FREE and bool((gap <= 0.0).any())
        if stance:  # the wrench matrix of this call's feet and centre of mass
            np.testing.assert_allclose(fast._A, reference._A, rtol=0.0, atol=1e-14)
        if stance and fast._feasible_out[0] < 0.5:
            continue  # proxsuite's solution, to its tolerance, from each QP's warm start
        compared += 1
        np.testing.assert_allclose(tau_fast, tau_reference, rtol=0.0, atol=_PATH_TOLERANCE)
        np.testing.assert_allclose(fast.forces, reference.forces, rtol=0.0, atol=_PATH_TOLERANCE)
    assert compared > 20


def test_experiment_replays_each_controller():
    """experiments/solo_pronk.py --replay: every mode replays the same recorded calls."""
    experiment = load_experiment("solo_pronk")
    calls = {mode: experiment.replay(mode, duration=0.05) for mode in experiment.REPLAY_MODES}
    assert calls == {"none": 0, "reference": 50, "compiled-own": 50, "compiled": 50}
