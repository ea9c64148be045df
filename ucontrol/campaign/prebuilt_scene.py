"""A scene whose integrator a campaign worker built before (:mod:`ucontrol.campaign.build_cache`).

Imported by the task function when a run starts, with the scene layer it extends.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol.scene import Scene

if TYPE_CHECKING:
    from ucontrol.plant import Integrator


class PrebuiltScene(Scene):
    """A :class:`~ucontrol.scene.Scene` that hands out an integrator given to it.

    :meth:`build_integrator` with the scene's own step and the compiled paths returns the
    integrator of :meth:`use_integrator` (built from a scene with the same plant, integrator
    settings and file; reset by the caller); otherwise it builds one as a scene does.
    """

    def use_integrator(self, integrator: Integrator) -> PrebuiltScene:
        """Hand out ``integrator`` from now on; returns this scene."""
        object.__setattr__(self, "_prebuilt_integrator", integrator)
        return self

    def build_integrator(self, dt: float | None = None, *, compiled: bool = True) -> Integrator:
        """The integrator given to :meth:`use_integrator`, or a new one (see the class)."""
        prebuilt: Integrator | None = self.__dict__.get("_prebuilt_integrator")
        if prebuilt is not None and dt is None and compiled:
            return prebuilt
        return super().build_integrator(dt, compiled=compiled)
