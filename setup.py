"""Packaging: the packages of the tree, and the `robots/` folder as ``ucontrol.robots``.

The rest of the configuration is in ``pyproject.toml``; ``packages`` is set here because
setuptools' ``find`` in ``pyproject.toml`` cannot add a package mapped from another folder.
"""

from setuptools import find_packages, setup

setup(packages=[*find_packages(include=["ucontrol", "ucontrol.*"]), "ucontrol.robots"])
