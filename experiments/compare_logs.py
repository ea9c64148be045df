"""Compare the closed-loop logs of two runs of the same scenes, field by field.

Given two directories, every ``log.npz`` found under the first (``A/<scene>/log.npz`` or
``A/log.npz``) is paired with the file at the same relative path under the second, and the
largest absolute difference of each compared field (default ``q``, ``v``, ``u``, ``impulse``)
is reported, with the length of each log. A pair passes when both logs have the same length
and every difference is at most ``--tolerance`` (default 1e-12); the exit status is 1 when a
pair fails or is missing.

Usage::

    python experiments/compare_logs.py /tmp/ref_logs /tmp/new_logs
    python experiments/compare_logs.py before/ after/ --fields q v u impulse gap --tolerance 1e-10
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Fields compared by default.
FIELDS = ("q", "v", "u", "impulse")
#: Largest difference accepted by default (round-off of the same computation).
TOLERANCE = 1e-12


@dataclass(frozen=True)
class Comparison:
    """One pair of logs.

    Attributes:
        name: Relative path of the log in both directories.
        rows: Number of rows of each log (first, second); None for a missing file.
        max_diff: Largest absolute difference per field (inf when shapes differ or a field is
            missing).
    """

    name: str
    rows: tuple[int | None, int | None]
    max_diff: dict[str, float]

    def passed(self, tolerance: float) -> bool:
        """Same length and every difference at most ``tolerance``."""
        return (
            self.rows[0] is not None
            and self.rows[0] == self.rows[1]
            and all(d <= tolerance for d in self.max_diff.values())
        )


def compare_pair(first: Path, second: Path, fields: Sequence[str], name: str) -> Comparison:
    """The largest difference of each field between two ``log.npz`` files."""
    if not second.is_file():
        with np.load(first) as a:
            return Comparison(name, (len(a["t"]), None), dict.fromkeys(fields, np.inf))
    with np.load(first) as a, np.load(second) as b:
        diffs = {}
        for field in fields:
            if field not in a or field not in b or a[field].shape != b[field].shape:
                diffs[field] = np.inf
            else:
                x, y = np.asarray(a[field], float), np.asarray(b[field], float)
                diffs[field] = float(np.max(np.abs(x - y))) if x.size else 0.0
        return Comparison(name, (len(a["t"]), len(b["t"])), diffs)


def compare_directories(
    first: Path, second: Path, fields: Sequence[str] = FIELDS
) -> list[Comparison]:
    """:func:`compare_pair` for every ``log.npz`` under ``first`` (sorted by path)."""
    return [
        compare_pair(path, second / path.relative_to(first), fields, str(path.relative_to(first)))
        for path in sorted(first.rglob("log.npz"))
    ]


def report(comparisons: Sequence[Comparison], fields: Sequence[str], tolerance: float) -> str:
    """A markdown table: one row per pair, the largest difference of each field."""
    lines = [
        "| log | rows | " + " | ".join(f"max Δ{f}" for f in fields) + " | pass |",
        "|:---|---:|" + "---:|" * len(fields) + ":---:|",
    ]
    for c in comparisons:
        rows = f"{c.rows[0]}" if c.rows[0] == c.rows[1] else f"{c.rows[0]} / {c.rows[1]}"
        diffs = " | ".join(f"{c.max_diff[f]:.1e}" for f in fields)
        lines.append(f"| {c.name} | {rows} | {diffs} | {'yes' if c.passed(tolerance) else 'NO'} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table; 0 when every pair passes, 1 otherwise."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("first", type=Path, help="directory of reference logs")
    parser.add_argument("second", type=Path, help="directory of logs to compare")
    parser.add_argument("--fields", nargs="+", default=list(FIELDS), help="log fields")
    parser.add_argument("--tolerance", type=float, default=TOLERANCE, help="largest |Δ| [-]")
    args = parser.parse_args(argv)
    comparisons = compare_directories(args.first, args.second, args.fields)
    if not comparisons:
        print(f"no log.npz under {args.first}", file=sys.stderr)
        return 1
    print(report(comparisons, args.fields, args.tolerance))
    return 0 if all(c.passed(args.tolerance) for c in comparisons) else 1


if __name__ == "__main__":
    sys.exit(main())
