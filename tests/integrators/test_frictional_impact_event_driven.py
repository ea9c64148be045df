"""Poisson's and the energetic law as event_driven's impact laws (frictionless contacts)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError, ShapeError, SimulationError
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate

_SCENES = {name: load_scene(builtin_scene(name)) for name in ("ball", "newton_cradle")}


def _scene(scene: str, **integrator: Any) -> Scene:
    """A shipped scene with its ``[integrator]`` settings changed (checked again)."""
    base = _SCENES[scene]
    return dataclasses.replace(base, integrator=dataclasses.replace(base.integrator, **integrator))


@pytest.mark.parametrize("law", ["poisson", "energetic"])
def test_single_contact_laws_are_newtons_without_friction(law: str) -> None:
    """A bouncing ball: Poisson's and Stronge's coefficients give Newton's rebounds."""
    newton = simulate(_scene("ball", name="event_driven"), duration=1.5).log
    other = simulate(_scene("ball", name="event_driven", impact_law=law), duration=1.5).log
    assert int((newton.impulse[:, 0] > 0).sum()) >= 2
    np.testing.assert_allclose(other.impulse, newton.impulse, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(other.v, newton.v, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(other.q, newton.q, rtol=0.0, atol=1e-12)


def test_energetic_law_passes_simultaneous_impacts_to_lzb() -> None:
    """Newton's cradle (touching balls): the energetic law is LZB's at simultaneous impacts."""
    lzb = simulate(_scene("newton_cradle", impact_law="lzb"), duration=0.05).log
    energetic = simulate(_scene("newton_cradle", impact_law="energetic"), duration=0.05).log
    np.testing.assert_allclose(energetic.v, lzb.v, rtol=0.0, atol=1e-12)


def test_poisson_refuses_simultaneous_impacts() -> None:
    with pytest.raises(SimulationError) as caught:
        simulate(_scene("newton_cradle", impact_law="poisson"), duration=0.05)
    cause = caught.value.__cause__
    assert isinstance(cause, InvalidParameterError)
    assert "poisson" in str(cause) and "single contact" in str(cause)


@pytest.mark.parametrize("integrator", ["moreau_jean", "compliant"])
@pytest.mark.parametrize("law", ["poisson", "energetic"])
def test_other_integrators_refuse_the_laws(integrator: str, law: str) -> None:
    with pytest.raises(InvalidParameterError, match=rf"impact_law.*'{law}'"):
        _scene("ball", name=integrator, impact_law=law).build_integrator()


def test_unknown_restitution_law_is_refused() -> None:
    scene = _scene("ball", name="event_driven")
    with pytest.raises(InvalidParameterError, match=r"restitution_law.*'routh'"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, restitution_law="routh")


def test_per_constraint_laws() -> None:
    """One law per constraint: all energetic is the scalar law; mixed laws refuse together."""
    scalar = simulate(_scene("newton_cradle", impact_law="energetic"), duration=0.05).log
    listed = simulate(
        _scene("newton_cradle", impact_law=["energetic", "energetic"]), duration=0.05
    ).log
    np.testing.assert_allclose(listed.v, scalar.v, rtol=0.0, atol=0.0)
    newton = simulate(_scene("newton_cradle"), duration=0.05).log
    listed = simulate(_scene("newton_cradle", impact_law=["newton", "newton"]), duration=0.05).log
    np.testing.assert_allclose(listed.v, newton.v, rtol=0.0, atol=0.0)
    with pytest.raises(SimulationError) as caught:
        simulate(_scene("newton_cradle", impact_law=["energetic", "newton"]), duration=0.05)
    assert "mixed laws" in str(caught.value.__cause__)


@pytest.mark.parametrize(
    ("laws", "error", "match"),
    [
        (["energetic"], ShapeError, r"impact_law"),
        (["energetic", "lzb"], InvalidParameterError, r"impact_law.*'lzb'"),
    ],
)
def test_per_constraint_law_lists_are_checked(laws: list[str], error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        _scene("newton_cradle", impact_law=laws).build_integrator()


def test_restitution_law_list_length_is_checked() -> None:
    scene = _scene("ball", name="event_driven")
    with pytest.raises(ShapeError, match="restitution_law"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, restitution_law=["energetic"] * 5)
