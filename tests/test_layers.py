"""The package's layers: no import circles, and lower layers never import higher ones.

Every import counts: at module level, type-only ones (under ``if TYPE_CHECKING:``), lazy ones
inside functions, and ``import_module("ucontrol....")`` calls. A lazy import of a higher layer
is still a dependency on it, and a type-only circle still ties two modules into one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ucontrol"

#: Rank of each top-level part of the package: a module may import only from parts of a
#: lower or equal rank (DESIGN.md §2, data flows down the list).
LAYERS = {
    "exceptions": 0,
    "_validation": 1,
    "_lazy_names": 0,
    "log": 1,
    "output_files": 1,
    "model": 2,
    "contact": 3,
    "solvers": 4,
    "plant": 5,
    "integrators": 6,
    "control": 7,
    "sensors": 7,
    "analysis": 8,
    "scene": 9,
    "simulate": 10,
    "saved_run": 10,
    "testing": 11,
    "design": 11,
    "campaign": 11,
    "convergence": 11,
    "scene_maps": 11,
    "bench": 11,
    "viz": 12,
    "cli": 13,
    "__main__": 14,
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """The ucontrol modules ``path`` imports, wherever the import statement stands."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("ucontrol"))
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("ucontrol"):
            assert node.module is not None and node.level == 0
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif (
            isinstance(node, ast.Call)
            and ast.unparse(node.func).endswith("import_module")
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and str(node.args[0].value).startswith("ucontrol")
        ):
            found.add(str(node.args[0].value))
    return found


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        imported = _imports(path) - {name, "ucontrol"}
        graph[name] = {m for m in imported if m in modules}
    return graph


def _layer(module: str) -> int:
    if module.endswith(".__main__"):  # a package's `python -m` entry point: the top layer
        return LAYERS["__main__"]
    top = module.split(".")[1] if "." in module else ""
    if top not in LAYERS:
        pytest.fail(f"{module}: its part {top!r} has no layer in tests/test_layers.py")
    return LAYERS[top]


def test_lower_layers_never_import_higher_ones() -> None:
    graph = _graph()
    upward = [
        f"{module} -> {target}"
        for module, targets in graph.items()
        if module != "ucontrol"
        for target in targets
        if _layer(target) > _layer(module)
    ]
    assert not upward, "upward imports:\n" + "\n".join(sorted(upward))


def test_no_import_circles() -> None:
    graph = _graph()
    # A package's __init__ importing its own modules is the package loading itself.
    edges = {
        module: {t for t in targets if not module.startswith(t + ".")}
        for module, targets in graph.items()
    }
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def walk(module: str, stack: list[str]) -> None:
        state[module] = 1
        stack.append(module)
        for target in sorted(edges.get(module, ())):
            if state.get(target) == 1:
                cycles.append([*stack[stack.index(target) :], target])
            elif target not in state:
                walk(target, stack)
        stack.pop()
        state[module] = 2

    for module in sorted(edges):
        if module not in state:
            walk(module, [])
    assert not cycles, "import circles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_the_checker_sees_every_kind_of_import(tmp_path: Path) -> None:
    """The two checks above are not vacuous: module-level, type-only and lazy imports count."""
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import TYPE_CHECKING\n"
        "from importlib import import_module\n"
        "from ucontrol.simulate import simulate\n"
        "if TYPE_CHECKING:\n    from ucontrol.cli import main\n"
        "def f():\n    import ucontrol.viz\n    return import_module('ucontrol.bench')\n"
    )
    assert _imports(module) == {
        "ucontrol.simulate",
        "ucontrol.simulate.simulate",
        "ucontrol.cli",
        "ucontrol.cli.main",
        "ucontrol.viz",
        "ucontrol.bench",
    }
    assert _layer("ucontrol.simulate") > _layer("ucontrol.model.robot_model")
