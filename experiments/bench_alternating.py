r"""Cost per step of two checkouts in fresh processes that alternate; the smallest is kept.

On a shared, loaded machine the median of a few runs moves by more than a change of 10 %
does; the smallest CPU time over many runs moves much less. This script runs, round after
round, one process per tree and per item, alternating which tree goes first, and reports per
item the smallest and the median CPU time per step of each tree.

- A scene (``--scenes``, names of ``robots/*.toml``) runs in closed loop with its own controller
  (:func:`ucontrol.simulate`): the cost per step is that of a ``--duration`` run minus that of
  a two-step run (which cancels the set-up), ``--runs`` times per process.
- A column of n beads with friction (``--beads``, the column of
  ``experiments/bench_contacts.py``) runs ``--steps`` Moreau–Jean steps after five of warm-up,
  ``--runs`` times per process.

With ``--instructions`` the columns of beads are counted instead, by valgrind's callgrind
(deterministic, unlike CPU time on a shared machine: one round): a worker warms up five
steps, switches the instrumentation on in itself (``callgrind_control -i on``) and runs
``--steps`` steps, then ``2 × --steps``; the difference over ``--steps`` is the instructions
of one step.

Usage::

    git archive 89430a0 | tar -x -C /tmp/base   # then copy the built _native_call extension
    python experiments/bench_alternating.py --baseline /tmp/base \
        --scenes panda_table_friction solo_landing solo_pronk --beads 10 50 100
    python experiments/bench_alternating.py --baseline /tmp/base --beads 100 --instructions
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _scene_costs(name: str, duration: float, runs: int) -> list[float]:
    """CPU µs per step of ``runs`` closed-loop runs of scene ``name`` (this process's tree)."""
    from ucontrol.scene import Scene
    from ucontrol.simulate import simulate

    scene = Scene.from_toml(Path("robots") / f"{name}.toml")
    warnings.simplefilter("ignore")  # a scene's own warnings are not the measurement
    simulate(scene, duration=0.05, progress=False)  # warm-up: caches, compiled laws
    costs = []
    for _ in range(runs):
        spans = []
        for span in (0.002, duration):
            start = time.process_time()
            log = simulate(scene, duration=span, progress=False).log
            spans.append((time.process_time() - start, len(log) - 1))
        (short, short_steps), (full, full_steps) = spans
        costs.append(1e6 * (full - short) / max(full_steps - short_steps, 1))
    return costs


def _beads_costs(n: int, steps: int, runs: int) -> list[float]:
    """CPU µs per step of ``runs`` runs of ``steps`` steps of the column of ``n`` beads."""
    import numpy as np

    sys.path.insert(0, str(Path("experiments").resolve()))
    from bench_contacts import _integrator, column

    robot, constraints, q, v = column(n)
    integrator = _integrator("ucontrol", robot, constraints, 1e-3, 1e-10)
    tau = np.zeros(v.size)
    costs = []
    for k in range(runs + 1):
        start = time.process_time()
        for _ in range(5 if k == 0 else steps):  # the first pass: warm-up
            outcome = integrator.step(integrator.evaluate(q, v), tau)
            q, v = outcome.q, outcome.v
        if k:
            costs.append(1e6 * (time.process_time() - start) / steps)
    return costs


def _beads_instructed(n: int, steps: int) -> None:
    """``steps`` steps of the column of ``n`` beads, instrumented by callgrind after warm-up."""
    import numpy as np

    sys.path.insert(0, str(Path("experiments").resolve()))
    from bench_contacts import _integrator, column

    robot, constraints, q, v = column(n)
    integrator = _integrator("ucontrol", robot, constraints, 1e-3, 1e-10)
    tau = np.zeros(v.size)
    for k in range(5 + steps):
        if k == 5:  # valgrind reads the request while this process runs: poll, not wait
            switch = subprocess.Popen(["callgrind_control", "-i", "on", str(os.getpid())])
            while switch.poll() is None:
                time.sleep(0.01)
        outcome = integrator.step(integrator.evaluate(q, v), tau)
        q, v = outcome.q, outcome.v


def _instructions(tree: Path, n: int, steps: int) -> float:
    """Instructions per step of the column of ``n`` beads on ``tree`` (module docstring)."""
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1", PYTHONHASHSEED="0")
    collected = []
    for length in (steps, 2 * steps):
        command = ["valgrind", "--tool=callgrind", "--instr-atstart=no"]
        command += ["--callgrind-out-file=/dev/null", sys.executable, str(Path(__file__).resolve())]
        command += ["--worker", f"instructed:{n}", "--steps", str(length)]
        done = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True)
        counts = re.findall(r"Collected : (\d+)", done.stderr)
        if done.returncode or not counts:
            raise RuntimeError(f"the instrumented run failed:\n{done.stderr[-2000:]}")
        collected.append(int(counts[-1]))
    return (collected[1] - collected[0]) / steps


def _measure(tree: Path, item: str, args: argparse.Namespace) -> list[float]:
    """The costs of ``item`` (``scene:NAME`` or ``beads:N``) in a fresh process on ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1")
    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--worker",
        item,
        "--duration",
        str(args.duration),
        "--steps",
        str(args.steps),
        "--runs",
        str(args.runs),
    ]
    done = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True, check=True)
    return [float(x) for x in json.loads(done.stdout.strip().splitlines()[-1])]


def main(argv: Sequence[str] | None = None) -> list[dict[str, object]]:
    """Run the comparison and print its table; returns one row per item."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, default=None, help="older checkout")
    parser.add_argument("--current", type=Path, default=ROOT, help="checkout measured")
    parser.add_argument("--scenes", nargs="*", default=[], help="scene names")
    parser.add_argument("--beads", nargs="*", type=int, default=[], help="column sizes [-]")
    parser.add_argument("--duration", type=float, default=2.0, help="closed-loop run [s]")
    parser.add_argument("--steps", type=int, default=20, help="bead-column steps per run [-]")
    parser.add_argument("--runs", type=int, default=2, help="runs per process [-]")
    parser.add_argument("--rounds", type=int, default=4, help="alternating rounds [-]")
    parser.add_argument(
        "--instructions", action="store_true", help="count the beads' instructions per step"
    )
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker is not None:
        kind, _, value = args.worker.partition(":")
        if kind == "instructed":
            _beads_instructed(int(value), args.steps)
            return []
        if kind == "scene":
            worker_costs = _scene_costs(value, args.duration, args.runs)
        else:
            worker_costs = _beads_costs(int(value), args.steps, args.runs)
        print(json.dumps(worker_costs))
        return []
    trees = {"before": args.baseline, "after": args.current}
    trees = {label: tree.resolve() for label, tree in trees.items() if tree is not None}
    if args.instructions:
        return _instruction_table(trees, args.beads, args.steps)
    items = [f"scene:{name}" for name in args.scenes] + [f"beads:{n}" for n in args.beads]
    costs: dict[tuple[str, str], list[float]] = {(i, t): [] for i in items for t in trees}
    load = [os.getloadavg()[0]]
    for round_ in range(args.rounds):
        order = list(trees.items()) if round_ % 2 == 0 else list(reversed(trees.items()))
        for item in items:
            for label, tree in order:
                costs[item, label] += _measure(tree, item, args)
        load.append(os.getloadavg()[0])
    rows: list[dict[str, object]] = []
    header = "| item | " + " | ".join(f"{t}: min | {t}: median" for t in trees)
    lines = [header + (" | after / before (min) |" if len(trees) == 2 else " |")]
    lines.append("|:---|" + "---:|" * (2 * len(trees) + (len(trees) == 2)))
    for item in items:
        row: dict[str, object] = {"item": item}
        cells = []
        smallest = {}
        for label in trees:
            smallest[label] = min(costs[item, label])
            row[label] = (smallest[label], statistics.median(costs[item, label]))
            cells += [f"{smallest[label]:.1f}", f"{statistics.median(costs[item, label]):.1f}"]
        if len(trees) == 2:
            row["ratio"] = smallest["after"] / smallest["before"]
            cells.append(f"{row['ratio']:.2f}")
        rows.append(row)
        lines.append(f"| {item} | " + " | ".join(cells) + " |")
    print(f"CPU µs per step; load average {min(load):.1f}–{max(load):.1f}\n")
    print("\n".join(lines))
    return rows


def _instruction_table(
    trees: dict[str, Path], sizes: list[int], steps: int
) -> list[dict[str, object]]:
    """Print and return the instructions per step of each column size on each tree."""
    rows: list[dict[str, object]] = []
    print("| item | " + " | ".join(trees) + (" | after / before |" if len(trees) == 2 else " |"))
    print("|:---|" + "---:|" * (len(trees) + (len(trees) == 2)))
    for n in sizes:
        row: dict[str, object] = {"item": f"beads:{n}"}
        for label, tree in trees.items():
            row[label] = _instructions(tree, n, steps)
        cells = [f"{row[label]:,.0f}" for label in trees]
        if len(trees) == 2:
            row["ratio"] = float(row["after"]) / float(row["before"])  # type: ignore[arg-type]
            cells.append(f"{row['ratio']:.2f}")
        rows.append(row)
        print(f"| beads:{n} | " + " | ".join(cells) + " |", flush=True)
    return rows


if __name__ == "__main__":
    main()
