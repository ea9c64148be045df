"""Declarative scenes: a TOML file -> robot, constraints, integrator and controller.

A scene builds only what it declares. Reading the file (:mod:`~ucontrol.scene.scene_table`)
checks every table before anything is built; the integrator and the controller are built by
one builder per name (:mod:`~ucontrol.scene.integrator_builders`,
:mod:`~ucontrol.scene.controller_builders`, with the builders of the longer controller tables
:mod:`~ucontrol.scene.impedance_table` and :mod:`~ucontrol.scene.juggling_table`) when a run
asks for them.
"""

from ucontrol.integrators.methods import INTEGRATORS
from ucontrol.scene.builtin_scenes import DEFAULT_SCENE, builtin_scene, builtin_scenes, load_scene
from ucontrol.scene.controller_builders import CONTROLLERS
from ucontrol.scene.impedance_table import impedance_from_table
from ucontrol.scene.integrator_settings import IntegratorSettings
from ucontrol.scene.juggling_table import juggling_from_table
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
    "impedance_from_table",
    "juggling_from_table",
    "load_scene",
]
