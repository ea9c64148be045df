"""Acceptance of issue 6: orders, event-driven accuracy, equal-error times, compliant limit."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ball_scene

from ucontrol.convergence import run_convergence


@pytest.mark.slow
def test_moreau_jean_is_first_order_on_the_ball() -> None:
    for restitution in (0.9, 0.5):
        study = run_convergence(ball_scene(restitution), integrators=["moreau_jean"])
        errors = [run.error for run in study.runs]
        assert errors[-1] < errors[0] / 50.0  # h / 100, error / 100 within a factor 2
        assert 0.8 <= study.orders()["moreau_jean"] <= 1.2, study.orders()


@pytest.mark.slow
@pytest.mark.parametrize(("restitution", "bound"), [(0.9, 1e-9), (0.5, 1e-8)])
def test_event_driven_beats_moreau_jean_at_every_tolerance(restitution: float, bound: float):
    study = run_convergence(
        ball_scene(restitution),
        integrators=["moreau_jean", "event_driven"],
        dts=(1e-2, 1e-3, 1e-4),
        tolerances=(1e-4, 1e-8, 1e-12),
    )
    event_driven = study.of("event_driven")
    assert max(run.error for run in event_driven) <= bound
    assert min(run.n_events for run in event_driven) >= (19 if restitution == 0.5 else 4)
    # Reported beside Moreau–Jean's time at the same error, which its runs cannot reach.
    rows = study.equal_error()
    assert len(rows) == len(event_driven)
    best = min(run.error for run in study.of("moreau_jean"))
    for row in rows:
        assert row.extrapolated and row.error < best
        assert row.moreau_jean_s > row.event_driven_s
    assert "moreau_jean at equal error" in study.to_markdown()


@pytest.mark.slow
def test_compliant_tends_to_the_rigid_ball_as_stiffness_grows() -> None:
    stiffnesses = (1e4, 1e5, 1e6, 1e7)
    study = run_convergence(
        ball_scene(0.9), integrators=["compliant"], stiffnesses=stiffnesses, sample_dt=1e-2
    )
    errors = np.array([run.error for run in study.runs])
    assert np.all(np.diff(errors) < 0.0), errors  # monotone in k
    # Penetration and contact time scale as k^(-1/2): so does the error.
    assert -0.7 <= study.orders()["compliant"] <= -0.3, study.orders()
    assert errors[-1] < errors[0] / 10.0
