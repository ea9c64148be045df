"""Shared runner of the phase-machine cases: run a scene's cycles, print the table, draw figures.

Each case script (``two_link_one_constraint.py``, ``panda_table.py``, ...) describes its case
and calls :func:`run_case` with its scene; run them as scripts (``python experiments/<case>.py
--cycles 3``).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path

from ucontrol.analysis.cycle_table import cycle_table, summary_line
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import SimulationResult, simulate
from ucontrol.viz.cycle_figures import cycle_figures

ROOT = Path(__file__).resolve().parents[1]


def run_case(
    name: str,
    description: str,
    argv: Sequence[str] | None = None,
    *,
    plane: tuple[int, int] = (0, 1),
    report: Callable[[SimulationResult, Scene], str] | None = None,
) -> SimulationResult:
    """Run ``robots/<name>.toml`` for some cycles of its controller.

    Args:
        name: Scene name; also the prefix of the figures ``<name>_path.png``, ``<name>_time.png``.
        description: First line of the command-line help.
        argv: Command-line arguments (default ``sys.argv``): ``--cycles``, ``--dt``,
            ``--restitution`` (of every contact), ``--mass-scale`` (of the controller's model),
            ``--figures``, ``--no-figures``, ``--out``.
        plane: World axes of the path figure (x–y by default).
        report: Makes an extra line printed after the summary, from the result and the scene.

    Returns:
        The simulation result (log and summary).
    """
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--cycles", type=int, default=3, help="number of cycles")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument(
        "--restitution",
        type=float,
        default=None,
        help="e of every contact [-]",
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

    scene = _with_settings(load_scene(ROOT / "robots" / f"{name}.toml"), args)
    controller = scene.build_controller()
    duration = args.cycles * controller.cycle.period + 0.5  # [s], the last takeoff included
    result = simulate(scene, controller, duration=duration, dt=args.dt, out=args.out)
    print(cycle_table(result.log))
    print(summary_line(result.summary))
    if report is not None:
        print(report(result, scene))
    if not args.no_figures:
        for path in cycle_figures(result.log, controller, args.figures, name, plane=plane):
            print(f"wrote {path}")
    return result


def _with_settings(scene: Scene, args: argparse.Namespace) -> Scene:
    """The scene with the restitution and controller mass scale of the command line."""
    if args.restitution is not None:
        contacts = tuple(
            dataclasses.replace(contact, restitution=args.restitution) for contact in scene.contacts
        )
        scene = dataclasses.replace(scene, contacts=contacts)
    if args.mass_scale != 1.0:
        controller = {**scene.controller, "mass_scale": args.mass_scale}
        scene = dataclasses.replace(scene, controller=controller)
    return scene
