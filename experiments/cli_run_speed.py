r"""``ucontrol run`` against the same loop in process: the command's cost and its real-time factors.

For each scene, ``--rounds`` times, interleaved: the command ``python -m ucontrol.cli run SCENE
--no-progress`` in a new process (its whole CPU time, user + system, and its wall time, from the
operating system), with the real-time factors its summary reports (simulated time over the
loop's wall time and over the loop's CPU time, ``summary.json``'s ``wall_time_s`` and
``cpu_time_s``); then the same scene in this process, a run after a warm-up run (imports done,
compiled laws loaded), its loop's CPU real-time factor. The default scene is the one ``ucontrol
run`` runs without a scene (``two_link_drop``). Medians over the rounds; the load average (the
other processes' work on a shared machine) is printed with them.

The commands run as a user's second run does: one untimed run of each scene first fills the
compile cache (its libraries are then found by their definitions, without casadi) and Python's
bytecode cache, kept in a temporary directory (``PYTHONPYCACHEPREFIX``) even where the
environment sets ``PYTHONDONTWRITEBYTECODE`` (an installed package ships its bytecode; an
editable install compiled anew at every start costs 0.1-0.3 s more). ``--no-bytecode-cache``
keeps the environment as it is.

``--baseline DIR`` also runs each command from the source tree DIR (another revision, e.g.
``git archive REV | tar -x -C DIR`` with ``robots`` linked as ``DIR/ucontrol/robots``),
interleaved with this tree's, first on ``sys.path`` and with this tree's editable-install
finder removed, and prints the command CPU of both; with ``--baseline-python PYTHON`` (an
environment where DIR is installed editable) the baseline runs as ``PYTHON -m ucontrol.cli``.

Run: ``python experiments/cli_run_speed.py --scenes default two_link_one_constraint panda_table
--rounds 5``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

#: The name that stands for ``ucontrol run`` without a scene.
DEFAULT = "default"


def main(argv: Sequence[str] | None = None) -> dict[str, dict[str, float]]:
    """Measure each scene; print one markdown table; return the medians per scene."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenes", nargs="+", default=[DEFAULT, "two_link_one_constraint", "panda_table"]
    )
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds")
    parser.add_argument(
        "--no-bytecode-cache",
        action="store_true",
        help="run the commands in this environment as it is (see the module docstring)",
    )
    parser.add_argument("--baseline", type=Path, default=None, help="a source tree to compare with")
    parser.add_argument(
        "--baseline-python",
        type=Path,
        default=None,
        help="the baseline's interpreter, whose environment installs --baseline (editable): "
        "the baseline runs as `python -m ucontrol.cli` there",
    )
    args = parser.parse_args(argv)

    samples: dict[str, list[dict[str, float]]] = {scene: [] for scene in args.scenes}
    baseline: dict[str, list[float]] = {scene: [] for scene in args.scenes}
    with tempfile.TemporaryDirectory() as work:
        env = dict(os.environ)
        if not args.no_bytecode_cache:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = str(Path(work) / "pycache")
        for scene in args.scenes:  # warm-up: the compile and bytecode caches filled
            _command(scene, Path(work) / scene, env)
            if args.baseline is not None:
                _command(scene, Path(work) / "baseline", env, args.baseline, args.baseline_python)
        for _ in range(args.rounds):
            for scene in args.scenes:
                out = Path(work) / scene
                samples[scene].append({**_command(scene, out, env), **_in_process(scene)})
                if args.baseline is not None:
                    other = _command(
                        scene, Path(work) / "baseline", env, args.baseline, args.baseline_python
                    )
                    baseline[scene].append(other["command_cpu_s"])
    figures = {
        scene: {key: statistics.median(run[key] for run in runs) for key in runs[0]}
        for scene, runs in samples.items()
    }
    print(f"{args.rounds} rounds, load average {os.getloadavg()[0]:.1f} (1 min)")
    print(
        "| scene | command CPU [s] | command wall [s] | reported RTF, wall | reported RTF, CPU "
        "| in-process RTF, CPU | reported / in-process |\n|---|---|---|---|---|---|---|"
    )
    for scene, f in figures.items():
        print(
            f"| {scene} | {f['command_cpu_s']:.3f} | {f['command_wall_s']:.3f} "
            f"| {f['rtf_wall']:.1f}× | {f['rtf_cpu']:.1f}× | {f['in_process_rtf_cpu']:.1f}× "
            f"| {f['rtf_cpu'] / f['in_process_rtf_cpu']:.2f} |"
        )
    if args.baseline is not None:
        print(f"\n| scene | command CPU, {args.baseline} [s] | this tree [s] |\n|---|---|---|")
        for scene, cpu in baseline.items():
            this = [run["command_cpu_s"] for run in samples[scene]]
            print(
                f"| {scene} | {statistics.median(cpu):.3f} ({min(cpu):.3f}–{max(cpu):.3f}) "
                f"| {statistics.median(this):.3f} ({min(this):.3f}–{max(this):.3f}) |"
            )
    return figures


#: Runs ``ucontrol.cli`` from the source tree ``sys.argv[1]`` (the rest: the command's words).
_FROM_TREE = """
import sys
tree = sys.argv.pop(1)
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
sys.path.insert(0, tree)
from ucontrol.cli import main
raise SystemExit(main(sys.argv[1:]))
"""


def _command(
    scene: str,
    out: Path,
    env: dict[str, str],
    tree: Path | None = None,
    python: Path | None = None,
) -> dict[str, float]:
    """``ucontrol run`` in a new process: its CPU and wall time and its summary's RTFs.

    From this environment, or from the source tree ``tree`` put first on ``sys.path``, or with
    the interpreter ``python`` (whose environment installs ``tree``).
    """
    words = ["run", "--out", str(out), "--no-progress", *([] if scene == DEFAULT else [scene])]
    if python is not None:
        command = [str(python), "-m", "ucontrol.cli", *words]
    elif tree is None:
        command = [sys.executable, "-m", "ucontrol.cli", *words]
    else:
        command = [sys.executable, "-c", _FROM_TREE, str(tree), *words]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    summary = json.loads((out / "summary.json").read_text())
    simulated = summary["final_time"]
    return {
        "command_cpu_s": cpu,
        "command_wall_s": wall,
        "rtf_wall": simulated / summary["wall_time_s"],
        "rtf_cpu": simulated / summary["cpu_time_s"],
    }


def _in_process(scene: str) -> dict[str, float]:
    """The loop's CPU real-time factor of a run in this process after a warm-up run."""
    from ucontrol.scene import load_scene
    from ucontrol.scene.builtin_scenes import DEFAULT_SCENE
    from ucontrol.simulate import simulate

    name = Path(DEFAULT_SCENE).stem if scene == DEFAULT else scene
    simulate(load_scene(name), progress=False)  # warm-up: imports, compiled laws loaded
    summary = simulate(load_scene(name), progress=False).summary
    return {"in_process_rtf_cpu": summary["final_time"] / summary["cpu_time_s"]}


if __name__ == "__main__":
    main()
