"""Closed-loop cost per step of the tracking scenes, split by stage, and its scaling with size.

Two tables (times in [µs/step], see :func:`ucontrol.bench.bench_closed_loop`):

- the tracking scenes (two-link rigid and flexible, one and two constraints; the Panda on its
  table, without and with friction) with their own controllers;
- the scaling table: the closed loop against the number of joints and contacts, the two-link
  arm (nv = 2, one contact and its stops), the Panda (nv = 9, one contact) and the Solo-12
  quadruped standing on four feet (robots/quadruped_stand.toml: nv = 18, four contacts, a
  joint PD).

With ``--baseline DIR`` (a checkout of an older ucontrol, e.g. ``git archive``d to /tmp), every
measurement runs in a fresh process per tree, alternating between the baseline and this
checkout round after round (interleaved), and the table reports the median over the rounds of
each, side by side: the before/after figures of one run on one machine. The baseline tree
runs this checkout's ``ucontrol/bench.py`` (read by path) against its own modules; its scenes
are read from its own ``robots/`` folder when they exist there.

Usage::

    python experiments/bench_closed_loop.py --duration 3 --repeats 3
    python experiments/bench_closed_loop.py --baseline /tmp/base_tree --rounds 3
    python experiments/bench_closed_loop.py --current /tmp/other_checkout --no-scaling
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: The shipped tracking scenes.
TRACKING = (
    "two_link_one_constraint",
    "two_link_two_constraints",
    "two_link_flexible_one_constraint",
    "two_link_flexible_two_constraints",
    "panda_table",
    "panda_table_friction",
)
#: The scaling table: 2-link, Panda, quadruped.
SCALING = ("two_link_one_constraint", "panda_table", "quadruped_stand")
#: Fields of a result, in [µs/step].
TIMES = ("untimed_us", "total_us", "controller_us", "plant_us", "solver_us", "loop_us")


def _bench_module() -> Any:
    """This checkout's ucontrol/bench.py, whatever ucontrol is imported (baseline trees)."""
    spec = importlib.util.spec_from_file_location("_ucontrol_bench", ROOT / "ucontrol/bench.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def scene_path(name: str, tree: Path) -> Path:
    """The TOML of scene ``name`` in ``tree``'s robots/ if it has it, else in this checkout."""
    own = tree / "robots" / f"{name}.toml"
    return own if own.is_file() else ROOT / "robots" / f"{name}.toml"


def measure(
    names: Sequence[str], tree: Path, duration: float, repeats: int, clock: str = "wall"
) -> list[dict]:
    """:func:`bench_closed_loop` of each scene, in this process, as dictionaries."""
    from ucontrol.scene import Scene

    bench = _bench_module()
    rows = []
    for name in names:
        result = bench.bench_closed_loop(
            Scene.from_toml(scene_path(name, tree)), duration=duration, repeats=repeats, clock=clock
        )
        row = {field: getattr(result, field) for field in result.__dataclass_fields__}
        row["real_time_factor"] = result.real_time_factor
        rows.append(row)
    return rows


def _worker(
    names: Sequence[str], tree: Path, duration: float, repeats: int, clock: str = "wall"
) -> list[dict]:
    """:func:`measure` in a fresh process importing ucontrol from ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--worker",
        "--tree",
        str(tree),
        "--duration",
        str(duration),
        "--repeats",
        str(repeats),
        "--clock",
        clock,
        "--scenes",
        *names,
    ]
    done = subprocess.run(command, env=env, capture_output=True, text=True, cwd="/")
    if done.returncode != 0:
        raise RuntimeError(f"benchmark worker on {tree} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _median_rows(rounds: list[list[dict]]) -> list[dict]:
    """Per scene, the median over the rounds of each time (the split then sums to ~total)."""
    rows = []
    for per_scene in zip(*rounds, strict=True):
        row = dict(per_scene[0])
        for field in TIMES:
            row[field] = float(np.median([r[field] for r in per_scene]))
        row["real_time_factor"] = 1e6 * row["dt"] / row["untimed_us"]
        rows.append(row)
    return rows


def table(rows: list[dict], labels: Sequence[str] = ()) -> str:
    """Markdown table of result rows (``labels``: a first column, e.g. before/after)."""
    head = "| scene | nv | constraints | untimed [µs/step] | real time | timed total "
    head += "| controller | plant | contact solve | log + loop |"
    rule = "|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    if labels:
        head, rule = "| code " + head, "|:---" + rule
    lines = [head, rule]
    for k, row in enumerate(rows):
        cells = [
            row["scene"],
            str(row["nv"]),
            str(row["n_constraints"]),
            f"{row['untimed_us']:.1f}",
            f"{row['real_time_factor']:.1f}×",
            *(f"{row[field]:.1f}" for field in TIMES[1:]),
        ]
        if labels:
            cells.insert(0, labels[k])
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def compare(
    names: Sequence[str],
    baseline: Path,
    duration: float,
    repeats: int,
    rounds: int,
    current: Path = ROOT,
    clock: str = "wall",
) -> str:
    """Before/after table: ``baseline`` and ``current`` interleaved over ``rounds`` rounds."""
    before: list[list[dict]] = []
    after: list[list[dict]] = []
    for _ in range(rounds):
        before.append(_worker(names, baseline, duration, repeats, clock))
        after.append(_worker(names, current, duration, repeats, clock))
    old, new = _median_rows(before), _median_rows(after)
    rows, labels = [], []
    for b, a in zip(old, new, strict=True):
        rows += [b, a]
        labels += ["before", "after"]
    return table(rows, labels)


def main(argv: Sequence[str] | None = None) -> str:
    """Run the benchmark and print (and optionally write) the markdown tables."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=None, help="scene names (robots/*.toml)")
    parser.add_argument("--duration", type=float, default=3.0, help="simulated time per run [s]")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs, median kept [-]")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds [-]")
    parser.add_argument("--baseline", type=Path, default=None, help="older checkout to compare")
    parser.add_argument(
        "--current", type=Path, default=ROOT, help="checkout measured (default: this one)"
    )
    parser.add_argument(
        "--clock", choices=("wall", "cpu"), default="wall", help="wall or process CPU time"
    )
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling table")
    parser.add_argument("--out", type=Path, default=None, help="markdown file to write")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--tree", type=Path, default=ROOT, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        rows = measure(args.scenes, args.tree, args.duration, args.repeats, args.clock)
        print(json.dumps(rows))
        return ""
    tracking = list(args.scenes or TRACKING)
    if args.baseline is not None:
        text = "Tracking scenes, before and after (interleaved medians):\n\n"
        text += compare(
            tracking,
            args.baseline,
            args.duration,
            args.repeats,
            args.rounds,
            args.current,
            args.clock,
        )
    else:
        rows = _worker(tracking, args.current, args.duration, args.repeats, args.clock)
        text = "Tracking scenes:\n\n" + table(rows)
    if not args.no_scaling:
        scaling = _worker(SCALING, args.current, args.duration, args.repeats, args.clock)
        text += "\n\nScaling with joints and contacts:\n\n" + table(scaling)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return text


if __name__ == "__main__":
    main()
