"""``python -m ucontrol.campaign CAMPAIGN.toml --out DIR``: the ``ucontrol sweep`` command."""

from __future__ import annotations

import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``ucontrol sweep`` with these arguments; returns the exit status.

    The command's own entry point handles the signals and the typed errors (one line).
    """
    from ucontrol.cli import main as command

    return command(["sweep", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
