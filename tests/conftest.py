"""Shared fixtures: the scenes of robots/ and variants of them."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from ucontrol.scene import Scene, load_scene

ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def ball_scene(restitution: float, **changes: object) -> Scene:
    """The ball of robots/ball.toml with another restitution (and other scene fields)."""
    scene = load_scene(ROBOTS / "ball.toml")
    contact = dataclasses.replace(scene.contacts[0], restitution=restitution)
    return dataclasses.replace(scene, contacts=(contact,), **changes)


@pytest.fixture
def robots_dir() -> Path:
    return ROBOTS


@pytest.fixture
def two_link_scene() -> Scene:
    return load_scene(ROBOTS / "two_link_drop.toml")
