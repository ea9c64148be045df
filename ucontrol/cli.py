"""Command line: ``ucontrol run [SCENE] --out DIR [--dt H] [--duration T] [--integrator NAME]``."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path

from ucontrol.exceptions import UControlError
from ucontrol.scene import INTEGRATORS, load_scene
from ucontrol.simulate import simulate


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ucontrol", description="Robots under unilateral constraints: simulate and control."
    )
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="run a scene and write log.npz and summary.json")
    run.add_argument("scene", nargs="?", help="scene TOML file (default: the built-in scene)")
    run.add_argument(
        "--out", type=Path, default=None, help="output directory (default: runs/<scene name>)"
    )
    run.add_argument("--dt", type=float, default=None, help="time step in [s]")
    run.add_argument("--duration", type=float, default=None, help="simulated time in [s]")
    run.add_argument("--integrator", choices=INTEGRATORS, default=None, help="time integrator")
    run.add_argument(
        "--control-period",
        type=float,
        default=None,
        help="controller period in [s] (zero-order hold); default every step",
    )
    bar = run.add_mutually_exclusive_group()
    bar.add_argument(
        "--progress",
        dest="progress",
        action="store_true",
        default=None,
        help="always show the progress bar",
    )
    bar.add_argument(
        "--no-progress", dest="progress", action="store_false", help="never show the progress bar"
    )
    return parser


def _run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    if args.integrator is not None:
        settings = dataclasses.replace(scene.integrator, name=args.integrator)
        scene = dataclasses.replace(scene, integrator=settings)
    out = args.out if args.out is not None else Path("runs") / scene.name
    result = simulate(
        scene,
        duration=args.duration,
        dt=args.dt,
        control_period=args.control_period,
        out=out,
        progress=args.progress,
    )
    summary = result.summary
    print(
        f"{scene.name}: {summary['steps']} steps in {summary['wall_time_s']:.3g} s, "
        f"{summary['n_impacts']} impacts, max penetration {summary['max_penetration']:.3g}; "
        f"wrote {out / 'log.npz'} and {out / 'summary.json'}"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ucontrol`` command; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        return _run(args)
    except UControlError as error:
        print(f"ucontrol: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
