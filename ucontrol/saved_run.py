"""A run saved on disk: its ``log.npz`` and the scene it ran, for replay and figures."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ucontrol.exceptions import InvalidParameterError, RunNotFoundError, SceneError
from ucontrol.log import Log
from ucontrol.scene import Scene, load_scene

#: Name of the log file in a run directory (see docs/outputs.md).
LOG_FILE = "log.npz"


@dataclass(frozen=True)
class SavedRun:
    """The output directory of ``ucontrol run`` (or ``simulate(..., out=DIR)``), loaded.

    Attributes:
        directory: The run directory.
        log: Its log.
        scene: The scene that ran, or None when it is not known (a scene built in code, or a
            scene file that has moved; see :meth:`load`).
    """

    directory: Path
    log: Log
    scene: Scene | None

    @classmethod
    def load(cls, directory: str | Path, scene: str | Path | None = None) -> SavedRun:
        """Load ``directory/log.npz`` and the scene of the run.

        The scene is ``scene`` when given, else the file named by the log's ``scene_path``
        metadata (written by :func:`ucontrol.simulate` for scenes loaded from a file) if it
        still exists, else None.

        Args:
            directory: The run directory.
            scene: Scene file to use instead of the one recorded in the log.

        Raises:
            RunNotFoundError: ``directory`` holds no ``log.npz``.
            SceneError: ``scene`` is not a valid scene file.
            InvalidParameterError: The scene does not match the log (configuration size or
                constraint names differ).
        """
        directory = Path(directory)
        if not (directory / LOG_FILE).is_file():
            raise RunNotFoundError(str(directory))
        log = Log.load(directory / LOG_FILE)
        recorded = log.metadata.get("scene_path")
        if scene is not None:
            path: Path | None = Path(scene)
        elif recorded is not None and Path(recorded).is_file():
            path = Path(recorded)
        else:
            path = None
        if path is None:
            return cls(directory, log, None)
        loaded = load_scene(path)
        nq, names = log.q.shape[1], log.constraint_names
        if loaded.robot.nq != nq or loaded.constraints.names != names:
            raise InvalidParameterError(
                "scene",
                str(path),
                f"the scene of the run in {str(directory)!r} (nq = {nq}, constraints {names}); "
                f"it has nq = {loaded.robot.nq}, constraints {loaded.constraints.names}",
            )
        return cls(directory, log, loaded)

    def require_scene(self) -> Scene:
        """The scene of the run.

        Raises:
            SceneError: The scene is unknown: the log names no scene file (a scene built in
                code), or names one that no longer exists.
        """
        if self.scene is not None:
            return self.scene
        recorded = self.log.metadata.get("scene_path")
        reason = (
            "does not name its scene file (a scene built in code)"
            if recorded is None
            else f"names the scene file {recorded!r}, which no longer exists"
        )
        raise SceneError(
            f"the log in {str(self.directory)!r} {reason}; pass the scene file with --scene FILE"
        )
