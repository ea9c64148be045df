"""Instructions per closed-loop step of scenes, counted by valgrind's callgrind.

Instruction counts do not depend on the machine's load, unlike timings on a shared machine.
Each scene runs in a fresh process under ``valgrind --tool=callgrind`` with the
instrumentation off while the process imports ucontrol and warms the scene up (a 0.01 s run:
the compiled libraries loaded); it is switched on (``callgrind_control -i on``) just before
the measured :func:`ucontrol.simulate` run. Two runs, of ``--duration`` and of two steps,
are subtracted, so that the run's own set-up cancels: the result is the cost of one step of
the closed loop (controller, plant, log), the interpreter included.
``OPENBLAS_NUM_THREADS=1`` keeps OpenBLAS's idle worker threads, whose spinning callgrind
would count, out of the figures, and ``PYTHONHASHSEED=0`` fixes the interpreter's hashing;
the same tree measured twice then agrees to about 0.3 % (docs/benchmarks.md).

``--python`` chooses the interpreter, hence the ucontrol tree it imports (a checkout's
virtual environment), ``--tree`` the folder whose ``robots/`` holds the scenes.

``--bench-loops`` measures loops of ``experiments/bench_step.py`` (the Panda, ``--contacts``
contacts: 1 by default, or 4) instead: ``--steps`` steps less 50, with the same
instrumentation switch.

Usage::

    python experiments/instructions_per_step.py --scenes two_link_one_constraint
    python experiments/instructions_per_step.py --bench-loops ucontrol "mujoco mj_step"
    python experiments/instructions_per_step.py --python /tmp/base/venv/bin/python --tree /tmp/base
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The scenes measured by default.
SCENES = ("two_link_one_constraint", "two_link_two_constraints", "two_link_drop")
#: What the child process runs: set up, warm up, signal, wait, then the measured run.
CHILD = """
import sys, time
from pathlib import Path
from ucontrol.scene import Scene
from ucontrol.simulate import simulate
scene = Scene.from_toml(sys.argv[1])
simulate(scene, duration=0.01, progress=False)
Path(sys.argv[3]).write_text("ready")
while not Path(sys.argv[4]).exists():
    time.sleep(0.05)
simulate(scene, duration=float(sys.argv[2]), progress=False)
"""


#: The same for a loop of experiments/bench_step.py (its number of contacts the sixth
#: argument): ``--steps`` steps of it.
BENCH_CHILD = """
import sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[5])
import numpy as np
import bench_step
from ucontrol.bench import time_loop
robot, contacts, control = bench_step.panda_setup(int(sys.argv[6]))
step = bench_step.make_loops(robot, contacts, 1e-3, 1e-8)[sys.argv[1]]
def forces(k, q, v):
    return control(q, v)
def run(steps):
    time_loop(step, forces, bench_step.Q0, np.zeros(bench_step.Q0.size), steps=steps, repeats=1,
              warmup=0)
run(50)
Path(sys.argv[3]).write_text("ready")
while not Path(sys.argv[4]).exists():
    time.sleep(0.05)
run(int(sys.argv[2]))
"""

#: Longest wait for the instrumented child (start-up, the switch, the measured run), in [s].
TIMEOUT_S = 900.0


def count(
    python: str,
    scene: Path | str,
    duration: float,
    workdir: Path,
    child: str = CHILD,
    experiments: Path = ROOT / "experiments",
    extra: Sequence[str] = (),
) -> int:
    """Instructions callgrind collects over one run of ``duration`` [s] of ``scene``.

    With ``child`` = :data:`BENCH_CHILD`, ``scene`` is a loop of experiments/bench_step.py and
    ``duration`` its number of steps, imported from ``experiments``; ``extra`` are further
    arguments of the child (the bench loop's number of contacts).
    """
    ready, go, out = workdir / "ready", workdir / "go", workdir / "callgrind.out"
    for path in (ready, go):
        path.unlink(missing_ok=True)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONHASHSEED="0")
    command = ["valgrind", "--tool=callgrind", "--dump-instr=no", "--instr-atstart=no"]
    command += [f"--callgrind-out-file={out}", python, "-c", child]
    command += [str(scene), repr(duration), str(ready), str(go), str(experiments), *extra]
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:  # the child waits for `go`: never left behind, whatever fails here
        deadline = time.monotonic() + TIMEOUT_S
        while not ready.exists():
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the run of {scene} ended or hung before its measured part")
            time.sleep(0.2)
        subprocess.run(["callgrind_control", "-i", "on", str(process.pid)], check=True,
                       capture_output=True, timeout=TIMEOUT_S)  # fmt: skip
        go.touch()
        output = process.communicate(timeout=TIMEOUT_S)[0].decode()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    if process.returncode:
        raise RuntimeError(f"the run of {scene} failed:\n{output[-2000:]}")
    collected = re.findall(r"Collected : (\d+)", output)
    return int(collected[-1])


def per_step(python: str, scene: Path, duration: float, dt: float = 1e-3) -> float:
    """Instructions per step: a run of ``duration`` less a two-step run, over their steps."""
    with tempfile.TemporaryDirectory() as directory:
        workdir = Path(directory)
        long, short = count(python, scene, duration, workdir), count(python, scene, 2 * dt, workdir)
    return (long - short) / (round(duration / dt) - 2)


def bench_loop_per_step(
    python: str, loop: str, steps: int, tree: Path = ROOT, contacts: int = 1
) -> float:
    """Instructions per step of ``loop`` of experiments/bench_step.py with ``contacts`` contacts.

    ``steps`` steps less 50, over their difference (the set-up, imports and warm-up cancel);
    the script from ``tree``'s experiments/.
    """
    with tempfile.TemporaryDirectory() as directory:
        workdir, experiments = Path(directory), tree / "experiments"
        extra = (str(contacts),)
        long = count(python, loop, steps, workdir, BENCH_CHILD, experiments, extra)
        short = count(python, loop, 50, workdir, BENCH_CHILD, experiments, extra)
    return (long - short) / (steps - 50)


def main(argv: Sequence[str] | None = None) -> list[tuple[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--python", default=sys.executable, help="interpreter (its ucontrol)")
    parser.add_argument("--tree", type=Path, default=ROOT, help="folder holding robots/")
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), help="scene names")
    parser.add_argument("--duration", type=float, default=2.0, help="measured run in [s]")
    parser.add_argument("--dt", type=float, default=1e-3, help="the scenes' step in [s]")
    parser.add_argument(
        "--bench-loops",
        nargs="+",
        default=[],
        help="loops of experiments/bench_step.py (e.g. 'ucontrol' 'mujoco mj_step') measured "
        "instead of scenes",
    )
    parser.add_argument(
        "--contacts", type=int, default=1, help="contacts of the bench loops (1 or 4) [-]"
    )
    parser.add_argument("--steps", type=int, default=1050, help="steps of a bench loop [-]")
    args = parser.parse_args(argv)
    rows = []
    if args.bench_loops:
        print(f"| bench_step loop, {args.contacts} contact(s) | instructions per step |")
        print("|:---|---:|")
        for loop in args.bench_loops:
            per_step_count = bench_loop_per_step(
                args.python, loop, args.steps, args.tree, args.contacts
            )
            rows.append((loop, per_step_count))
            print(f"| {loop} | {rows[-1][1]:,.0f} |", flush=True)
        return rows
    print("| scene | instructions per step |\n|:---|---:|")
    for name in args.scenes:
        scene = args.tree / "robots" / f"{name}.toml"
        rows.append((name, per_step(args.python, scene, args.duration, args.dt)))
        print(f"| {name} | {rows[-1][1]:,.0f} |", flush=True)
    return rows


if __name__ == "__main__":
    main()
