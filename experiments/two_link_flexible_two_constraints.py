r"""Brogliato's flexible two-constraint case: ground, corner and wall through joint springs.

The scene is ``robots/two_link_flexible_two_constraints.toml`` (DESIGN §5): the cycle of the
rigid two-constraint case (upper-left quarter of the circle of centre (0.7, 0) m and radius
0.5 m, period 10 s; ground [2.5, 7.5] s and wall [5, 10] s of each period, λ_d = 10 N) run by
the two-link arm with flexible joints (links I1 = I2 = 0.5 kg m², K = 2000 N m/rad,
B = 0.1 kg m²), e = 0, with the passivity-based law γ1 = 10, γ2 = 1, K_f = 0.5;
q0 = (1.5, -0.9, 1.5, -0.9) rad (links, motors).

Run: ``python experiments/two_link_flexible_two_constraints.py --cycles 3 --dt 1e-3``.
"""

from __future__ import annotations

from collections.abc import Sequence

from cycle_case import run_case

from ucontrol.simulate import SimulationResult


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    return run_case("two_link_flexible_two_constraints", __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
