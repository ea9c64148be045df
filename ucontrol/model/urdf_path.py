"""Where a scene's ``urdf`` (or ``mjcf``, ``sdf``) entry points to."""

from __future__ import annotations

import sys
from pathlib import Path

from ucontrol.exceptions import URDFError

#: Prefix of URDF paths inside the example-robot-data package (extra ``robots``).
EXAMPLE_ROBOT_DATA = "example-robot-data:"


def example_robot_data_dir() -> Path:
    """The ``robots`` folder of the installed example-robot-data package.

    Raises:
        URDFError: The package is not installed (``pip install ucontrol[robots]``).
    """
    for entry in sys.path:
        candidate = Path(entry) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if candidate.is_dir():
            return candidate
    raise URDFError(EXAMPLE_ROBOT_DATA, "example-robot-data is not installed (extra `robots`)")


def resolve_urdf(spec: str, base_dir: Path) -> Path:
    """Absolute path of a robot description file (URDF, MJCF, SDF) named in a scene.

    Args:
        spec: A path relative to ``base_dir`` (or absolute), or
            ``example-robot-data:<path under its robots folder>``.
        base_dir: Folder of the scene file.
    """
    if spec.startswith(EXAMPLE_ROBOT_DATA):
        return example_robot_data_dir() / spec.removeprefix(EXAMPLE_ROBOT_DATA)
    path = Path(spec)
    return path if path.is_absolute() else base_dir / path
