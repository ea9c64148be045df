"""Every shipped scene through the reference stages and through the fast paths, field by field.

The equivalence harness of the step (docs/moreau_jean.md, "Paths"): each scene runs once with
``UCONTROL_NO_COMPILE=1`` — the readable reference of every stage: Pinocchio's dynamics and
constraint rows, the numpy step, the interpreted controller laws — and once as a user's run
takes it, with every generated fast path its step and controller allow; the logs must agree
within the named tolerances below. Step-level comparisons from random states are in
tests/integrators/test_compiled_free_step.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from ucontrol.scene import load_scene
from ucontrol.scene.builtin_scenes import builtin_scenes
from ucontrol.simulate import simulate

#: Simulated time of each run, at most, in [s] (the scene's own duration when shorter).
DURATION = 1.0
#: Largest difference accepted per log field, in its unit ([m] or [rad], [m/s] or [rad/s],
#: [N m] or [N], [N s], [J]). Round-off of the same mathematics computed in another order,
#: carried through impacts: over 2 s of every scene the largest measured differences were
#: q 4.2e-14, v 3.7e-11, u 1.3e-12, impulse 3.6e-11 (two_link_flexible_drop's stiff joints).
TOLERANCES = {
    "q": 1e-11,
    "v": 1e-9,
    "u": 1e-9,
    "impulse": 1e-9,
    "gap": 1e-11,
    "normal_velocity": 1e-9,
    "energy": 1e-9,
}
#: Every shipped scene.
SCENES = sorted(builtin_scenes())


def _run(name: str) -> tuple[dict[str, np.ndarray], tuple[str, ...]]:
    """The log fields of a short run of scene ``name``, and its integrator's fast paths."""
    scene = load_scene(name)
    paths = getattr(scene.build_integrator(), "fast_paths", ())
    log = simulate(scene, duration=min(DURATION, scene.duration), progress=False).log
    return {field: np.asarray(getattr(log, field)) for field in TOLERANCES}, paths


@pytest.mark.parametrize("name", SCENES)
def test_fast_paths_reproduce_the_reference(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    fast, fast_paths = _run(name)
    monkeypatch.setenv("UCONTROL_NO_COMPILE", "1")
    reference, reference_paths = _run(name)
    assert reference_paths == ()  # the reference stages alone
    for field, tolerance in TOLERANCES.items():
        assert fast[field].shape == reference[field].shape, field
        difference = np.abs(fast[field] - reference[field])
        assert np.all(difference <= tolerance), (field, float(np.max(difference)), fast_paths)


def test_the_fast_paths_run_where_the_step_allows_them() -> None:
    """Not a comparison of the reference with itself: the tracking scenes run compiled."""
    for name in ("two_link_one_constraint", "two_link_flexible_one_constraint", "panda_table"):
        assert "free step" in _run(name)[1], name
    for name in ("two_link_drop", "two_link_flexible_two_constraints"):  # contacts and stops
        assert {"single row", "several rows"} <= set(_run(name)[1]), name
    for name in ("table_drop", "quadruped_stand"):  # free-flyer roots: their rows compiled
        assert "constraint rows" in _run(name)[1], name
    # With friction: the normal and tangential rows, M⁻¹ [Jᵀ Tᵀ] from the free step, with
    # rebounds (Panda's tool, e = 0.5) or plastic contacts (Solo's feet).
    for name in ("panda_table_friction", "solo_landing"):
        assert {"constraint rows", "free step", "tangent rows"} <= set(_run(name)[1]), name
