"""Shared helpers of the campaign tests: campaign files written into tmp_path."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest


@pytest.fixture
def write_campaign(tmp_path: Path):
    """Write a campaign file (dedented TOML) into tmp_path and return its path."""

    def write(text: str, name: str = "campaign.toml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return write
