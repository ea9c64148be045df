r"""Brogliato's flexible one-constraint case: the arm lands, slides and takes off through springs.

The scene is ``robots/two_link_flexible_one_constraint.toml`` (DESIGN §5): the two-link arm with
flexible joints (links I1 = I2 = 0.5 kg m², K = 2000 N m/rad, B = 0.1 kg m²) tracks with its end
effector the circle of centre (0.4, 0) m and radius 0.3 m (period 10 s) whose lower half lies
below the ground y >= 0 (e = 0); the passivity-based law (γ1 = 10, γ2 = 5, K_f = 0.5) drives the
motors; q0 = (0.9, -1.5, 0.9, -1.5) rad (links, motors). Each cycle approaches the ground from
τ0 = 4.2 s + 10 k s, lands, slides with λ_d = 5 N from (0.1, 0) and takes off at
t_d = 10 (k + 1) s at (0.7, 0).

Prints one row per cycle and writes ``two_link_flexible_one_constraint_path.png`` and
``two_link_flexible_one_constraint_time.png`` into ``--figures``.

Run: ``python experiments/two_link_flexible_one_constraint.py --cycles 3 --dt 1e-3``.
"""

from __future__ import annotations

from collections.abc import Sequence

from cycle_case import run_case

from ucontrol.simulate import SimulationResult


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    return run_case("two_link_flexible_one_constraint", __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
