r"""Brogliato's rigid two-constraint case: ground, corner and wall, cycle after cycle.

The scene is ``robots/two_link_two_constraints.toml`` (DESIGN §5): the end effector of the
two-link arm runs the upper-left quarter of the circle of centre (0.7, 0) m and radius 0.5 m
(period 10 s) in free motion, lands on the ground y >= 0 at (0.2, 0), slides to the corner
against the wall x <= 0.7 (both e = 0.7), enters the corner through a second transition, slides
up the wall and takes off at (0.7, 0.5); γ1 = γ2 = 15, K_f = 0.5, q0 = (1.5, -0.9) rad. Both
task coordinates are gaps, X = (y, 0.7 - x).

Every cycle is built from the declared contact phases only (ground [2.5, 7.5] s, wall
[5, 10] s of the period), never from values left by the previous cycle, so that cycle k + 1
starts where cycle k would: the table printed has one row per cycle and contact.

Run: ``python experiments/two_link_two_constraints.py --cycles 3 --dt 1e-3``.
"""

from __future__ import annotations

from collections.abc import Sequence

from cycle_case import run_case

from ucontrol.simulate import SimulationResult


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    return run_case("two_link_two_constraints", __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
