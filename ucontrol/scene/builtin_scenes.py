"""The scenes shipped with ucontrol (the repository's ``robots/`` folder)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from ucontrol.exceptions import NotFoundError
from ucontrol.scene.scene import Scene

#: Scene run by ``ucontrol run`` without a scene argument.
DEFAULT_SCENE = "two_link_drop.toml"


def builtin_scene(name: str = DEFAULT_SCENE) -> Path:
    """Path of a scene shipped with ucontrol (the repository's ``robots/`` folder)."""
    path = Path(str(files("ucontrol.robots").joinpath(name)))
    if not path.is_file():
        available = [p.name for p in Path(str(files("ucontrol.robots"))).glob("*.toml")]
        raise NotFoundError("built-in scene", name, available)
    return path


def load_scene(path: str | Path | None = None) -> Scene:
    """Load a scene file, or the built-in default scene when ``path`` is None."""
    return Scene.from_toml(builtin_scene() if path is None else path)
