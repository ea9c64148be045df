"""The scenes shipped with ucontrol (the repository's ``robots/`` folder), by name."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from ucontrol.exceptions import InvalidParameterError, NotFoundError
from ucontrol.scene.scene import Scene

#: Scene run by ``ucontrol run`` without a scene argument.
DEFAULT_SCENE = "two_link_drop.toml"


def _folder() -> Path:
    return Path(str(files("ucontrol.robots")))


def _has_table(path: Path, table: str) -> bool:
    """Whether the TOML file declares the top-level ``[table]``."""
    return any(line.strip() == f"[{table}]" for line in path.read_text().splitlines())


def builtin_campaigns() -> dict[str, Path]:
    """The campaign files shipped with ucontrol (a ``[campaign]`` table), by name."""
    return {
        path.stem: path for path in sorted(_folder().glob("*.toml")) if _has_table(path, "campaign")
    }


def builtin_scene(name: str = DEFAULT_SCENE) -> Path:
    """Path of a scene shipped with ucontrol, by its name with or without ``.toml``.

    Raises:
        NotFoundError: No built-in scene has that name (the message lists them).
    """
    file = name if name.endswith(".toml") else f"{name}.toml"
    path = _folder() / file
    if not path.is_file():
        raise NotFoundError("built-in scene", name, sorted(builtin_scenes()))
    return path


def builtin_scenes() -> dict[str, str]:
    """Each built-in scene's name and the whole first sentence of its description, by name.

    Other TOML files shipped beside the scenes (design tasks, campaigns) are left out: a scene
    has a ``[robot]`` table.
    """
    scenes = {}
    for path in sorted(_folder().glob("*.toml")):
        if not _has_table(path, "robot"):
            continue
        text = path.read_text()
        comment = []
        for line in text.splitlines():
            if not line.startswith("#"):
                break
            comment.append(line.lstrip("#").strip())
        description = " ".join(comment)
        scenes[path.stem] = description.split(". ")[0].rstrip(".")
    return scenes


def load_scene(scene: str | Path | None = None) -> Scene:
    """Load a scene file, a built-in scene by name, or the default scene when None.

    A name without a folder or ``.toml`` that is not a file in the working directory names a
    built-in scene (``load_scene("ball")``).

    Raises:
        InvalidParameterError: ``scene`` is neither a path nor a string.
        NotFoundError: A name that is no built-in scene.
        SceneError: The file is missing or malformed.
    """
    if scene is None:
        return Scene.from_toml(builtin_scene())
    if not isinstance(scene, str | Path):
        raise InvalidParameterError("scene", scene, "a scene file path or a built-in scene name")
    path = Path(scene)
    if not path.exists() and path.parent == Path(".") and path.suffix in ("", ".toml"):
        return Scene.from_toml(builtin_scene(path.name))
    return Scene.from_toml(path)
