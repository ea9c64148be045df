"""Command line: ``ucontrol run`` (one simulation) and ``ucontrol convergence`` (accuracy study).

``ucontrol run [SCENE] --out DIR [--dt H] [--duration T] [--integrator NAME]``;
``ucontrol convergence [SCENE] --out DIR [--duration T] [--dts H ...] [--tolerances ...]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path

from ucontrol.analysis import convergence
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
    study = commands.add_parser(
        "convergence",
        help="error against run time of each integrator: CSV, markdown, work-precision PNG",
    )
    study.add_argument("scene", nargs="?", help="scene TOML file (default: the built-in scene)")
    study.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output directory (default: runs/<scene name>/convergence)",
    )
    study.add_argument("--duration", type=float, default=None, help="simulated time in [s]")
    study.add_argument(
        "--integrators", nargs="+", choices=INTEGRATORS, default=INTEGRATORS, help="integrators"
    )
    study.add_argument(
        "--dts",
        type=float,
        nargs="+",
        default=convergence.DEFAULT_DTS,
        help="moreau_jean steps in [s]",
    )
    study.add_argument(
        "--tolerances",
        type=float,
        nargs="+",
        default=convergence.DEFAULT_TOLERANCES,
        help="event_driven relative tolerances (atol = rtol / 100)",
    )
    study.add_argument(
        "--stiffnesses",
        type=float,
        nargs="+",
        default=convergence.DEFAULT_STIFFNESSES,
        help="compliant stiffnesses in [N/m]",
    )
    study.add_argument(
        "--sample-dt",
        type=float,
        default=None,
        help="sampling period of event_driven and compliant in [s]; default the scene's dt",
    )
    study.add_argument(
        "--control-period",
        type=float,
        default=None,
        help="controller period of every run in [s] (closed loops); default every step",
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


def _convergence(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    out = args.out if args.out is not None else Path("runs") / scene.name / "convergence"
    study = convergence.run_convergence(
        scene,
        duration=args.duration,
        integrators=args.integrators,
        dts=args.dts,
        tolerances=args.tolerances,
        stiffnesses=args.stiffnesses,
        sample_dt=args.sample_dt,
        control_period=args.control_period,
    )
    paths = convergence.write_report(study, out)
    print(study.to_markdown())
    print(f"wrote {', '.join(str(path) for path in paths.values())}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ucontrol`` command; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        return _convergence(args) if args.command == "convergence" else _run(args)
    except UControlError as error:
        print(f"ucontrol: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
