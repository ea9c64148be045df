"""Declarative scenes: a TOML file -> robot, constraints, integrator and controller.

A scene builds only what it declares. Reading the file (:mod:`~ucontrol.scene.scene_table`)
checks every table before anything is built; the integrator and the controller are built by
one builder per name (:mod:`~ucontrol.scene.integrator_builders`,
:mod:`~ucontrol.scene.controller_builders`) when a run asks for them.
"""

from ucontrol.integrators.methods import INTEGRATORS
from ucontrol.scene.builtin_scenes import DEFAULT_SCENE, builtin_scene, builtin_scenes, load_scene
from ucontrol.scene.controller_builders import CONTROLLERS
from ucontrol.scene.integrator_settings import IntegratorSettings
from ucontrol.scene.scene import Scene
from ucontrol.scene.scene_table import REFERENCES

__all__ = [
    "CONTROLLERS",
    "DEFAULT_SCENE",
    "INTEGRATORS",
    "REFERENCES",
    "IntegratorSettings",
    "Scene",
    "builtin_scene",
    "builtin_scenes",
    "load_scene",
]
