"""A reset Moreau–Jean integrator runs as a new one: its step memory and warm starts forgotten.

The contact solvers start each solve from the last one's solution (proxsuite's QP objects, the
Coulomb fixed point's last impulses), which changes the last bits of the next solves. On the
quadruped standing on four feet (frictionless, four-row QPs: the reference stages, whose every
multi-row step solves its QP; the compiled path's active-set start skips most) and the block on
an incline with spatial friction (four frictional corners), a second run after renewing the step
memory alone differs from a new integrator's by up to 2.3e-12 rad in (q, v) and 8.9e-16
(measured); after :meth:`MoreauJean.reset` it is equal bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ucontrol.integrators.moreau_jean import MoreauJean
from ucontrol.integrators.step_stages import fresh_memory
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: Steps of each run: the feet and corners land and are held (multi-row solves).
STEPS = 300


def _run(integrator: MoreauJean, scene: Scene) -> np.ndarray:
    """(q, v, impulses) of each step from the scene's initial state, without input, stacked."""
    q, v = scene.q0.copy(), scene.v0.copy()
    tau = np.zeros(v.size)
    rows = []
    for k in range(STEPS):
        outcome = integrator.step(integrator.evaluate(q, v, k * integrator.dt), tau)
        q, v = outcome.q, outcome.v
        rows.append(np.concatenate((q, v, outcome.impulse)))
    return np.array(rows)


@pytest.mark.parametrize(
    ("name", "compiled"), [("quadruped_stand", False), ("block_incline_spatial", True)]
)
def test_a_reset_integrator_reproduces_a_new_one(name: str, compiled: bool) -> None:
    scene = Scene.from_toml(ROBOTS / f"{name}.toml")
    fresh = _run(scene.build_integrator(compiled=compiled), scene)
    integrator = scene.build_integrator(compiled=compiled)
    assert isinstance(integrator, MoreauJean)
    _run(integrator, scene)
    integrator.memory = fresh_memory(integrator.constraints.size)  # the memory alone
    memory_only = _run(integrator, scene)
    # The set-up is the one the reset is for: the warm starts change the run.
    assert not np.array_equal(memory_only, fresh)
    integrator.reset()
    assert np.array_equal(_run(integrator, scene), fresh)
