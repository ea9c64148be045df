r"""Cost of one Moreau–Jean step: ucontrol against Pinocchio's own ADMM and PGS loops.

The Franka Panda (example-robot-data, nq = nv = 9 with the fingers) presses its hand on a
horizontal frictionless table: a joint PD holds the start configuration, with gravity
compensation and a feed-forward downward force at the tool centre point (the same few numpy
operations in every loop, timed with it). One contact (``panda_hand_tcp``) or four (also
``panda_leftfinger``, ``panda_rightfinger``, ``panda_link7``) are point contacts whose radii
make every sphere touch the table at the start; the four are redundant (the Delassus matrix is
singular). The loops advance the same state with the same dt, dynamics and active-set rule:

- ``ucontrol``: ``MoreauJean.evaluate`` then ``MoreauJean.step`` (one active contact is solved
  by its closed form ``P = max(0, -b / D)``, which is the QP's exact solution; two or more by
  the exact solve on the last step's active set when it solves the LCP, else by proxsuite,
  warm-started);
- ``ucontrol, QP always``: the same with proxsuite for every contact problem;
- ``pin ADMM`` / ``pin PGS``: :class:`ucontrol.solvers.PinocchioStepper`, a Python loop written
  as a Pinocchio user would (``aba``, ``crba``, ``PointContactConstraintModel``,
  ``ConstraintCholeskyDecomposition``, ``ADMMConstraintSolver`` / ``PGSConstraintSolver``,
  ``aba``, ``integrate``), trusting the solvers' own stopping tests;
- ``pin PGS, solved``: the PGS loop swept again until the complementarity residual is below
  the tolerance (pin 4.1's PGS stops after one sweep on frictionless contacts, see
  :mod:`ucontrol.solvers.pinocchio_constraint_solver`);
- ``mujoco mj_step``, where MuJoCo is installed (extra ``peers``): the same robot, forces and
  sphere contacts as an MJCF model stepped by ``mj_step`` (``experiments/mujoco_peer.py``; soft
  contacts, so a different trajectory: the cost of a step is compared).

Times are µs per step, wall clock (``time.perf_counter``) or with ``--clock cpu`` the
process's CPU time (``time.process_time``, steadier on a loaded machine), best of
``--repeats`` runs of ``--steps`` steps after a warm-up. A second, untimed run of each loop
gives the largest velocity difference to the ucontrol trajectory (``max Δv``), to check that
the loops do the same work.

The targets are ucontrol at most :data:`TARGET_RATIOS` times the ``pin PGS`` loop (issue 14)
and at most :data:`MUJOCO_TARGET_RATIOS` times ``mj_step`` (issue 30).

Run: ``python experiments/bench_step.py --steps 3000 --repeats 9 --clock cpu``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco_peer  # experiments/: the optional MuJoCo loop
import numpy as np
from numpy.typing import NDArray

from ucontrol.bench import (
    CLOCKS,
    Forces,
    Step,
    integrator_step,
    stepper_step,
    time_loop,
    trajectory,
)
from ucontrol.contact import ConstraintSet, Plane, PointContact
from ucontrol.integrators import MoreauJean
from ucontrol.model import RobotModel, example_robot_data_dir
from ucontrol.solvers import PinocchioStepper, ProxsuiteLCPSolver

PANDA_URDF = "panda_description/urdf/panda.urdf"
#: Hand pointing down above the table, fingers open, in [rad] and [m].
Q0 = np.array([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.8, 0.04, 0.04])
FRAMES = ("panda_hand_tcp", "panda_leftfinger", "panda_rightfinger", "panda_link7")
TCP_RADIUS = 0.01  # [m], radius of the tool-centre-point sphere
#: [m], initial overlap of every sphere with the table: with a zero gap at rest the active-set
#: prediction g + (h/2) u <= 0 would be decided by round-off, differently in each loop.
OVERLAP = 1e-6
PUSH_FORCE = 10.0  # [N], downward force of the hand on the table
KP = 50.0  # [N m/rad] or [N/m], joint PD stiffness
KD = 5.0  # [N m s/rad] or [N s/m], joint PD damping
#: Targets of ucontrol / pin PGS by number of contacts.
TARGET_RATIOS = {1: 0.5, 4: 0.7}
#: Targets of ucontrol / MuJoCo's mj_step by number of contacts.
MUJOCO_TARGET_RATIOS = {1: 1.3, 4: 2.5}
#: The MuJoCo loop's name.
MUJOCO = "mujoco mj_step"

#: Loop names, in table order; the first is the reference of the ratios and of max Δv. MuJoCo
#: only where it is installed.
LOOPS = ("ucontrol", "ucontrol, QP always", "pin ADMM", "pin PGS", "pin PGS, solved") + (
    (MUJOCO,) if mujoco_peer.available() else ()
)

Vector = NDArray[np.float64]
Control = Callable[[Vector, Vector], Vector]


@dataclass(frozen=True)
class BenchRow:
    """One line of the table.

    Attributes:
        contacts: Number of point contacts.
        time_us: Wall time of each loop of :data:`LOOPS` in [µs/step].
        max_dv: Max |v - v_ucontrol| of each loop over the run in [rad/s] or [m/s].
        active_fraction: Fraction of ucontrol steps with an active contact.
    """

    contacts: int
    time_us: dict[str, float]
    max_dv: dict[str, float]
    active_fraction: float

    def ratio(self, loop: str) -> float:
        """Ratio of the ucontrol time to the time of ``loop``."""
        return self.time_us["ucontrol"] / self.time_us[loop]


def panda_setup(n_contacts: int) -> tuple[RobotModel, list[PointContact], Control]:
    """The Panda, ``n_contacts`` contacts touching the table at :data:`Q0`, and its controller.

    Returns:
        The robot, its contacts and the control law ``tau(q, v)``, generalized forces in
        [N m] or [N], shape (nv,).
    """
    robot = RobotModel.from_urdf(example_robot_data_dir() / PANDA_URDF)
    heights = {frame: robot.frame_position(Q0, frame)[2] for frame in FRAMES[:n_contacts]}
    table_z = heights[FRAMES[0]] - TCP_RADIUS  # [m]
    table = Plane(point=np.array([0.0, 0.0, table_z]), name="table")
    contacts = [
        PointContact(frame=frame, surface=table, radius=height - table_z + OVERLAP)
        for frame, height in heights.items()
    ]
    J_tcp_world = robot.frame_jacobian(Q0, FRAMES[0])[:3]
    tau_ff = robot.gravity_torque(Q0) + J_tcp_world.T @ np.array([0.0, 0.0, -PUSH_FORCE])

    def control(q: Vector, v: Vector) -> Vector:
        return tau_ff + KP * (Q0 - q) - KD * v

    return robot, contacts, control


def make_loops(
    robot: RobotModel, contacts: Sequence[PointContact], dt: float, tolerance: float
) -> dict[str, Step]:
    """One step function ``(q, v, tau) -> (q_next, v_next, any_active)`` per loop of LOOPS."""

    def ucontrol(exact_single: bool) -> Step:
        solver = ProxsuiteLCPSolver(exact_single=exact_single, active_set_start=exact_single)
        return integrator_step(
            MoreauJean(robot, ConstraintSet(robot, contacts), dt=dt, solver=solver)
        )

    def pinocchio(method: str, until_solved: bool) -> Step:
        return stepper_step(
            PinocchioStepper(
                robot.model,
                contacts,
                dt=dt,
                method=method,
                tolerance=tolerance,
                pgs_until_solved=until_solved,
            )
        )

    loops = {
        "ucontrol": ucontrol(exact_single=True),
        "ucontrol, QP always": ucontrol(exact_single=False),
        "pin ADMM": pinocchio("admm", False),
        "pin PGS": pinocchio("pgs", False),
        "pin PGS, solved": pinocchio("pgs", True),
    }
    if MUJOCO in LOOPS:
        loops[MUJOCO] = mujoco_peer.mujoco_step(robot.model, contacts, dt)
    return loops


def _closed_loop(control: Control) -> Forces:
    """``control`` as the forces of :func:`ucontrol.bench.time_loop`: ``tau(k, q, v)``."""

    def forces(k: int, q: Vector, v: Vector) -> Vector:
        return control(q, v)

    return forces


def run(
    n_contacts: int,
    *,
    steps: int,
    repeats: int,
    dt: float,
    tolerance: float,
    warmup: int,
    clock: str = "wall",
) -> BenchRow:
    """Time every loop for ``n_contacts`` contacts with ``clock`` (:data:`CLOCKS`)."""
    robot, contacts, control = panda_setup(n_contacts)
    loops = make_loops(robot, contacts, dt, tolerance)
    forces, v0 = _closed_loop(control), np.zeros(Q0.size)
    time_us = {
        name: time_loop(
            step, forces, Q0, v0, steps=steps, repeats=repeats, warmup=warmup, clock=CLOCKS[clock]
        )
        for name, step in loops.items()
    }
    reference, active_fraction = trajectory(loops["ucontrol"], forces, Q0, v0, steps)
    max_dv = {
        name: float(np.max(np.abs(trajectory(step, forces, Q0, v0, steps)[0] - reference)))
        for name, step in loops.items()
    }
    return BenchRow(n_contacts, time_us, max_dv, active_fraction)


def markdown_table(rows: Sequence[BenchRow]) -> str:
    """The rows as a markdown table: times, ratios, active steps and max Δv."""
    others = LOOPS[1:]
    header = (
        ["contacts"]
        + [f"{name} [µs/step]" for name in LOOPS]
        + [f"ucontrol / {name}" for name in others]
        + ["active steps"]
        + [f"max Δv {name} [rad/s]" for name in others]
    )
    lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
    for row in rows:
        cells = (
            [str(row.contacts)]
            + [f"{row.time_us[name]:.1f}" for name in LOOPS]
            + [f"{row.ratio(name):.2f}" for name in others]
            + [f"{100 * row.active_fraction:.0f} %"]
            + [f"{row.max_dv[name]:.1e}" for name in others]
        )
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> list[BenchRow]:
    """Run the benchmark, print the table and the target check, return the rows."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
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
    parser.add_argument(
        "--clock", choices=sorted(CLOCKS), default="wall", help="wall or process CPU time"
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
            clock=args.clock,
        )
        for n in TARGET_RATIOS
    ]
    print(
        f"Panda pressing on a table, dt = {args.dt:g} s, {args.steps} steps, best of "
        f"{args.repeats}, {args.clock} clock, Pinocchio tolerance {args.tolerance:g} m/s"
    )
    print(markdown_table(rows))
    print()
    targets = [("pin PGS", TARGET_RATIOS)]
    if MUJOCO in LOOPS:
        targets.append((MUJOCO, MUJOCO_TARGET_RATIOS))
    for row in rows:
        for loop, ratios in targets:
            ratio, target = row.ratio(loop), ratios[row.contacts]
            verdict = "holds" if ratio <= target else "does NOT hold"
            print(
                f"Target ucontrol <= {target} x {loop}, {row.contacts} contact(s): "
                f"{ratio:.2f} -> {verdict}"
            )
    return rows


if __name__ == "__main__":
    main()
