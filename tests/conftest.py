"""Shared fixtures: the scenes of robots/ and variants of them."""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import signal
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from ucontrol.model.compiled_function import compilation_possible
from ucontrol.scene import Scene, load_scene

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
#: Marks a test of what only compiled code does (a fast path, a compiled law's shortcut): it is
#: skipped where that code does not exist, with UCONTROL_NO_COMPILE=1 or without a C compiler.
needs_compiled_code = pytest.mark.skipif(
    not compilation_possible(),
    reason="checks compiled code, which UCONTROL_NO_COMPILE=1 (or no C compiler) turns off",
)
EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
#: The tracking scenes of the phase-machine controller (robots/ names), frictionless.
TRACKING_SCENES = (
    "two_link_one_constraint",
    "two_link_two_constraints",
    "panda_table",
    "two_link_flexible_one_constraint",
    "two_link_flexible_two_constraints",
)


def load_experiment(name: str) -> ModuleType:
    """Import ``experiments/<name>.py`` (the folder is not a package) as ``experiments_<name>``."""
    module_name = f"experiments_{name}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    if str(EXPERIMENTS) not in sys.path:  # the case scripts import their shared runner
        sys.path.append(str(EXPERIMENTS))
    spec = importlib.util.spec_from_file_location(module_name, EXPERIMENTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses look their module up while being created
    spec.loader.exec_module(module)
    return module


@contextlib.contextmanager
def sigint_default() -> Iterator[None]:
    """SIGINT handled (not ignored) in this process while a child is started.

    A child inherits an ignored SIGINT through exec (pytest started as a background job); a
    handled one is reset to its default, where Python installs its KeyboardInterrupt: then
    Ctrl-C reaches the child, as in a terminal.
    """
    previous = signal.getsignal(signal.SIGINT)
    if previous is not signal.SIG_IGN:
        yield
        return
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def ball_scene(restitution: float, **changes: object) -> Scene:
    """The ball of robots/ball.toml with another restitution (and other scene fields)."""
    scene = load_scene(ROBOTS / "ball.toml")
    contact = dataclasses.replace(scene.contacts[0], restitution=restitution)
    return dataclasses.replace(scene, contacts=(contact,), **changes)


@pytest.fixture
def rng(request: pytest.FixtureRequest) -> np.random.Generator:
    """A generator of its own for each test, seeded from the test's id.

    A test's inputs then never depend on which other tests ran before it (a module-level
    generator shared by a module's tests does), and each test keeps the same inputs from run
    to run and when run alone.
    """
    return np.random.default_rng(list(request.node.nodeid.encode()))  # every byte seeds it


@pytest.fixture
def robots_dir() -> Path:
    return ROBOTS


@pytest.fixture
def two_link_scene() -> Scene:
    return load_scene(ROBOTS / "two_link_drop.toml")


@pytest.fixture
def write_campaign(tmp_path: Path) -> Any:
    """Write a campaign file (dedented TOML) into tmp_path and return its path."""

    def write(text: str, name: str = "campaign.toml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return write
