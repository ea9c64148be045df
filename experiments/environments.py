"""Measured figures of the environments page (docs/environments.md).

- four-bar (``robots/four_bar.toml``, Moreau–Jean): largest closure residual and energy error
  over ``--duration`` seconds at h = 1e-3 and 1e-4;
- ball on a vibrating table (``robots/ball_vibrating_table.toml``): impact times and leaving
  velocities against the period-1 orbit, and Newton's law on the relative velocity;
- box from a URDF ``<collision>`` box dropped flat (``robots/box_drop_collision.toml``): tilt
  and corner impulses at rest;
- broad phase: cost of evaluating a scene with 50 declared shape pairs of which 2 are near,
  against the same scene with the 2 near pairs only (a benchmark, not a test);
- event-driven: the four-bar's closure residual and energy error over ``--ed-duration``
  seconds, Newton's law at a crank stop through the kinetic energy of the one-degree-of-freedom
  chain, and the ball on the vibrating table against its period-1 orbit (impact phase and
  take-off velocity reconstructed from the ballistic flights between samples).

Usage::

    python experiments/environments.py --duration 10
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import scipy.optimize

from ucontrol.analysis.poincare import vibrating_table_period_one
from ucontrol.contact import CollisionPair, ConstraintSet, EnvironmentShape
from ucontrol.contact.surface_motion import Sinusoid
from ucontrol.model import RobotModel
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def four_bar(duration: float) -> None:
    """Closure residual and energy error of the four-bar over ``duration`` [s]."""
    for h in (1e-3, 1e-4):
        scene = Scene.from_toml(ROBOTS / "four_bar.toml")
        log = simulate(scene, duration=duration, dt=h, out=None, progress=False).log
        bilateral = scene.constraints.bilateral
        assert bilateral is not None
        q = np.asarray(log.q)
        residual = max(np.max(np.abs(bilateral.residuals(row))) for row in q)
        energy = np.asarray(log.energy)
        print(
            f"four-bar h = {h:g} s, {duration:g} s: max closure residual {residual:.2e} m, "
            f"max |E - E0| {np.max(np.abs(energy - energy[0])):.2e} J (E0 = {energy[0]:.3f} J)"
        )


def vibrating_table(duration: float) -> None:
    """Impacts of the ball on the vibrating table against its period-1 orbit."""
    base = Scene.from_toml(ROBOTS / "ball_vibrating_table.toml")
    motion = base.contacts[0].surface.motion
    period = 2 * np.pi / motion.frequency  # type: ignore[union-attr]
    leave = 9.81 * period / 2  # [m/s]
    e = base.contacts[0].restitution
    for h in (1e-3, 1e-4):
        log = simulate(base, duration=duration, dt=h, out=None, progress=False).log
        impulse = np.asarray(log.impulse)[:, 0]
        t, v = np.asarray(log.t), np.asarray(log.v)[:, 0]
        u = np.asarray(log.normal_velocity)[:, 0]
        impacts = np.flatnonzero(impulse > 0.0)
        impacts = impacts[impacts + 1 < t.size]
        n = np.round(t[impacts] / period)
        newton = np.max(np.abs(u[impacts + 1] + e * u[impacts]) / np.abs(u[impacts]))
        print(
            f"vibrating table h = {h:g} s: {impacts.size} impacts, max |t_k - nT| "
            f"{np.max(np.abs(t[impacts] - n * period)):.2e} s, max |v+ - gT/2| "
            f"{np.max(np.abs(v[impacts + 1] - leave)):.2e} m/s, Newton's law on the relative "
            f"velocity to {newton:.1e} (relative)"
        )


def box_drop() -> None:
    """Tilt and corner impulses of the collision box dropped flat."""
    scene = Scene.from_toml(ROBOTS / "box_drop_collision.toml")
    log = simulate(scene, dt=1e-3, out=None, progress=False).log
    q = np.asarray(log.q)
    tilt = 2.0 * np.arcsin(np.linalg.norm(q[:, 3:6], axis=1))
    impulse = np.asarray(log.impulse).sum(axis=1)[-100:-1]
    print(
        f"box drop: max tilt {tilt.max():.1e} rad, corner impulses at rest / (m g h) - 1 in "
        f"[{impulse.min() / 9.81e-3 - 1:.1e}, {impulse.max() / 9.81e-3 - 1:.1e}]"
    )


def broad_phase(repeats: int) -> None:
    """Evaluation cost of 50 pairs with 2 near against the 2 near pairs alone."""
    robot = RobotModel.from_urdf(ROBOTS / "box_collision.urdf", floating_base=True)
    near = [
        CollisionPair(
            link="box",
            other=EnvironmentShape(
                name=f"near{k}", type="sphere", position=[0.3 * k - 0.15, 0.0, -0.1], radius=0.04
            ),
        )
        for k in range(2)
    ]
    far = [
        CollisionPair(
            link="box",
            other=EnvironmentShape(
                name=f"far{k}", type="box", position=[2.0 + 0.5 * k, 3.0, 1.0], size=[0.2, 0.2, 0.2]
            ),
        )
        for k in range(48)
    ]
    q = pin.neutral(robot.model)
    v = np.zeros(robot.nv)
    costs = []
    for pairs in (near, near + far):
        constraints = ConstraintSet(robot, collision_pairs=pairs)
        data = pin.Data(robot.model)
        pin.computeAllTerms(robot.model, data, q, v)
        pin.updateFramePlacements(robot.model, data)
        constraints.evaluate(data, q, v)
        start = time.perf_counter()
        for _ in range(repeats):
            constraints.evaluate(data, q, v)
        costs.append((time.perf_counter() - start) / repeats * 1e6)
    print(
        f"broad phase: evaluate 2 pairs {costs[0]:.1f} us, 50 pairs (2 near) {costs[1]:.1f} us, "
        f"ratio {costs[1] / costs[0]:.2f}"
    )


def _event_driven(scene: Scene, dt: float) -> Scene:
    integrator = dataclasses.replace(scene.integrator, name="event_driven", dt=dt)
    return dataclasses.replace(scene, integrator=integrator)


def four_bar_event_driven(duration: float) -> None:
    """Closure residual, energy error and stop impacts of the four-bar, event-driven."""
    scene = _event_driven(Scene.from_toml(ROBOTS / "four_bar.toml"), 1e-2)
    start = time.perf_counter()
    log = simulate(scene, duration=duration, out=None, progress=False).log
    elapsed = time.perf_counter() - start
    bilateral = scene.constraints.bilateral
    assert bilateral is not None
    q, energy = np.asarray(log.q), np.asarray(log.energy)
    residual = max(np.max(np.abs(bilateral.residuals(row))) for row in q)
    print(
        f"four-bar event-driven (rtol 1e-10), {duration:g} s: max closure residual "
        f"{residual:.1e} m, max |E - E0| {np.max(np.abs(energy - energy[0])):.1e} J "
        f"(E0 = {energy[0]:.3f} J), {elapsed:.1f} s wall"
    )
    e, stop = 0.6, 0.2  # restitution, crank angle of the stop [rad]
    scene = Scene.from_toml(ROBOTS / "four_bar_stop.toml")  # the stop at 0.2 rad, e = 0.6
    log = simulate(scene, out=None, progress=False).log
    bilateral = scene.constraints.bilateral
    assert bilateral is not None
    energy, impulse = np.asarray(log.energy), np.asarray(log.impulse)[:, 0]
    model = scene.robot.model
    data = pin.Data(model)
    q_stop = scene.q0.copy()
    q_stop[0] = stop
    for _ in range(20):  # the assembly at the stop: Gauss-Newton on the closure, crank fixed
        pin.framesForwardKinematics(model, data, q_stop)
        pin.computeJointJacobians(model, data, q_stop)
        J = bilateral.jacobian(data)[:, 1:]
        q_stop[1:] -= np.linalg.lstsq(J, bilateral.residual(data, q_stop), rcond=None)[0]
    pin.computeAllTerms(model, data, q_stop, np.zeros(3))
    at_stop = data.potential_energy  # [J]
    impacts = np.flatnonzero(impulse[:-1] > 0.0)
    errors = [
        abs((energy[k + 1] - at_stop) - e * e * (energy[k] - at_stop)) / (energy[k] - at_stop)
        for k in impacts
    ]
    residual = max(np.max(np.abs(bilateral.residuals(row))) for row in np.asarray(log.q))
    print(
        f"four-bar on a crank stop (e = {e}), event-driven: {impacts.size} impacts, "
        f"|T+ - e^2 T-| / T- at most {max(errors):.1e}, closure residual {residual:.1e} m"
    )


def vibrating_table_event_driven(duration: float) -> None:
    """Impacts of the ball on the vibrating table, event-driven, against the period-1 orbit."""
    base = Scene.from_toml(ROBOTS / "ball_vibrating_table.toml")
    contact = base.contacts[0]
    motion, e, g, radius = contact.surface.motion, contact.restitution, 9.81, contact.radius
    assert isinstance(motion, Sinusoid)
    phase_star, leave = vibrating_table_period_one(
        amplitude=motion.amplitude[2], frequency=motion.frequency, restitution=e, gravity=g
    )
    dt = 0.0071  # [s], sampling only: no sample within 1e-4 s of an impact nT (n < 71)
    for label, dq, dv in (("on the orbit", 0.0, 0.0), ("2 mm, -0.1 m/s off", 2e-3, -0.1)):
        scene = dataclasses.replace(_event_driven(base, dt), q0=base.q0 + dq, v0=base.v0 + dv)
        log = simulate(scene, duration=duration, out=None, progress=False).log
        t, z = np.asarray(log.t), np.asarray(log.q)[:, 0]
        v, impulse = np.asarray(log.v)[:, 0], np.asarray(log.impulse)[:, 0]
        rows = []
        for k in np.flatnonzero(impulse[:-1] > 0.0):

            def gap(s: float, k: int = k) -> float:
                tau = s - t[k]
                return z[k] + v[k] * tau - 0.5 * g * tau * tau - radius - motion(s)[0][2]

            t_i = scipy.optimize.brentq(gap, t[k], t[k + 1], xtol=1e-15, rtol=1e-15)
            plate = motion(t_i)[1][2]
            before = v[k] - g * (t_i - t[k]) - plate
            after = v[k + 1] + g * (t[k + 1] - t_i)
            phase = (motion.frequency * t_i + motion.phase) % (2 * np.pi)
            newton = abs(after - plate + e * before) / abs(before)
            rows.append((abs(phase - phase_star), abs(after - leave), newton))
        errors = np.array(rows)
        print(
            f"vibrating table event-driven, {label}, {duration:g} s: {len(rows)} impacts; last "
            f"five: |phase - phase*| {errors[-5:, 0].max():.1e} rad, |v+ - gT/2| "
            f"{errors[-5:, 1].max():.1e} m/s; Newton's law on the relative velocity to "
            f"{errors[:, 2].max():.1e} (relative)"
        )


def main() -> None:
    """Print every measured figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0, help="four-bar run [s]")
    parser.add_argument("--table-duration", type=float, default=2.0, help="table run [s]")
    parser.add_argument("--repeats", type=int, default=2000, help="broad-phase timing loops")
    parser.add_argument(
        "--ed-duration", type=float, default=5.0, help="event-driven four-bar run [s]"
    )
    parser.add_argument(
        "--ed-table-duration", type=float, default=8.0, help="event-driven table run [s]"
    )
    args = parser.parse_args()
    box_drop()
    broad_phase(args.repeats)
    vibrating_table(args.table_duration)
    four_bar(args.duration)
    four_bar_event_driven(args.ed_duration)
    vibrating_table_event_driven(args.ed_table_duration)


if __name__ == "__main__":
    main()
