"""Monte Carlo draws of restitution and of the controller's masses compile nothing new.

Restitution is an input of the compiled Moreau–Jean free step and the bodies' inertias an input
of the Brogliato law's symbolic kinematics, so the libraries the first draw compiled serve the
next draws. Each draw's run is checked against the reference stages (``UCONTROL_NO_COMPILE=1``:
Pinocchio on the mass-scaled model, numpy's impact law with the drawn restitution), so a
value that did not reach the library would show.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from ucontrol.campaign.overrides import apply_overrides
from ucontrol.model.compile_cache import CACHE_ENV
from ucontrol.model.compiled_function import NO_COMPILE_ENV, compilation_possible
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

#: Largest difference per log field between the compiled and the reference run (the
#: tolerances of tests/test_paths_agree.py: round-off of the same mathematics in another order).
TOLERANCES = {"q": 1e-11, "v": 1e-9, "u": 1e-9, "impulse": 1e-9}
#: Two draws of the Monte Carlo of experiments/campaign_two_link.py.
DRAWS = [
    {"contacts.0.restitution": 0.2, "controller.model.mass_scale": 0.9},
    {"contacts.0.restitution": 0.7, "controller.model.mass_scale": 1.15},
]


def _run(overrides: dict[str, float]) -> dict[str, np.ndarray]:
    path = builtin_scene("two_link_one_constraint")
    table = tomllib.loads(path.read_text())
    table["duration"] = 6.0  # through the first impacts
    table = apply_overrides(table, overrides)
    scene = Scene.from_dict(table, base_dir=path.parent, default_name=path.stem)
    log = simulate(scene, progress=False).log
    assert len(log.impacts.t) > 0
    return {field: np.asarray(getattr(log, field)) for field in TOLERANCES}


@pytest.mark.skipif(not compilation_possible(), reason="no C compiler")
def test_draws_load_the_first_draws_libraries_and_match_the_reference(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    libraries = []
    for overrides in DRAWS:
        compiled = _run(overrides)
        libraries.append(sorted(p.name for p in tmp_path.glob("casadi/*.so")))
        with monkeypatch.context() as reference_env:
            reference_env.setenv(NO_COMPILE_ENV, "1")
            reference = _run(overrides)
        for field, tolerance in TOLERANCES.items():
            assert compiled[field].shape == reference[field].shape, field
            difference = float(np.max(np.abs(compiled[field] - reference[field])))
            assert difference <= tolerance, (overrides, field, difference)
    stems = {name.rsplit("_", 1)[0] for name in libraries[0]}
    assert {"free_step", "brogliato_law"} <= stems  # the draws' laws ran compiled
    assert libraries[1] == libraries[0]  # and the second draw compiled nothing
