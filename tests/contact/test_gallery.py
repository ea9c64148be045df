"""experiments/gallery.py draws a figure of every gallery scene (briefly), and each exists."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import ROBOTS, load_experiment


@pytest.mark.slow
def test_gallery_draws_every_scene(tmp_path: Path) -> None:
    gallery = load_experiment("gallery")
    assert all((ROBOTS / f"{name}.toml").is_file() for name in gallery.SCENES)
    gallery.main(["--duration", "0.01", "--out", str(tmp_path)])
    figures = sorted(path.name for path in tmp_path.glob("gallery_*.png"))
    assert figures == sorted(f"gallery_{name}.png" for name in gallery.SCENES)
    docs = (ROBOTS.parent / "docs" / "gallery.md").read_text(encoding="utf-8")
    assert all(f"figures/gallery_{name}.png" in docs for name in gallery.SCENES)
