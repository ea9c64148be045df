"""``python -m ucontrol.campaign CAMPAIGN.toml --out DIR``: the ``ucontrol sweep`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ucontrol.campaign.command import add_sweep_parser, run_sweep
from ucontrol.exceptions import UControlError


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the ``sweep`` arguments and run the campaign; returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m ucontrol.campaign")
    commands = parser.add_subparsers(dest="command", required=True)
    add_sweep_parser(commands)
    arguments = ["sweep", *(sys.argv[1:] if argv is None else argv)]
    args = parser.parse_args(arguments)
    try:
        return run_sweep(args)
    except UControlError as error:
        print(f"ucontrol: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
