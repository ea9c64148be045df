"""The tutorials of docs/tutorials run as they stand: their code blocks, in order, in a new folder.

A page's ``{code-block}`` directives with a ``:caption:`` are the files the reader saves under
that name (a URDF, a scene); its ``python`` blocks are run in page order in one namespace, as a
reader pasting them into one session would. Console blocks are shown, not run. The tutorials keep
their runs short themselves, so that this file runs in well under a minute.
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

TUTORIALS = Path(__file__).resolve().parents[1] / "docs" / "tutorials"
#: A fenced block: ```python ...``` or ```{code-block} LANG with a :caption: FILE option.
_BLOCK = re.compile(
    r"^```(?:(?P<python>python)|\{code-block\}\s+(?P<lang>\S+)\n:caption:\s*(?P<file>\S+)\n)\n?"
    r"(?P<body>.*?)^```\s*$",
    re.M | re.S,
)


def tutorial_blocks(page: Path) -> list[tuple[str, str]]:
    """The blocks of a page in order: ("python", code) or (file name, content)."""
    blocks = []
    for match in _BLOCK.finditer(page.read_text(encoding="utf-8")):
        kind = "python" if match["python"] else match["file"]
        blocks.append((kind, match["body"]))
    return blocks


PAGES = sorted(TUTORIALS.glob("*.md"))


def test_every_tutorial_is_in_the_toctree() -> None:
    index = (TUTORIALS.parents[0] / "index.md").read_text(encoding="utf-8")
    assert len(PAGES) >= 3
    for page in PAGES:
        assert f"tutorials/{page.stem}" in index, page.name


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES, ids=[page.stem for page in PAGES])
def test_tutorial_runs(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    blocks = tutorial_blocks(page)
    assert any(kind == "python" for kind, _ in blocks), f"{page.name} has no python block"
    namespace: dict[str, object] = {"__name__": f"tutorial_{page.stem}"}
    for number, (kind, body) in enumerate(blocks):
        if kind == "python":
            code = compile(body, f"{page.name} (block {number})", "exec")
            exec(code, namespace)  # the tutorial's own code
        else:
            target = tmp_path / kind
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(body, encoding="utf-8")


def test_blocks_are_found() -> None:
    page = TUTORIALS / "first_impacting_scene.md"
    kinds = [kind for kind, _ in tutorial_blocks(page)]
    assert kinds[:2] == ["ball.urdf", "drop.toml"]
    assert kinds.count("python") >= 3


def test_getting_started_runs_outside_the_clone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """docs/getting_started.md's Python runs in an empty folder: built-in scenes by name."""
    monkeypatch.chdir(tmp_path)
    blocks = tutorial_blocks(TUTORIALS.parent / "getting_started.md")
    code = [body for kind, body in blocks if kind == "python"]
    assert code and all("robots/" not in body for body in code)
    namespace: dict[str, object] = {"__name__": "getting_started"}
    for number, body in enumerate(code):
        exec(compile(body, f"getting_started.md (block {number})", "exec"), namespace)
    assert (tmp_path / "runs" / "pd" / "summary.json").is_file()
