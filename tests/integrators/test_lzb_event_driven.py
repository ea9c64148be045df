"""The LZB impact law as the event-driven integrator's impact law (``impact_law = "lzb"``)."""

from __future__ import annotations

import tomllib
from typing import Any

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError, SimulationError, SolverError
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

ROBOTS = builtin_scene().parent


def _scene(scene: str, **integrator: Any) -> Scene:
    table = tomllib.loads((ROBOTS / f"{scene}.toml").read_text())
    table.pop("reference", None)
    table["integrator"].update(integrator)
    return Scene.from_dict(table, base_dir=ROBOTS)


def test_cradle_disperses_its_energy_and_keeps_momentum_and_energy() -> None:
    """Three touching balls, the first at 1 m/s, elastic Hertz contacts (m = 0.1 kg)."""
    lzb = simulate(_scene("newton_cradle", impact_law="lzb"), duration=0.05).log
    newton = simulate(_scene("newton_cradle"), duration=0.05).log
    v = lzb.v[-1]
    assert v.sum() == pytest.approx(1.0, abs=1e-9)  # momentum (equal masses) [kg m/s / m]
    assert (v**2).sum() == pytest.approx(1.0, abs=1e-9)  # energy, energetic restitution 1
    # The energy is dispersed: every ball moves, the last carries most of it.
    np.testing.assert_allclose(v, [-0.0710, 0.0764, 0.9945], atol=2e-4)
    assert not np.allclose(newton.v[-1], v, atol=1e-2)  # Newton's law gives another outcome


def test_one_contact_lzb_is_newtons_law() -> None:
    """With a single contact the energetic coefficient is Newton's: the same bouncing ball."""
    newton = simulate(_scene("ball", name="event_driven"), duration=1.5).log
    lzb = simulate(_scene("ball", name="event_driven", impact_law="lzb"), duration=1.5).log
    assert int((newton.impulse[:, 0] > 0).sum()) >= 1
    np.testing.assert_allclose(lzb.q, newton.q, atol=1e-9)
    np.testing.assert_allclose(lzb.v, newton.v, atol=1e-8)


@pytest.mark.parametrize(
    ("settings", "match"),
    [
        ({"impact_law": "lzb", "name": "moreau_jean"}, r"impact_law.*'lzb'"),
        ({"impact_law": "routh"}, r"'routh'"),
        ({"impact_law": "lzb", "lzb_exponent": -1.0}, r"lzb_exponent"),
        ({"impact_law": "lzb", "lzb_impulse_step": 0.0}, r"lzb_impulse_step"),
        ({"impact_law": "lzb", "lzb_max_steps": 0}, r"lzb_max_steps"),
        ({"impact_law": "lzb", "lzb_max_steps": 2.5}, r"lzb_max_steps"),
    ],
)
def test_impact_law_settings_are_checked(settings: dict[str, Any], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        _scene("newton_cradle", **settings).build_integrator()


def test_lzb_max_steps_reaches_the_law_of_the_scene() -> None:
    # the cradle's impact takes more than 3 solve_ivp steps: the run stops at it, named
    with pytest.raises(SimulationError, match=r"max_steps = 3") as caught:
        simulate(_scene("newton_cradle", impact_law="lzb", lzb_max_steps=3), duration=0.05)
    assert isinstance(caught.value.__cause__, SolverError)
    law = _scene("newton_cradle", impact_law="lzb", lzb_max_steps=7).build_integrator()
    assert law.impact_law.max_steps == 7  # type: ignore[attr-defined]


@pytest.mark.slow
def test_lzb_bouncing_ball_comes_to_rest_through_its_accumulation_like_newtons() -> None:
    """With e = 0.5 the rebounds accumulate at t∞ = t1 (1 + 2e / (1 - e)) = 3 t1 = 1.355 s.

    Rebounds slower than ``zeno_velocity`` are plastic under either law (the accumulation
    rule), so the LZB ball comes to rest at t∞ as Newton's does, and both runs agree.
    """
    runs = {}
    for law in ("newton", "lzb"):
        table = tomllib.loads((ROBOTS / "ball.toml").read_text())
        table.pop("reference", None)
        table["contacts"][0]["restitution"] = 0.5
        table["integrator"].update(name="event_driven", impact_law=law)
        runs[law] = simulate(Scene.from_dict(table, base_dir=ROBOTS), duration=2.0).log
    t_rest = 3.0 * np.sqrt(2.0 * 1.0 / 9.81)  # [s]
    log = runs["lzb"]
    resting = log.t > t_rest + 0.01
    np.testing.assert_allclose(log.q[resting, 0], 0.1, atol=1e-9)  # on the ground (r = 0.1 m)
    np.testing.assert_allclose(log.v[resting, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(log.q, runs["newton"].q, atol=1e-9)
