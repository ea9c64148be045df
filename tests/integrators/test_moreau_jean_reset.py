"""A reset Moreau–Jean integrator runs as a new one: its step memory and warm starts forgotten.

The contact solvers start each solve from the last one's solution (proxsuite's QP objects, the
Coulomb fixed point's last impulses), which changes the last bits of the next solves. On the
quadruped standing on four feet (frictionless, four-row QPs: the reference stages, whose every
multi-row step solves its QP; the compiled path's active-set start skips most) and the block on
an incline with spatial friction (four frictional corners), a second run after renewing the step
memory alone differs from a new integrator's by up to 2.3e-12 rad in (q, v) and 8.9e-16
(measured); after :meth:`MoreauJean.reset` the quadruped's run is equal bit for bit, and the
block's runs the same QPs step by step (proxsuite's own round-off differs between instances).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ucontrol.integrators.moreau_jean import MoreauJean
from ucontrol.integrators.step_stages import fresh_memory
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
#: Steps of each run: the feet and corners land and are held (multi-row solves).
STEPS = 300


def _run(integrator: MoreauJean, scene: Scene) -> tuple[np.ndarray, list[int]]:
    """Each step's (q, v, impulses), stacked, and the QPs of its contact solve (-1: none).

    From the scene's initial state, without input; the QPs are the solve's outer iterations.
    """
    q, v = scene.q0.copy(), scene.v0.copy()
    tau = np.zeros(v.size)
    rows, qps = [], []
    for k in range(STEPS):
        outcome = integrator.step(integrator.evaluate(q, v, k * integrator.dt), tau)
        q, v = outcome.q, outcome.v
        rows.append(np.concatenate((q, v, outcome.impulse)))
        qps.append(-1 if outcome.solution is None else outcome.solution.outer_iterations)
    return np.array(rows), qps


Run = tuple[np.ndarray, list[int]]


def _runs(name: str, compiled: bool) -> tuple[Run, Run, Run]:
    """A new integrator's run; a used one's after renewing its memory alone; then after reset."""
    scene = Scene.from_toml(ROBOTS / f"{name}.toml")
    fresh = _run(scene.build_integrator(compiled=compiled), scene)
    integrator = scene.build_integrator(compiled=compiled)
    assert isinstance(integrator, MoreauJean)
    _run(integrator, scene)
    integrator.memory = fresh_memory(integrator.constraints.size)  # the memory alone
    memory_only = _run(integrator, scene)
    integrator.reset()
    return fresh, memory_only, _run(integrator, scene)


def test_a_reset_integrator_reproduces_a_new_one() -> None:
    """Frictionless, bit for bit: the quadruped's QPs give the same bits from the same start."""
    (fresh, _), (memory_only, _), (reset, _) = _runs("quadruped_stand", compiled=False)
    # The set-up is the one the reset is for: the warm starts change the run.
    assert not np.array_equal(memory_only, fresh)
    assert np.array_equal(reset, fresh)


def test_a_reset_coulomb_solver_starts_cold_as_a_new_one() -> None:
    """With friction, the same QPs as a new integrator, step by step, and the same run.

    Not bit for bit: proxsuite's Tresca QP from the same inputs differs between its instances
    by up to 4e-13 N s (the alignment of its own memory; measured over fresh integrators), which
    the polish leaves at 1.2e-14. The warm start's trace is in the QPs each step runs: a
    remembered solution is polished by Newton without a QP, a cold start solves one first.
    """
    (fresh, fresh_qps), (_, memory_only_qps), (reset, reset_qps) = _runs(
        "block_incline_spatial", compiled=True
    )
    assert memory_only_qps != fresh_qps  # the last solutions kept: fewer QPs
    assert reset_qps == fresh_qps
    np.testing.assert_allclose(reset, fresh, rtol=0.0, atol=1e-12)
