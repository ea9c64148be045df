r"""Brogliato's rigid one-constraint case: a two-link arm lands, slides on the ground, takes off.

The scene is ``robots/two_link_one_constraint.toml`` (DESIGN §5): the end effector tracks the
circle of centre (0.65, 0) m and radius 0.1 m (period 10 s) whose lower half lies below the
ground y >= 0 (e = 0.7); γ1 = 8 N s/m, γ2 = 7 1/s, K_f = 0.5, q0 = (0.9, -1.6) rad. Each cycle
approaches the ground from τ0 = 4.2 s + 10 k s, lands (t0), lets the impacts accumulate (t_f),
slides with the desired force λ_d = 5 N and takes off at t_d = 10 (k + 1) s.

Prints one row per cycle (events, V(τ0), errors) and writes ``two_link_one_constraint_path.png``
and ``two_link_one_constraint_time.png`` into ``--figures``.

Run: ``python experiments/two_link_one_constraint.py --cycles 3 --dt 1e-3``.
"""

from __future__ import annotations

from collections.abc import Sequence

from cycle_case import run_case

from ucontrol.simulate import SimulationResult


def main(argv: Sequence[str] | None = None) -> SimulationResult:
    """Run the case; return the simulation result (log and summary)."""
    return run_case("two_link_one_constraint", __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
