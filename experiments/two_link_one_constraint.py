r"""Brogliato's rigid one-constraint case: a two-link arm lands, slides on the ground, takes off.

The scene is ``robots/two_link_one_constraint.toml`` (DESIGN §5): the end effector tracks the
circle of centre (0.65, 0) m and radius 0.1 m (period 10 s) whose lower half lies below the
ground y >= 0 (e = 0.7); γ1 = 8 N s/m, γ2 = 7 1/s, K_f = 0.5, q0 = (0.9, -1.6) rad. Each cycle
approaches the ground from τ0 = 4.2 s + 10 k s, lands (t0), lets the impacts accumulate (t_f),
slides with the desired force λ_d = 5 N and takes off at t_d = 10 (k + 1) s.

Prints one row per cycle (events, V(τ0), errors) and writes ``two_link_one_constraint_path.png``
and ``two_link_one_constraint_time.png`` into ``--figures``.

Run: ``python experiments/two_link_one_constraint.py --cycles 3 --dt 1e-3``.
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
SCENE = ROOT / "robots" / "two_link_one_constraint.toml"
NAME = "two_link_one_constraint"


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3, help="number of 10 s cycles")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument("--restitution", type=float, default=None, help="e of the ground [-]")
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
        ground = dataclasses.replace(scene.contacts[0], restitution=args.restitution)
        scene = dataclasses.replace(scene, contacts=(ground,))
    scene = dataclasses.replace(
        scene, controller={**scene.controller, "mass_scale": args.mass_scale}
    )
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
