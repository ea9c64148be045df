r"""The Panda lands on a table, slides along it under force control and takes off, several times.

The scene is ``robots/panda_table.toml``: the Franka Panda of example-robot-data (7 arm joints
and 2 fingers, nq = nv = 9) tracks with its tool centre point ``panda_hand_tcp`` a vertical
circle of centre (0.5, 0, 0.2) m and radius 0.1 m (period 4 s) whose lower half lies below the
frictionless table z >= 0.2 m (e = 0.5). The task X = (z - 0.2, x, y) has three coordinates; the
null space (six directions) holds the initial posture. γ1 = 50 N s/m, γ2 = 10 1/s, K_f = 0.5,
λ_d = 10 N.

Prints one row per cycle and writes ``panda_table_path.png`` (x–z plane) and
``panda_table_time.png`` into ``--figures``.

Run: ``python experiments/panda_table.py --cycles 3 --dt 1e-3`` (needs the ``robots`` extra).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ucontrol.analysis.cycle_table import cycle_table, summary_line
from ucontrol.scene import load_scene
from ucontrol.simulate import SimulationResult, simulate
from ucontrol.viz.cycle_figures import cycle_figures

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "robots" / "panda_table.toml"
NAME = "panda_table"


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3, help="number of 4 s cycles")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument(
        "--figures", type=Path, default=ROOT / "docs" / "figures", help="folder of the figures"
    )
    parser.add_argument("--no-figures", action="store_true", help="write no figure")
    parser.add_argument("--out", type=Path, default=None, help="folder for log.npz, summary.json")
    args = parser.parse_args(argv)

    scene = load_scene(SCENE)
    controller = scene.build_controller()
    duration = args.cycles * controller.cycle.period + 0.5  # [s], the last takeoff included
    result = simulate(scene, controller, duration=duration, dt=args.dt, out=args.out)
    print(cycle_table(result.log))
    print(summary_line(result.summary))
    arm = slice(0, 7)
    excursion = np.abs(result.log.q[:, arm] - scene.q0[arm]).max()  # [rad]
    print(f"largest arm-joint excursion from the posture: {excursion:.3f} rad")
    if not args.no_figures:
        for path in cycle_figures(result.log, controller, args.figures, NAME, plane=(0, 2)):
            print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
