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


def test_a_reset_integrator_reproduces_a_new_one() -> None:
    """Frictionless, bit for bit: the quadruped's QPs give the same bits from the same start."""
    scene = Scene.from_toml(ROBOTS / "quadruped_stand.toml")
    fresh, _ = _run(scene.build_integrator(compiled=False), scene)
    integrator = scene.build_integrator(compiled=False)
    assert isinstance(integrator, MoreauJean)
    _run(integrator, scene)
    integrator.memory = fresh_memory(integrator.constraints.size)  # the memory alone
    memory_only, _ = _run(integrator, scene)
    # The set-up is the one the reset is for: the warm starts change the run.
    assert not np.array_equal(memory_only, fresh)
    integrator.reset()
    assert np.array_equal(_run(integrator, scene)[0], fresh)


def test_a_reset_coulomb_solver_starts_cold_as_a_new_one() -> None:
    """With friction, the same QPs as a new integrator, step by step, and the same run.

    Not bit for bit: proxsuite's Tresca QP from the same inputs differs between its instances
    by up to 4e-13 N s (the alignment of its own memory; measured over fresh integrators), which
    the polish leaves at 1.2e-14. The warm start's trace is in the QPs each step runs: a
    remembered solution is polished by Newton without a QP, a cold start solves one first.
    """
    scene = Scene.from_toml(ROBOTS / "block_incline_spatial.toml")
    fresh, fresh_qps = _run(scene.build_integrator(compiled=True), scene)
    integrator = scene.build_integrator(compiled=True)
    assert isinstance(integrator, MoreauJean)
    _run(integrator, scene)
    integrator.memory = fresh_memory(integrator.constraints.size)  # the memory alone
    _, memory_only_qps = _run(integrator, scene)
    assert memory_only_qps != fresh_qps  # the last solutions kept: fewer QPs
    integrator.reset()
    reset, reset_qps = _run(integrator, scene)
    assert reset_qps == fresh_qps
    np.testing.assert_allclose(reset, fresh, rtol=0.0, atol=1e-12)
