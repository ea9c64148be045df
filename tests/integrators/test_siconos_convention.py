"""Newton's law as Siconos applies it (``newton_law = "siconos"``) reproduces its runs.

Siconos' MoreauJeanOSI applies the law 0 <= u+ + e u- ⟂ P >= 0 to every constraint of the active
set, separating ones included; ucontrol's default applies restitution to closing constraints
only. The reference is Siconos' published output of its BouncingBallTS example
(tests/data/siconos/README.md): m = 1, g = 9.81, q0 = 1, e = 0.9, θ = 1/2, h = 5 ms, 10 s.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate

REFERENCE = Path(__file__).resolve().parents[1] / "data" / "siconos" / "BouncingBallTS.ref"


def test_siconos_bouncing_ball_is_reproduced_to_rounding() -> None:
    reference = np.loadtxt(REFERENCE, skiprows=1)  # t, q, v, impulse, multiplier
    log = simulate(load_scene("ball_siconos")).log
    assert len(log) == len(reference) == 2001
    np.testing.assert_allclose(log.t, reference[:, 0], rtol=0, atol=1e-12)
    # Measured: 2.9e-15 m, 2.2e-14 m/s, 2.7e-14 N s over the whole run, the accumulation
    # (from ~8.5 s) and the rest included.
    np.testing.assert_allclose(log.q[:, 0], reference[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.v[:, 0], reference[:, 2], rtol=0, atol=1e-12)
    # Siconos logs at t_k the impulse of the step that ends there; ucontrol that of the step
    # that starts there.
    np.testing.assert_allclose(log.impulse[:-1, 0], reference[1:, 3], rtol=0, atol=1e-12)
    assert np.count_nonzero(reference[:, 3]) > 20  # impacts and the resting phase


def test_the_default_law_differs_only_where_a_constraint_separates() -> None:
    table = tomllib.loads((builtin_scene("ball_siconos")).read_text())
    del table["integrator"]["newton_law"]
    default = simulate(Scene.from_dict(table, base_dir=builtin_scene().parent)).log
    reference = np.loadtxt(REFERENCE, skiprows=1)
    error = np.abs(default.q[:, 0] - reference[:, 1])
    first = int(np.argmax(error > 1e-12))
    assert reference[first, 0] > 1.0  # the free flights and first impacts agree
    # Then an active constraint separating at t_k gets e = 0 instead of e: measured 3.4e-7 m.
    assert error.max() > 1e-8


def test_unknown_newton_law_is_named() -> None:
    table = tomllib.loads((builtin_scene("ball_siconos")).read_text())
    table["integrator"]["newton_law"] = "poisson"
    with pytest.raises(InvalidParameterError, match=r"newton_law.*'poisson'"):
        Scene.from_dict(table, base_dir=builtin_scene().parent)
