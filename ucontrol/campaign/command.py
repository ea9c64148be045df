"""The ``ucontrol sweep`` command and ``ucontrol plot`` on a campaign directory.

``ucontrol sweep CAMPAIGN.toml --out DIR [--scheduler ADDRESS] [--workers N]
[--format csv|parquet]`` checks the campaign file, runs the runs not yet in ``DIR`` and prints
the success rate (95 % Wilson interval) and the worst runs with the commands that re-run them.
The functions here are wired into :mod:`ucontrol.cli`; ``python -m ucontrol.campaign`` runs
the same command.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ucontrol.campaign.figures import plot_campaign, worst_cases, worst_markdown
from ucontrol.campaign.table import CAMPAIGN_FILE, TABLE_FORMATS, load, wilson_interval

#: Exit status of a campaign stopped without a signal (runs cancelled by the scheduler); a
#: signal gives 128 + its number (130 for Ctrl-C, 143 for SIGTERM), the table written.
INTERRUPTED = 130

__all__ = ["add_sweep_parser", "is_campaign", "plot_campaign", "run_sweep", "success_line"]


def add_sweep_parser(commands: Any) -> argparse.ArgumentParser:
    """Add the ``sweep`` subcommand to an argparse subparsers object and return its parser."""
    sweep = commands.add_parser(
        "sweep",
        help="run a campaign (grid or Monte Carlo over scene keys) on dask.distributed",
        description="Run a campaign file's runs on a local Dask cluster or an existing "
        "scheduler; runs already in --out are skipped.",
    )
    sweep.add_argument(
        "campaign",
        type=Path,
        help="campaign TOML file, or the name of a shipped one (ball_restitution_campaign)",
    )
    sweep.add_argument("--out", type=Path, required=True, help="campaign directory")
    sweep.add_argument(
        "--scheduler",
        default=None,
        help="address of a running Dask scheduler, e.g. tcp://host:8786 (default: a local cluster)",
    )
    sweep.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes of the local cluster (default: the number of cores)",
    )
    sweep.add_argument(
        "--format",
        choices=TABLE_FORMATS,
        default="csv",
        help="table format: csv, or parquet too (needs pyarrow)",
    )
    bar = sweep.add_mutually_exclusive_group()
    bar.add_argument("--progress", dest="progress", action="store_true", default=None)
    bar.add_argument("--no-progress", dest="progress", action="store_false")
    return sweep


def run_sweep(args: argparse.Namespace) -> int:
    """Run the ``sweep`` command; returns 0, or 128 + the signal when interrupted.

    The table of the runs finished so far is written in every case.

    Raises:
        UControlError: Any typed error of the campaign file, the output directory or the
            scheduler, before a run starts.
    """
    from ucontrol.campaign.runner import run_campaign
    from ucontrol.campaign.spec import load_campaign
    from ucontrol.campaign.table import check_formats
    from ucontrol.exceptions import InvalidParameterError

    if args.workers is not None and args.workers < 1:
        raise InvalidParameterError("--workers", args.workers, "an integer >= 1")
    formats = ("csv",) if args.format == "csv" else ("csv", "parquet")
    check_formats(formats)
    campaign = load_campaign(args.campaign)
    outcome = run_campaign(
        campaign,
        args.out,
        scheduler=args.scheduler,
        workers=args.workers,
        formats=formats,
        progress=getattr(args, "progress", None),
    )
    print(
        f"{campaign.name}: {outcome.total} runs, {outcome.skipped} already done, "
        f"{outcome.ran} ran now ({outcome.failed} failed)"
    )
    print(success_line(load(outcome.directory)))
    print(f"worst runs (re-run one with its command):\n{worst_markdown(worst_cases(args.out))}")
    print(f"wrote {', '.join(str(path) for path in outcome.tables)}")
    if outcome.interrupted:
        missing = outcome.total - outcome.skipped - outcome.ran
        why = "" if outcome.reason is None else f" ({outcome.reason})"
        print(f"interrupted{why}: {missing} runs left; run the same command again to finish")
        return 128 + outcome.signum if outcome.signum is not None else INTERRUPTED
    return 0


def success_line(frame: Any) -> str:
    """``success k/n = p (95 % Wilson interval [a, b])`` of a campaign table."""
    n, k = len(frame), int(frame["success"].sum())
    low, high = wilson_interval(k, n)
    rate = k / n if n else float("nan")
    return f"success {k}/{n} = {rate:.3f} (95 % Wilson interval [{low:.3f}, {high:.3f}])"


def is_campaign(directory: str | Path) -> bool:
    """Whether ``directory`` is a campaign's (holds ``campaign.json``), for ``ucontrol plot``."""
    return Path(directory, CAMPAIGN_FILE).is_file()
