"""A scene: a robot, what it can touch, its initial state, and how to run it."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ucontrol._validation import toml_error_message
from ucontrol.exceptions import SceneError
from ucontrol.scene.controller_builders import build_controller, controller_view
from ucontrol.scene.integrator_builders import build_integrator
from ucontrol.scene.scene_data import SceneData
from ucontrol.scene.scene_table import check_reference, scene_fields

if TYPE_CHECKING:
    from ucontrol.contact.constraint_set import ConstraintSet
    from ucontrol.control.controller import Controller
    from ucontrol.plant import Integrator


@dataclass(frozen=True, kw_only=True)
class Scene(SceneData):
    """A robot, what it can touch, its initial state, and how to run it.

    The fields (:class:`~ucontrol.scene.scene_data.SceneData`, checked when the scene is made)
    and what is built from them: the integrator and the controller, each when a run asks.
    """

    def build_integrator(self, dt: float | None = None, *, compiled: bool = True) -> Integrator:
        """The integrator of this scene, optionally with another step ``dt`` in [s].

        ``compiled = False`` runs the reference stages of a Moreau–Jean step alone, without
        its generated fast paths (which also stay off with ``UCONTROL_NO_COMPILE`` set).

        Raises:
            InvalidParameterError: The scene has friction and the integrator is not
                ``moreau_jean`` (the others are frictionless), or a ``qpsolvers:`` contact
                solver was asked for a scene with friction.
        """
        return build_integrator(self, dt, compiled=compiled)

    def build_controller(self) -> Controller:
        """The controller declared by the scene's ``[controller]`` table."""
        return build_controller(self)

    def believed_constraints(self) -> ConstraintSet:
        """The constraints as the controller believes them: its ``[controller.model]`` surfaces.

        The same rows, names and order as :attr:`constraints`, on the surfaces of the
        controller's model where ``[controller.model.surfaces]`` declares them (the scene's
        elsewhere); :attr:`constraints` itself without a ``[controller.model]`` table. The
        measurement-only observer (``[sensors] observer = "momentum"``) computes the gaps and
        normal velocities the controller sees on these.
        """
        model = self.controller.get("model")
        if model is None:
            return self.constraints
        return controller_view(self, model).constraints

    @classmethod
    def from_toml(cls, path: str | Path) -> Scene:
        """Load a scene file; relative URDF paths are taken from the file's folder.

        Raises:
            SceneError: The file is missing or not valid TOML.
            UnknownKeyError: A table holds keys the format does not define.
        """
        path = Path(path)
        if not path.is_file():
            raise SceneError(f"scene file {str(path)!r} does not exist")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as error:
            raise SceneError(f"scene file {str(path)!r} is not UTF-8 text: {error}") from error
        except OSError as error:
            raise SceneError(f"scene file {str(path)!r} cannot be read: {error}") from error
        try:
            table = tomllib.loads(text)
        except tomllib.TOMLDecodeError as error:
            reason = toml_error_message(error, text)
            raise SceneError(f"scene file {str(path)!r} is not valid TOML: {reason}") from error
        scene = cls.from_dict(table, base_dir=path.parent, default_name=path.stem)
        return replace(scene, source=path.resolve())

    @classmethod
    def from_dict(
        cls, table: Mapping[str, Any], *, base_dir: Path, default_name: str = "scene"
    ) -> Scene:
        """Build a scene from its parsed TOML table (see :meth:`from_toml`).

        Every table is checked (keys, values, the controller's keys) before the scene is
        built; relative URDF paths are taken from ``base_dir``.
        """
        fields = scene_fields(table, base_dir=base_dir, default_name=default_name)
        reference = fields.pop("reference")
        scene = cls(**fields)
        if reference is None:
            return scene
        return replace(scene, reference=check_reference(reference, scene.contacts))
