"""Command line: ``ucontrol run``, ``check``, ``convergence``, ``bench``, ``view`` and ``plot``.

``run`` simulates a scene, ``check`` evaluates the weak-stability conditions of its Brogliato
cycle before a run, ``convergence`` measures error against run time, ``bench`` times its
step against Pinocchio's ADMM and PGS loops, ``view`` replays a saved run in meshcat (or exports
it as HTML) and ``plot`` draws its figures:

``ucontrol run [SCENE] --out DIR [--dt H] [--duration T] [--integrator NAME] [--view]``;
``ucontrol check [SCENE] [--set KEY=VALUE ...] [--V1-tau0 J] [--run DIR]`` (exit status 1 when
a condition fails);
``ucontrol convergence [SCENE] --out DIR [--duration T] [--dts H ...] [--tolerances ...]``;
``ucontrol bench [SCENE] [--steps N] [--repeats R] [--warmup W] [--dt H] [--out FILE]``;
``ucontrol view DIR [--scene FILE] [--html FILE]``; ``ucontrol plot DIR [--out FIGURES]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import os
import signal
import sys
import textwrap
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ucontrol import __version__
from ucontrol.exceptions import OptionalDependencyError, UControlError
from ucontrol.output_files import check_output_dir, check_output_file

#: Scene benchmarked by ``ucontrol bench`` without a scene argument: four redundant feet on a
#: table, which Pinocchio's ADMM and PGS solve too.
BENCH_SCENE = "table_drop"
#: Width in characters of `ucontrol scenes` lines (longer descriptions wrap under themselves).
_SCENES_WIDTH = 100
_SCENE_HELP = "scene TOML file or built-in scene name (default: the built-in default scene)"
#: The commands whose parsers this module builds (``sweep`` and ``design`` have their modules').
_OWN_COMMANDS = ("run", "check", "convergence", "bench", "view", "plot", "scenes")
#: The variables OpenBLAS reads its thread count from, first found first: where none is set,
#: this module's commands load it single-threaded (:func:`_single_threaded_blas`).
_BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")

if TYPE_CHECKING:  # meshcat is imported only when a viewer is asked for
    from ucontrol.analysis.stability_check import StabilityCheck
    from ucontrol.log import Log
    from ucontrol.scene import Scene
    from ucontrol.viz.live_viewer import LiveViewer
    from ucontrol.viz.meshcat_server import MeshcatServer


def _parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The command line's parser; ``sweep`` and ``design`` only where ``argv`` may name them.

    Their parsers live in their own modules (the campaign's and the design's), imported only
    when the first word of ``argv`` (the command: the top-level options take no value) is
    neither of this module's commands: ``ucontrol run`` builds no parser it does not use.
    """
    # Pinocchio comes with the scenes: imported once the signals are handled (main)
    from ucontrol.scene import INTEGRATORS

    parser = argparse.ArgumentParser(
        prog="ucontrol", description="Robots under unilateral constraints: simulate and control."
    )
    parser.add_argument("--version", action="version", version=f"ucontrol {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser(
        "scenes",
        help="list the built-in scenes (run one by its name)",
        description="List the scenes shipped with ucontrol (the repository's robots/ folder, "
        "installed as the package ucontrol.robots), each with the first sentence of its "
        "description. Run one from any folder by its name: `ucontrol run NAME`. The campaign "
        "shipped beside them runs the same way: `ucontrol sweep ball_restitution_campaign "
        "--out DIR`.",
    )
    run = commands.add_parser("run", help="run a scene and write log.npz and summary.json")
    run.add_argument("scene", nargs="?", help=_SCENE_HELP)
    run.add_argument(
        "--out", type=Path, default=None, help="output directory (default: runs/<scene name>)"
    )
    run.add_argument("--dt", type=float, default=None, help="time step in [s]")
    run.add_argument("--duration", type=float, default=None, help="simulated time in [s]")
    run.add_argument("--integrator", choices=INTEGRATORS, default=None, help="time integrator")
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a scene key (dotted TOML key, TOML value), e.g. contacts.0.restitution=0.5; "
        "repeatable",
    )
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
    run.add_argument(
        "--view",
        action="store_true",
        help="draw the run live in meshcat (in real time, once a browser has the viewer open)",
    )
    check = commands.add_parser(
        "check",
        help="check the weak-stability conditions of a scene's Brogliato cycle before a run "
        "(exit status 1 when one fails)",
        description="Evaluate, for the scene's desired cycle and gains, the conditions of the "
        "book's weak stability over cycles (ch. 8, Lemma 8.1): the bound on the jumps of V over "
        "an accumulation of impacts, the finite accumulation and its time bound before the "
        "takeoff, a positive desired force in the constrained phase. Prints each condition "
        "with its numbers; exit status 0 when all hold, 1 when one fails, 2 on bad input "
        "(docs/stability_check.md).",
    )
    check.add_argument("scene", nargs="?", help=_SCENE_HELP)
    check.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a scene key, as `ucontrol run --set`; repeatable",
    )
    check.add_argument(
        "--V1-tau0",
        type=float,
        default=0.0,
        metavar="J",
        help="V1 at the start of the approach in [J], which sets the virtual depth (default 0: "
        "the cycle tracked exactly)",
    )
    check.add_argument(
        "--run",
        type=Path,
        default=None,
        metavar="DIR",
        help="a run directory of the scene: write the bounds beside the quantities measured on "
        "its cycles into DIR/summary.json (key stability_check)",
    )
    study = commands.add_parser(
        "convergence",
        help="error against run time of each integrator: CSV, markdown, work-precision PNG",
    )
    study.add_argument("scene", nargs="?", help=_SCENE_HELP)
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
        default=None,
        help="moreau_jean steps in [s]",
    )
    study.add_argument(
        "--tolerances",
        type=float,
        nargs="+",
        default=None,
        help="event_driven relative tolerances (atol = rtol / 100)",
    )
    study.add_argument(
        "--stiffnesses",
        type=float,
        nargs="+",
        default=None,
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
    bench = commands.add_parser(
        "bench",
        help="time a scene's step against Pinocchio's ADMM and PGS loops (markdown table)",
    )
    bench.add_argument(
        "scene",
        nargs="?",
        help=f"scene TOML file or built-in scene name (default: {BENCH_SCENE}, which has the "
        "Pinocchio comparison)",
    )
    bench.add_argument("--steps", type=int, default=2000, help="steps per timed run")
    bench.add_argument("--repeats", type=int, default=5, help="timed runs, the fastest kept")
    bench.add_argument("--warmup", type=int, default=100, help="untimed steps before them")
    bench.add_argument(
        "--dt", type=float, default=None, help="time step in [s] (default: the scene's)"
    )
    bench.add_argument(
        "--out", type=Path, default=None, help="also write the table to this markdown file"
    )
    bench.add_argument(
        "--closed-loop",
        action="store_true",
        help="time the scene's closed loop (its controller), split controller / plant / contact "
        "solve / log",
    )
    bench.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated time per closed-loop run in [s] (default: the scene's)",
    )
    bench.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="wall time or this process's CPU time (steadier on a loaded machine)",
    )
    view = commands.add_parser(
        "view", help="replay a saved run in meshcat, or export it as a standalone HTML page"
    )
    view.add_argument("directory", type=Path, help="run directory (holds log.npz)")
    view.add_argument(
        "--scene", type=Path, default=None, help="scene file (default: the one the run recorded)"
    )
    view.add_argument(
        "--html", type=Path, default=None, help="write the animation to this HTML file and exit"
    )
    view.add_argument(
        "--fps",
        type=float,
        default=30.0,
        help="frames per second (of simulated time in meshcat; of video with --video)",
    )
    view.add_argument(
        "--video",
        type=Path,
        default=None,
        metavar="FILE",
        help="write the run as a video (.mp4 or .gif, needs ffmpeg) and exit",
    )
    view.add_argument(
        "--speed", type=float, default=1.0, help="simulated seconds per second of --video"
    )
    view.add_argument(
        "--still",
        type=Path,
        default=None,
        metavar="FILE",
        help="write one figure-quality image (.png, .pdf or .svg) of the run and exit",
    )
    view.add_argument(
        "--time", type=float, default=None, help="time of --still in [s] (default: the end)"
    )
    plot = commands.add_parser("plot", help="figures (PNG) of a saved run or of a campaign")
    plot.add_argument(
        "directory", type=Path, help="run directory (holds log.npz) or campaign directory"
    )
    plot.add_argument(
        "--scene", type=Path, default=None, help="scene file (default: the one the run recorded)"
    )
    plot.add_argument(
        "--out", type=Path, default=None, help="folder of the figures (default: DIR/figures)"
    )
    words = sys.argv[1:] if argv is None else argv
    command = next((word for word in words if not word.startswith("-")), None)
    if command not in _OWN_COMMANDS:  # sweep, design, or a word argparse reports with them
        from ucontrol.campaign.command import add_sweep_parser
        from ucontrol.design.command import add_design_parser

        add_sweep_parser(commands)
        add_design_parser(commands)
    return parser


def _scenes(args: argparse.Namespace) -> int:
    """Print each scene's name and its description's first sentence, wrapped, never cut."""
    from ucontrol.scene import builtin_scenes

    for name, summary in builtin_scenes().items():
        print(
            textwrap.fill(
                summary,
                width=_SCENES_WIDTH,
                initial_indent=f"{name:36s} ",
                subsequent_indent=" " * 37,
                break_on_hyphens=False,
            )
        )
    return 0


def _run(args: argparse.Namespace) -> int:
    from ucontrol.scene import load_scene
    from ucontrol.simulate import simulate

    if args.set:  # the campaign package's overrides, for these alone
        from ucontrol.campaign.overrides import scene_with_overrides

        scene = scene_with_overrides(args.scene, args.set)
    else:
        scene = load_scene(args.scene)
    if args.integrator is not None:
        settings = dataclasses.replace(scene.integrator, name=args.integrator)
        scene = dataclasses.replace(scene, integrator=settings)
    out = args.out if args.out is not None else Path("runs") / scene.name
    server, live = _live_viewer(scene) if args.view else (None, None)
    result = simulate(
        scene,
        duration=args.duration,
        dt=args.dt,
        control_period=args.control_period,
        out=out,
        progress=args.progress,
        observer=live,
    )
    summary = result.summary
    if dict(scene.controller).get("type") == "brogliato" and scene.flexible is None:
        from ucontrol.analysis.stability_check import check_scene

        _write_stability_check(check_scene(scene), result.log, out / "summary.json")
    print(
        f"{scene.name}: {summary['steps']} steps in {_loop_time(summary)}, "
        f"{summary['n_impacts']} impacts, max penetration {summary['max_penetration']:.3g}; "
        f"wrote {out / 'log.npz'} and {out / 'summary.json'}"
    )
    if server is not None and live is not None:
        live.show(result.log)
        print(f"{server.url} shows the end of the run; Ctrl-C to quit", flush=True)
        _wait_for_interrupt()
        server.close()
    return 0


def _loop_time(summary: dict[str, Any]) -> str:
    """The loop's wall and CPU time with their real-time factors (simulated over spent time).

    On a shared machine the wall time also counts the other processes' work; the CPU time
    (this process's) is the figure to set beside an in-process benchmark.
    """
    simulated, wall, cpu = summary["final_time"], summary["wall_time_s"], summary["cpu_time_s"]
    return (
        f"{wall:.3g} s ({simulated / max(wall, 1e-9):.3g}× real time; "
        f"CPU {cpu:.3g} s, {simulated / max(cpu, 1e-9):.3g}×)"
    )


def _write_stability_check(check: StabilityCheck, log: Log, path: Path) -> None:
    """Put ``check``'s bounds beside the run's measured cycles into ``path`` (summary.json)."""
    import json

    from ucontrol.analysis.stability_check import compare_with_run

    summary = json.loads(path.read_text()) if path.is_file() else {}
    summary["stability_check"] = compare_with_run(check, log)
    path.write_text(json.dumps(summary, indent=2) + "\n")


def _check(args: argparse.Namespace) -> int:
    """``ucontrol check``: the a-priori weak-stability check, optionally beside a run."""
    from ucontrol.analysis.stability_check import EXIT_CONDITION_FAILS, check_scene
    from ucontrol.campaign.overrides import scene_with_overrides
    from ucontrol.saved_run import SavedRun
    from ucontrol.scene import load_scene

    scene = scene_with_overrides(args.scene, args.set) if args.set else load_scene(args.scene)
    result = check_scene(scene, V1_tau0=args.V1_tau0)
    print(result.report())
    if args.run is not None:
        run = SavedRun.load(args.run, scene.source)
        path = args.run / "summary.json"
        _write_stability_check(result, run.log, path)
        print(f"wrote the bounds beside the measured cycles into {path}")
    for failure in result.failures:
        print(
            f"ucontrol: condition {failure.name} fails: {failure.statement} ("
            + ", ".join(f"{key} = {value:g}" for key, value in failure.gains.items())
            + ")",
            file=sys.stderr,
        )
    return 0 if result.holds else EXIT_CONDITION_FAILS


def _live_viewer(scene: Scene) -> tuple[MeshcatServer, LiveViewer]:
    """A meshcat server with the scene drawn, once a browser has its page open."""
    from ucontrol.viz.live_viewer import LiveViewer
    from ucontrol.viz.meshcat_server import MeshcatServer

    server = MeshcatServer()
    phases = dict(scene.controller).get("type") == "brogliato"
    live = LiveViewer(scene, server.viewer, phases=phases)
    print(f"meshcat viewer: open {server.url} in a browser; the run starts then", flush=True)
    server.wait_for_browser()
    return server, live


def _view(args: argparse.Namespace) -> int:
    if args.video is not None or args.still is not None:
        return _export(args)
    if args.html is not None:
        check_output_file("--html", args.html)
    from ucontrol.saved_run import SavedRun

    run = SavedRun.load(args.directory, args.scene)
    scene = run.require_scene()
    from ucontrol.viz.meshcat_server import MeshcatServer
    from ucontrol.viz.replay import replay, write_html

    if args.html is not None:
        path = write_html(args.html, scene, run.log, fps=args.fps)
        print(f"wrote {path}: open it in a browser (it plays offline)")
        return 0
    with MeshcatServer() as server:
        replay(server.viewer, scene, run.log, fps=args.fps)
        print(f"replay of {args.directory}: open {server.url}; Ctrl-C to quit", flush=True)
        _wait_for_interrupt()
    return 0


def _export(args: argparse.Namespace) -> int:
    """``ucontrol view DIR --video FILE`` / ``--still FILE``: files rendered offline."""
    for option, path in (("--video", args.video), ("--still", args.still)):
        if path is not None:
            check_output_file(option, path)
    try:
        from ucontrol.viz.video import write_still, write_video
    except ModuleNotFoundError as error:
        if (error.name or "").partition(".")[0] != "matplotlib":
            raise
        raise OptionalDependencyError("matplotlib", "viz") from error
    if args.video is not None:
        written = write_video(
            args.directory, args.video, fps=args.fps, speed=args.speed, scene=args.scene
        )
        print(f"wrote {written}")
    if args.still is not None:
        written = write_still(args.directory, args.still, time=args.time, scene=args.scene)
        print(f"wrote {written}")
    return 0


def _plot(args: argparse.Namespace) -> int:
    out = args.out if args.out is not None else args.directory / "figures"
    check_output_dir("--out", out)
    from ucontrol.campaign.command import is_campaign, plot_campaign
    from ucontrol.saved_run import SavedRun

    if is_campaign(args.directory):  # a campaign's figures: success rates, distributions
        for path in plot_campaign(args.directory, out):
            print(f"wrote {path}")
        return 0
    run = SavedRun.load(args.directory, args.scene)
    try:
        from ucontrol.viz.run_figures import run_figures
    except ModuleNotFoundError as error:
        if (error.name or "").partition(".")[0] != "matplotlib":
            raise
        raise OptionalDependencyError("matplotlib", "viz") from error
    if run.scene is None:
        print(
            "ucontrol: note: the scene of the run is unknown (pass --scene FILE for the "
            "path figures of a phase-machine run)",
            file=sys.stderr,
        )
    for path in run_figures(run.log, out, scene=run.scene):
        print(f"wrote {path}")
    return 0


def _wait_for_interrupt() -> None:
    """Block until Ctrl-C (SIGINT), keeping a viewer server alive."""
    try:
        while True:
            time.sleep(3600.0)
    except KeyboardInterrupt:
        pass


def _convergence(args: argparse.Namespace) -> int:
    from ucontrol import convergence
    from ucontrol.scene import load_scene

    scene = load_scene(args.scene)
    out = args.out if args.out is not None else Path("runs") / scene.name / "convergence"
    check_output_dir("--out", out)
    # the ranges the command line leaves out take run_convergence's defaults
    ranges = {"dts": args.dts, "tolerances": args.tolerances, "stiffnesses": args.stiffnesses}
    study = convergence.run_convergence(
        scene,
        duration=args.duration,
        integrators=args.integrators,
        **{name: values for name, values in ranges.items() if values is not None},
        sample_dt=args.sample_dt,
        control_period=args.control_period,
    )
    paths = convergence.write_report(study, out)
    print(study.to_markdown())
    print(f"wrote {', '.join(str(path) for path in paths.values())}")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from ucontrol.bench import bench_closed_loop, bench_scene, closed_loop_markdown
    from ucontrol.scene import load_scene

    if args.scene is None:
        print(f"benchmarking the built-in scene {BENCH_SCENE} (it has the Pinocchio comparison)")
    if args.out is not None:
        check_output_file("--out", args.out)
    scene = load_scene(BENCH_SCENE if args.scene is None else args.scene)
    if args.closed_loop:
        result = bench_closed_loop(
            scene, duration=args.duration, repeats=args.repeats, dt=args.dt, clock=args.clock
        )
        table = closed_loop_markdown([result])
    else:
        report = bench_scene(
            scene,
            steps=args.steps,
            repeats=args.repeats,
            warmup=args.warmup,
            dt=args.dt,
            clock=args.clock,
        )
        table = report.markdown()
    print(table)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(table + "\n")
        print(f"wrote {args.out}")
    return 0


class _Signalled(KeyboardInterrupt):
    """SIGTERM or SIGHUP, handled like Ctrl-C (a run keeps its log)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _interrupt_on_signals(previous: dict[int, Any]) -> None:
    """Make SIGTERM and SIGHUP raise :class:`_Signalled`, the handlers replaced in ``previous``.

    Filled as it goes, ``previous`` holds what to restore also when a signal lands in between.
    """

    def interrupt(signum: int, frame: Any) -> None:
        raise _Signalled(signum)

    for signum in (signal.SIGTERM, signal.SIGHUP):
        previous[signum] = signal.getsignal(signum)
        signal.signal(signum, interrupt)


def _restore_signals(previous: dict[int, Any]) -> None:
    for signum, handler in previous.items():
        signal.signal(signum, handler)


def _sweep(args: argparse.Namespace) -> int:
    from ucontrol.campaign.command import run_sweep

    return run_sweep(args)


def _design(args: argparse.Namespace) -> int:
    from ucontrol.design.command import run_design

    return run_design(args)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ucontrol`` command; returns the exit status.

    SIGTERM and SIGHUP are handled like Ctrl-C from the start, before the modules that take
    seconds to import: a signal then ends the command in one line, never a traceback.

    Called as the process's command (``argv`` None: the ``ucontrol`` script, ``python -m
    ucontrol.cli``), it spares the garbage collector the objects of its imports, which live
    as long as the process (:func:`gc.freeze`, docs/benchmarks.md): the collector is off
    while the parser's modules (the scene layer, numpy, Pinocchio) are imported, then what
    they made is frozen and the collector on again; when the command ends, the objects are
    frozen again, so that the interpreter's exit does not traverse them (it still closes
    files, flushes its streams and runs the exit handlers). A call with ``argv`` from a
    Python program leaves its collector alone.
    """
    previous: dict[int, Any] = {}
    restore_blas = _single_threaded_blas(sys.argv[1:] if argv is None else argv)
    own_process = argv is None
    if own_process:
        gc.disable()
    try:
        _interrupt_on_signals(previous)
        args = _parser(argv).parse_args(argv)
        if own_process:
            _freeze_collector()
        commands = {
            "run": _run,
            "check": _check,
            "convergence": _convergence,
            "bench": _bench,
            "view": _view,
            "plot": _plot,
            "scenes": _scenes,
            "sweep": _sweep,
            "design": _design,
        }
        return commands[args.command](args)
    except UControlError as error:
        print(f"ucontrol: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:  # Ctrl-C, SIGTERM, SIGHUP: one line
        signum = getattr(interrupt, "signum", signal.SIGINT)
        name = signal.Signals(signum).name
        time_s, log_path = getattr(interrupt, "time", None), getattr(interrupt, "log_path", None)
        if log_path is not None:
            done = f"the log up to t = {time_s:.6g} s is in {log_path}"
        elif time_s is not None:
            done = f"stopped at t = {time_s:.6g} s, nothing written"
        else:
            done = "nothing was written"
        print(f"ucontrol: interrupted by {name}; {done}", file=sys.stderr)
        return 128 + signum  # the conventional status of a process ended by that signal
    finally:
        _restore_signals(previous)
        if restore_blas:
            del os.environ[_BLAS_THREAD_VARIABLES[0]]
        if own_process:
            _freeze_collector()


def _freeze_collector() -> None:
    """Move every object the collector tracks out of its reach, and turn it on."""
    gc.freeze()
    gc.enable()


def _single_threaded_blas(argv: Sequence[str]) -> bool:
    """Have OpenBLAS loaded with one thread for this module's commands; True if this set it.

    Their matrices are a robot's (tens of rows), far below the sizes where OpenBLAS's
    threads pay, while its pools of idle threads, started when numpy's and scipy's copies
    load, cost each process CPU time (docs/benchmarks.md). Nothing is set where the user
    chose a thread count (:data:`_BLAS_THREAD_VARIABLES`), where numpy is loaded already (an
    in-process call: its OpenBLAS is started), or for ``sweep`` and ``design`` (their workers
    and solvers are their modules' business). The variable is removed when the command ends.
    """
    command = next((word for word in argv if not word.startswith("-")), None)
    if command not in _OWN_COMMANDS or "numpy" in sys.modules:
        return False
    if any(os.environ.get(name) for name in _BLAS_THREAD_VARIABLES):
        return False
    os.environ[_BLAS_THREAD_VARIABLES[0]] = "1"
    return True


if __name__ == "__main__":
    sys.exit(main())
