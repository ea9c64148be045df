r"""The Panda lands on a table, slides along it under force control and takes off, several times.

The scene is ``robots/panda_table.toml``: the Franka Panda of example-robot-data (7 arm joints
and 2 fingers, nq = nv = 9) tracks with its tool centre point ``panda_hand_tcp`` a vertical
circle of centre (0.5, 0, 0.2) m and radius 0.1 m (period 4 s) whose lower half lies below the
frictionless table z >= 0.2 m (e = 0.5). The task X = (z - 0.2, x, y) has three coordinates; the
null space (six directions) holds the initial posture. γ1 = 50 N s/m, γ2 = 10 1/s, K_f = 0.5,
λ_d = 10 N.

Prints one row per cycle and writes ``panda_table_path.png`` (x–z plane) and
``panda_table_time.png`` into ``--figures``.

Run: ``python experiments/panda_table.py --cycles 3 --dt 1e-3`` (needs the ``robots`` extra).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from cycle_case import run_case

from ucontrol.scene import Scene
from ucontrol.simulate import SimulationResult


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    return run_case("panda_table", __doc__.splitlines()[0], argv, plane=(0, 2), report=_excursion)


def _excursion(result: SimulationResult, scene: Scene) -> str:
    """How far the seven arm joints moved from the posture."""
    arm = slice(0, 7)
    excursion = np.abs(result.log.q[:, arm] - scene.q0[arm]).max()  # [rad]
    return f"largest arm-joint excursion from the posture: {excursion:.3f} rad"


if __name__ == "__main__":
    main()
