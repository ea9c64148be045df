"""A first build of compiled code says so once on the terminal, never off it."""

from __future__ import annotations

import io
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
