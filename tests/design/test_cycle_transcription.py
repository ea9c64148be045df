"""The transcription's model Functions against Pinocchio's dynamics, small and large robots."""

from __future__ import annotations

import numpy as np
import pytest
from two_link_design import ROBOTS, pinocchio_terms

from ucontrol.design import DesignTask
from ucontrol.design.cycle_transcription import CycleTranscription

#: Relative tolerance: M's condition number (≤ 1e3 at these states) times rounding.
_TOLERANCE = 1e-10


@pytest.mark.parametrize("name", ["two_link_one_constraint_task", "panda_table_task"])
def test_contact_force_and_impact_equal_pinocchio_solves(
    name: str, rng: np.random.Generator
) -> None:
    task = DesignTask.from_toml(ROBOTS / f"{name}.toml")
    transcription = CycleTranscription(task)
    f, nv = transcription.functions, transcription.nv
    assert transcription.friction == 0.0  # W = J_n in the reference below
    for _ in range(3):
        q, v, tau = rng.uniform(-1.0, 1.0, (3, nv))
        P = rng.uniform(0.0, 1.0)
        M, h, J_n, drift, _ = pinocchio_terms(task, q, v)
        a_free = np.linalg.solve(M, tau - h)
        Minv_Jt = np.linalg.solve(M, J_n)
        force = -(J_n @ a_free + drift) / (J_n @ Minv_Jt)  # [N]
        x = np.concatenate((q, v))
        assert float(f["contact_force"](x, tau)) == pytest.approx(force, rel=_TOLERANCE)
        assert float(f["normal_acceleration"](x, tau)) == pytest.approx(
            J_n @ a_free + drift, rel=_TOLERANCE, abs=_TOLERANCE
        )
        np.testing.assert_allclose(
            np.asarray(f["impact"](q, v, P)).ravel(),
            v + Minv_Jt * P,
            rtol=_TOLERANCE,
            atol=_TOLERANCE,
        )
