"""summary.json's contact-solve timings: closed forms inside the compiled step counted apart."""

from __future__ import annotations

import pytest
from conftest import ball_scene

from ucontrol.model.compiled_function import NO_COMPILE_ENV
from ucontrol.simulate import simulate


def test_untimed_closed_form_solves_are_counted_apart(monkeypatch: pytest.MonkeyPatch) -> None:
    # The ball's contact steps have one active row. Compiled (a C compiler here, as in CI),
    # Moreau-Jean solves them in closed form inside its compiled step, not timed apart; with
    # UCONTROL_NO_COMPILE the solver object solves and times each one.
    compiled = simulate(ball_scene(0.9), duration=3.0).summary
    monkeypatch.setenv(NO_COMPILE_ENV, "1")
    reference = simulate(ball_scene(0.9), duration=3.0).summary
    assert compiled["contact_solves"] == reference["contact_solves"] >= 5  # 5 bounces in 3 s
    assert reference["untimed_contact_solves"] == 0
    assert reference["contact_solve_time_s"] > 0.0 and reference["mean_contact_solve_us"] > 0.0
    assert reference["max_contact_solve_us"] >= reference["mean_contact_solve_us"]
    assert compiled["untimed_contact_solves"] == compiled["contact_solves"]
    assert compiled["contact_solve_time_s"] == 0.0
    # no mean or maximum made of zeros: those solves were not measured
    assert compiled["mean_contact_solve_us"] is None and compiled["max_contact_solve_us"] is None
