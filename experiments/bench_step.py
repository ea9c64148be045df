r"""Cost of one Moreau–Jean step: ucontrol against Pinocchio's own ADMM and PGS loops.

The Franka Panda (example-robot-data, nq = nv = 9 with the fingers) presses its hand on a
horizontal frictionless table with a constant torque: gravity compensation plus a downward force
at the tool centre point. One contact (``panda_hand_tcp``) or four (also ``panda_leftfinger``,
``panda_rightfinger``, ``panda_link7``) are point contacts whose radii make every gap zero at the
start; the four are redundant (the Delassus matrix is singular). Three loops advance the same
state with the same dt, dynamics and active-set rule:

- ``ucontrol``: ``MoreauJean.evaluate`` then ``MoreauJean.step`` (proxsuite, warm-started);
- ``pin ADMM`` / ``pin PGS``: :class:`ucontrol.solvers.PinocchioStepper`, a Python loop written
  as a Pinocchio user would (``aba``, ``crba``, ``PointContactConstraintModel``,
  ``ConstraintCholeskyDecomposition``, ``ADMMConstraintSolver`` / ``PGSConstraintSolver``,
  ``aba``, ``integrate``).

Times are wall-clock µs per step (``time.perf_counter``), best of ``--repeats`` runs of
``--steps`` steps after a warm-up. A second, untimed run checks that the three loops compute the
same trajectory (max velocity difference).

Run: ``python experiments/bench_step.py --steps 2000 --repeats 7``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ucontrol.contact import ConstraintSet, Plane, PointContact
from ucontrol.integrators import MoreauJean
from ucontrol.model import RobotModel, example_robot_data_dir
from ucontrol.solvers import PinocchioStepper

PANDA_URDF = "panda_description/urdf/panda.urdf"
#: Hand pointing down above the table, fingers open [rad] and [m].
Q0 = np.array([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.8, 0.04, 0.04])
FRAMES = ("panda_hand_tcp", "panda_leftfinger", "panda_rightfinger", "panda_link7")
TCP_RADIUS = 0.01  # [m], radius of the tool-centre-point sphere
PUSH_FORCE = 10.0  # [N], downward force of the hand on the table
TARGET_RATIO = 0.7  # ucontrol / PGS with one contact

Vector = NDArray[np.float64]
Step = Callable[[Vector, Vector, Vector], tuple[Vector, Vector, bool]]


@dataclass(frozen=True)
class BenchRow:
    """One line of the table.

    Attributes:
        contacts: Number of point contacts.
        ucontrol_us: ucontrol loop in [µs/step].
        admm_us: Pinocchio ADMM loop in [µs/step].
        pgs_us: Pinocchio PGS loop in [µs/step].
        active_fraction: Fraction of ucontrol steps with an active contact.
        max_dv_admm: Max |v_ucontrol - v_ADMM| over the run in [rad/s] or [m/s].
        max_dv_pgs: Max |v_ucontrol - v_PGS| over the run in [rad/s] or [m/s].
    """

    contacts: int
    ucontrol_us: float
    admm_us: float
    pgs_us: float
    active_fraction: float
    max_dv_admm: float
    max_dv_pgs: float

    @property
    def ratio_pgs(self) -> float:
        """Ratio of the ucontrol time to the Pinocchio PGS time."""
        return self.ucontrol_us / self.pgs_us

    @property
    def ratio_admm(self) -> float:
        """Ratio of the ucontrol time to the Pinocchio ADMM time."""
        return self.ucontrol_us / self.admm_us


def panda_setup(n_contacts: int) -> tuple[RobotModel, list[PointContact], Vector]:
    """The Panda, ``n_contacts`` contacts touching the table at :data:`Q0`, and the torque.

    Returns:
        The robot, its contacts and the constant generalized force in [N m] or [N], (nv,).
    """
    robot = RobotModel.from_urdf(example_robot_data_dir() / PANDA_URDF)
    heights = {frame: robot.frame_position(Q0, frame)[2] for frame in FRAMES[:n_contacts]}
    table_z = heights[FRAMES[0]] - TCP_RADIUS  # [m]
    table = Plane(point=np.array([0.0, 0.0, table_z]), name="table")
    contacts = [
        PointContact(frame=frame, surface=table, radius=height - table_z)
        for frame, height in heights.items()
    ]
    J_tcp_world = robot.frame_jacobian(Q0, FRAMES[0])[:3]
    tau = robot.gravity_torque(Q0) + J_tcp_world.T @ np.array([0.0, 0.0, -PUSH_FORCE])
    return robot, contacts, tau


def _ucontrol_step(robot: RobotModel, contacts: Sequence[PointContact], dt: float) -> Step:
    integrator = MoreauJean(robot, ConstraintSet(robot, contacts), dt=dt)

    def step(q: Vector, v: Vector, tau: Vector) -> tuple[Vector, Vector, bool]:
        outcome = integrator.step(integrator.evaluate(q, v), tau)
        return outcome.q, outcome.v, bool(outcome.active.any())

    return step


def _pinocchio_step(
    robot: RobotModel, contacts: Sequence[PointContact], dt: float, method: str, tolerance: float
) -> Step:
    stepper = PinocchioStepper(robot.model, contacts, dt=dt, method=method, tolerance=tolerance)

    def step(q: Vector, v: Vector, tau: Vector) -> tuple[Vector, Vector, bool]:
        outcome = stepper.step(q, v, tau)
        return outcome.q, outcome.v, bool(outcome.active.any())

    return step


def _time_loop(step: Step, tau: Vector, steps: int, repeats: int, warmup: int) -> float:
    """Best-of-``repeats`` wall time of ``steps`` steps from (Q0, 0), in [µs/step]."""
    v0 = np.zeros(Q0.size)
    q, v = Q0.copy(), v0
    for _ in range(warmup):
        q, v, _ = step(q, v, tau)
    best = np.inf
    for _ in range(repeats):
        q, v = Q0.copy(), v0
        start = time.perf_counter()
        for _ in range(steps):
            q, v, _ = step(q, v, tau)
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / steps


def _trajectory(step: Step, tau: Vector, steps: int) -> tuple[Vector, float]:
    """Velocities (steps, nv) from (Q0, 0) and the fraction of steps with an active contact."""
    q, v = Q0.copy(), np.zeros(Q0.size)
    velocities = np.empty((steps, Q0.size))
    active = 0
    for k in range(steps):
        q, v, is_active = step(q, v, tau)
        velocities[k] = v
        active += is_active
    return velocities, active / steps


def run(
    n_contacts: int, *, steps: int, repeats: int, dt: float, tolerance: float, warmup: int
) -> BenchRow:
    """Time the three loops for ``n_contacts`` contacts; see the module docstring."""
    robot, contacts, tau = panda_setup(n_contacts)
    loops = {
        "ucontrol": _ucontrol_step(robot, contacts, dt),
        "admm": _pinocchio_step(robot, contacts, dt, "admm", tolerance),
        "pgs": _pinocchio_step(robot, contacts, dt, "pgs", tolerance),
    }
    times = {name: _time_loop(step, tau, steps, repeats, warmup) for name, step in loops.items()}
    reference, active_fraction = _trajectory(loops["ucontrol"], tau, steps)
    max_dv = {
        name: float(np.max(np.abs(_trajectory(loops[name], tau, steps)[0] - reference)))
        for name in ("admm", "pgs")
    }
    return BenchRow(
        contacts=n_contacts,
        ucontrol_us=times["ucontrol"],
        admm_us=times["admm"],
        pgs_us=times["pgs"],
        active_fraction=active_fraction,
        max_dv_admm=max_dv["admm"],
        max_dv_pgs=max_dv["pgs"],
    )


def markdown_table(rows: Sequence[BenchRow]) -> str:
    """The rows as a markdown table."""
    lines = [
        "| contacts | ucontrol [µs/step] | pin ADMM [µs/step] | pin PGS [µs/step] "
        "| ucontrol/PGS | ucontrol/ADMM | active steps | max Δv ADMM | max Δv PGS |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        lines.append(
            f"| {row.contacts} | {row.ucontrol_us:.1f} | {row.admm_us:.1f} | {row.pgs_us:.1f} "
            f"| {row.ratio_pgs:.2f} | {row.ratio_admm:.2f} | {100 * row.active_fraction:.0f} % "
            f"| {row.max_dv_admm:.1e} | {row.max_dv_pgs:.1e} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> list[BenchRow]:
    """Run the benchmark, print the table and the target check, return the rows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per timed run [-]")
    parser.add_argument("--repeats", type=int, default=7, help="timed runs, best kept [-]")
    parser.add_argument("--warmup", type=int, default=100, help="untimed steps first [-]")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step [s]")
    parser.add_argument(
        "--tolerance",
        type=float,
        default=1e-8,
        help="feasibility/complementarity tolerance of Pinocchio's solvers [m/s]",
    )
    args = parser.parse_args(argv)
    rows = [
        run(
            n,
            steps=args.steps,
            repeats=args.repeats,
            dt=args.dt,
            tolerance=args.tolerance,
            warmup=args.warmup,
        )
        for n in (1, 4)
    ]
    print(
        f"Panda on a table, dt = {args.dt:g} s, {args.steps} steps, best of {args.repeats}, "
        f"Pinocchio tolerance {args.tolerance:g} m/s"
    )
    print(markdown_table(rows))
    ratio = rows[0].ratio_pgs
    verdict = "holds" if ratio <= TARGET_RATIO else "does NOT hold"
    print(f"\nTarget ucontrol <= {TARGET_RATIO} x PGS with one contact: {ratio:.2f} -> {verdict}")
    return rows


if __name__ == "__main__":
    main()
