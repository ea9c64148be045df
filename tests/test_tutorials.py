"""The tutorials of docs/tutorials run as they stand: their code cells, in order, in a new folder.

The tutorials are Jupyter notebooks in MyST-NB's text form (``{code-cell}`` directives), which
the documentation build executes too. A cell that starts with ``%%writefile NAME`` is a file
the reader saves under that name (a URDF, a scene, a campaign); the other cells run in page
order in one namespace, as the notebook's kernel runs them. The tutorials keep their runs
short themselves, so that this file runs in well under a minute.
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

TUTORIALS = Path(__file__).resolve().parents[1] / "docs" / "tutorials"
#: A code cell: ```{code-cell} ipython3, its ":key: value" options, an optional blank line.
_CELL = re.compile(
    r"^```\{code-cell\}\s+ipython3\n(?P<options>(?::\S+:[^\n]*\n)*)\n?(?P<body>.*?)^```[ \t]*$",
    re.M | re.S,
)
#: The cell magic that saves a cell's content to a file.
_WRITEFILE = re.compile(r"\A%%writefile\s+(?P<file>\S+)\n")


def tutorial_blocks(page: Path) -> list[tuple[str, str]]:
    """The code cells of a page in order: ("python", code) or (file name, content)."""
    blocks = []
    for match in _CELL.finditer(page.read_text(encoding="utf-8")):
        body = match["body"]
        saved = _WRITEFILE.match(body)
        if saved is None:
            blocks.append(("python", body))
        else:
            blocks.append((saved["file"], body[saved.end() :]))
    return blocks


PAGES = sorted(TUTORIALS.glob("*.md"))


def test_every_tutorial_is_in_the_toctree_and_a_notebook() -> None:
    index = (TUTORIALS.parents[0] / "index.md").read_text(encoding="utf-8")
    assert len(PAGES) >= 4
    for page in PAGES:
        assert f"tutorials/{page.stem}" in index, page.name
        header = page.read_text(encoding="utf-8").split("---\n")[1]  # the YAML front matter
        assert "format_name: myst" in header and "kernelspec:" in header, page.name
        assert "```python" not in page.read_text(encoding="utf-8"), page.name  # no dead code


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
    blocks = tutorial_blocks(page)
    kinds = [kind for kind, _ in blocks]
    assert kinds[:2] == ["ball.urdf", "drop.toml"]
    assert blocks[0][1].startswith('<robot name="ball">')  # the magic and options left out
    assert kinds.count("python") >= 3


@pytest.mark.parametrize("page", PAGES, ids=[page.stem for page in PAGES])
def test_each_tutorial_shows_the_run_in_meshcat_inline(page: Path) -> None:
    code = [body for kind, body in tutorial_blocks(page) if kind == "python"]
    assert any("notebook_replay(" in body.splitlines()[-1] for body in code), page.name


def test_getting_started_runs_outside_the_clone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """docs/getting_started.md's Python runs in an empty folder: built-in scenes by name."""
    monkeypatch.chdir(tmp_path)
    text = (TUTORIALS.parent / "getting_started.md").read_text(encoding="utf-8")
    code = re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)  # a page, not a notebook
    assert code and all("robots/" not in body for body in code)
    namespace: dict[str, object] = {"__name__": "getting_started"}
    for number, body in enumerate(code):
        exec(compile(body, f"getting_started.md (block {number})", "exec"), namespace)
    assert (tmp_path / "runs" / "pd" / "summary.json").is_file()
