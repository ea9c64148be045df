"""A first build of compiled code says so once on the terminal, never off it."""

from __future__ import annotations

import io
import os
from pathlib import Path

import pytest

from ucontrol.model import compile_cache
from ucontrol.model.compile_cache import CACHE_ENV, build_library

SOURCE = "double twice(double x) { return 2.0 * x; }\n"


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_first_build_is_announced_once_on_a_terminal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(compile_cache, "_announced", False)
    terminal = _Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    build_library("notice_a", "a", SOURCE)
    build_library("notice_a", "a", SOURCE)  # cached: nothing built
    build_library("notice_b", "b", SOURCE)  # built, already said
    said = terminal.getvalue()
    assert said.count("compiling") == 1, said
    assert str(tmp_path) in said


def test_no_notice_off_a_terminal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(compile_cache, "_announced", False)
    pipe = io.StringIO()  # isatty() is False
    monkeypatch.setattr("sys.stderr", pipe)
    build_library("notice_c", "c", SOURCE)
    assert pipe.getvalue() == ""


def test_cache_keeps_the_most_recently_used_libraries(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """At most MAX_LIBRARIES libraries: a build removes the least recently used (found = used)."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(compile_cache, "MAX_LIBRARIES", 2)
    monkeypatch.setattr("sys.stderr", io.StringIO())
    first = build_library("lru", "first", SOURCE)
    second = build_library("lru", "second", SOURCE)
    os.utime(first, (1.0, 1.0))  # both used long ago, first before second
    os.utime(second, (2.0, 2.0))
    assert build_library("lru", "first", SOURCE) == first  # found: its use recorded
    third = build_library("lru", "third", SOURCE)  # beyond 2: the least recently used goes
    assert sorted(tmp_path.glob("casadi/*.so")) == sorted([first, third])
    assert not second.with_name(second.name + ".lock").exists()
    assert build_library("lru", "second", SOURCE) == second  # built again on need
    assert second.is_file() and len(list(tmp_path.glob("casadi/*.so"))) == 2
