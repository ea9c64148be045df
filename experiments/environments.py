"""Measured figures of the environments page (docs/environments.md).

- four-bar (``robots/four_bar.toml``, Moreau–Jean): largest closure residual and energy error
  over ``--duration`` seconds at h = 1e-3 and 1e-4;
- ball on a vibrating table (``robots/ball_vibrating_table.toml``): impact times and leaving
  velocities against the period-1 orbit, and Newton's law on the relative velocity;
- box from a URDF ``<collision>`` box dropped flat (``robots/box_drop_collision.toml``): tilt
  and corner impulses at rest;
- broad phase: cost of evaluating a scene with 50 declared shape pairs of which 2 are near,
  against the same scene with the 2 near pairs only (a benchmark, not a test).

Usage::

    python experiments/environments.py --duration 10
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from ucontrol.contact import CollisionPair, ConstraintSet, EnvironmentShape
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
        data = robot.model.createData()
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


def main() -> None:
    """Print every measured figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0, help="four-bar run [s]")
    parser.add_argument("--table-duration", type=float, default=2.0, help="table run [s]")
    parser.add_argument("--repeats", type=int, default=2000, help="broad-phase timing loops")
    args = parser.parse_args()
    box_drop()
    broad_phase(args.repeats)
    vibrating_table(args.table_duration)
    four_bar(args.duration)


if __name__ == "__main__":
    main()
