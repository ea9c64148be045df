"""Packages whose names are imported on first use: every listed name resolves, others fail."""

from __future__ import annotations

import importlib
import importlib.util

import pytest

#: Packages whose ``__getattr__`` imports their names from their modules on first use.
PACKAGES = (
    "ucontrol",
    "ucontrol.analysis",
    "ucontrol.campaign",
    "ucontrol.contact",
    "ucontrol.control",
    "ucontrol.design",
    "ucontrol.integrators",
    "ucontrol.model",
    "ucontrol.solvers",
)


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_is_its_module_object(package: str) -> None:
    module = importlib.import_module(package)
    for name in module.__all__:
        if importlib.util.find_spec(f"{package}.{name}") is not None:
            continue  # ucontrol.simulate: the submodule, once imported, shadows the function
        value = getattr(module, name)  # an AttributeError if its module is listed wrong
        if isinstance(value, type) or callable(value):  # defined where the package says
            assert getattr(importlib.import_module(value.__module__), name) is value, name


@pytest.mark.parametrize("package", PACKAGES)
def test_an_unknown_name_raises_attribute_error(package: str) -> None:
    module = importlib.import_module(package)
    with pytest.raises(AttributeError, match=f"module '{package}' has no attribute 'Nowhere'"):
        _ = module.Nowhere
