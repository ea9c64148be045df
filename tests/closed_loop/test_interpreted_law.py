"""The rigid phase-machine law in casadi's virtual machine: the reference it falls back on.

:class:`~ucontrol.control.BrogliatoController` runs its one casadi Function compiled when it
can, and in casadi's virtual machine when compilation is unavailable or disabled
(``UCONTROL_NO_COMPILE=1``). The closed-loop tests run the compiled form; this one runs the
reference through a constrained phase with a 20 % lighter model, where the force loop
closed on the measured contact force divides the open-loop force error r by 1 + K_f.
"""

from __future__ import annotations

import numpy as np
import pytest
from brogliato_runs import DT_ROBUSTNESS, scene

from ucontrol.analysis.cycles import cycle_events
from ucontrol.control import BrogliatoController
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out


def _mean_force_error(force_gain: float) -> float:
    """Mean contact force error [N] mid-way through the first constrained phase."""
    variant = scene("two_link_one_constraint", mass_scale=0.8, force_gain=force_gain)
    with pytest.MonkeyPatch.context() as patch:  # the interpreted law, as without a C compiler
        patch.setenv("UCONTROL_NO_COMPILE", "1")
        controller = variant.build_controller()
    assert isinstance(controller, BrogliatoController)
    duration = controller.cycle.period + 0.5  # [s]
    log = simulate(variant, controller, duration=duration, dt=DT_ROBUSTNESS).log
    cycle = cycle_events(log)[0]
    t_f, t_d = cycle.accumulation_end[0], cycle.takeoff[0]
    middle = (log.t > t_f + (t_d - t_f) / 3) & (log.t < t_d - (t_d - t_f) / 3)
    return float(np.mean(log.contact_force[middle, 0] - log.lambda_d[middle, 0]))


def test_the_interpreted_force_feedback_divides_the_force_error_by_one_plus_kf() -> None:
    open_loop = _mean_force_error(0.0)
    assert abs(open_loop) > 1.0  # [N]
    # Measured: 1 / 1.5 within a relative 4.6e-7 (open-loop error 1.95 N).
    assert _mean_force_error(0.5) / open_loop == pytest.approx(1.0 / 1.5, rel=5e-6)
