"""Packaging: the packages, ``robots/`` as ``ucontrol.robots``, the optional C extension.

The rest of the configuration is in ``pyproject.toml``; ``packages`` is set here because
setuptools' ``find`` in ``pyproject.toml`` cannot add a package mapped from another folder.
The extension (``ucontrol/model/_native_call.c``) is optional: without a C compiler the
package installs and compiled calls go through ctypes (``ucontrol/model/native_call.py``).
"""

from setuptools import Extension, find_packages, setup

setup(
    packages=[*find_packages(include=["ucontrol", "ucontrol.*"]), "ucontrol.robots"],
    ext_modules=[
        Extension(
            "ucontrol.model._native_call",
            ["ucontrol/model/_native_call.c"],
            extra_compile_args=["-O2"],
            optional=True,
        )
    ],
)
