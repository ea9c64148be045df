r"""Brogliato's rigid two-constraint case: ground, corner and wall, cycle after cycle.

The scene is ``robots/two_link_two_constraints.toml`` (DESIGN §5): the end effector of the
two-link arm runs the upper-left quarter of the circle of centre (0.7, 0) m and radius 0.5 m
(period 10 s) in free motion, lands on the ground y >= 0 at (0.2, 0), slides to the corner
against the wall x <= 0.7 (both e = 0.7), enters the corner through a second transition, slides
up the wall and takes off at (0.7, 0.5); γ1 = γ2 = 15, K_f = 0.5, q0 = (1.5, -0.9) rad. Both
task coordinates are gaps, X = (y, 0.7 - x).

Every cycle is built from the declared contact phases only (ground [2.5, 7.5] s, wall
[5, 10] s of the period), never from values left by the previous cycle, so that cycle k + 1
starts where cycle k would: the table printed has one row per cycle and contact.

Run: ``python experiments/two_link_two_constraints.py --cycles 3 --dt 1e-3``.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from pathlib import Path

from ucontrol.analysis.cycle_table import cycle_table, summary_line
from ucontrol.scene import load_scene
from ucontrol.simulate import SimulationResult, simulate
from ucontrol.viz.cycle_figures import cycle_figures

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "robots" / "two_link_two_constraints.toml"
NAME = "two_link_two_constraints"


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3, help="number of 10 s cycles")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument(
        "--restitution", type=float, default=None, help="e of the ground and the wall [-]"
    )
    parser.add_argument(
        "--mass-scale", type=float, default=1.0, help="masses of the controller's model × this [-]"
    )
    parser.add_argument(
        "--figures", type=Path, default=ROOT / "docs" / "figures", help="folder of the figures"
    )
    parser.add_argument("--no-figures", action="store_true", help="write no figure")
    parser.add_argument("--out", type=Path, default=None, help="folder for log.npz, summary.json")
    args = parser.parse_args(argv)

    scene = load_scene(SCENE)
    if args.restitution is not None:
        contacts = tuple(
            dataclasses.replace(contact, restitution=args.restitution) for contact in scene.contacts
        )
        scene = dataclasses.replace(scene, contacts=contacts)
    table = {**scene.controller, "mass_scale": args.mass_scale}
    scene = dataclasses.replace(scene, controller=table)
    controller = scene.build_controller()
    duration = args.cycles * controller.cycle.period + 0.5  # [s], the last takeoff included
    result = simulate(scene, controller, duration=duration, dt=args.dt, out=args.out)
    print(cycle_table(result.log))
    print(summary_line(result.summary))
    if not args.no_figures:
        for path in cycle_figures(result.log, controller, args.figures, NAME):
            print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
