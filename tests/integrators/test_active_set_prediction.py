r"""The prediction horizon of Moreau–Jean's active set, pinned on a ball at constant speed.

Step 2 of the scheme puts a constraint in the active set when its gap predicted half a step
ahead, :math:`g_k + \tfrac12 h u_k`, is at most 0. A ball without gravity falling at
:math:`u = -1` m/s from a gap of 10.7 mm (h = 1 ms) reaches that prediction at step 11
(:math:`g_{11} + \tfrac12 h u = -0.8` mm, while :math:`g_{10} + \tfrac12 h u = 0.2` mm), so the
impulse is in the step from :math:`t_{11}`; a one-step horizon would catch it at step 10. The
references are exact: free flight at constant speed, then Newton's law with e = 1/2 and
θ = 1/2 (measured errors 0 to 8.7e-18).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
RADIUS, GAP0, SPEED, H, E = 0.1, 0.0107, 1.0, 1e-3, 0.5


def test_the_impact_comes_at_the_first_step_predicted_closed_at_mid_step() -> None:
    table = {
        "name": "ball",
        "duration": 0.015,
        "robot": {
            "urdf": "ball.urdf",
            "q0": [RADIUS + GAP0],
            "v0": [-SPEED],
            "gravity": [0.0, 0.0, 0.0],
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [{"frame": "ball", "surface": "ground", "radius": RADIUS, "restitution": E}],
        "integrator": {"name": "moreau_jean", "dt": H, "theta": 0.5},
    }
    log = simulate(Scene.from_dict(table, base_dir=ROBOTS, default_name="ball"), progress=False).log
    impulse = log.impulse[:, 0]
    assert np.flatnonzero(impulse).tolist() == [11]  # the step from t_11 alone
    assert abs(impulse[11] - (1.0 + E) * SPEED) <= 1e-15  # m (1 + e)|u|, m = 1 kg
    gap = log.q[:, 0] - RADIUS
    np.testing.assert_allclose(gap[:12], GAP0 - SPEED * H * np.arange(12), rtol=0, atol=1e-15)
    # θ = 1/2: q_12 = q_11 + h (u_11 + u_12) / 2 with u_12 = e |u|
    assert abs(gap[12] - (gap[11] + 0.5 * H * (-SPEED + E * SPEED))) <= 1e-15
    np.testing.assert_allclose(log.v[12:, 0], E * SPEED, rtol=0, atol=1e-15)
