r"""Impact oscillators and their Poincaré maps: the figures of docs/stability.md.

- ``table``: the ball on a sinusoidally vibrating table (e = 0.8, ω = 2π rad/s): the period-1
  orbit found by Newton on the impact map against the closed form, its multipliers by saltation
  matrices and by finite differences, the period-doubling amplitude found by continuation against
  the closed form, and the orbit diagram in the amplitude A (the period-doubling cascade).
- ``oscillator``: the linear impact oscillator (m = k = 1, c = 0.05, F = 1, stop at 0, r = 0.8):
  continuation of the period-1 orbit in ω with its period doubling, orbit diagram in ω; the
  grazing of the non-impacting orbit (stop at 0.5 m, ω = 0.8 rad/s) in F against the free
  amplitude.

Run: ``python experiments/impact_oscillator.py`` (about 1 min; ``--points`` fewer for a
smoke run); writes ``docs/figures/poincare/impact_oscillators.md`` and the two diagrams
``table_diagram.png``, ``oscillator_diagram.png`` (``--out``).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ucontrol.analysis import poincare as pc

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures" / "poincare"
G, W, E = 9.81, 2.0 * math.pi, 0.8  # gravity [m/s²], table frequency [rad/s], restitution
T = 2.0 * math.pi / W  # [s]
OSCILLATOR = {
    "mass": 1.0,
    "damping": 0.05,
    "stiffness": 1.0,
    "force": 1.0,
    "stop": 0.0,
    "restitution": 0.8,
}


def ball_solver(A: float, z: np.ndarray) -> pc.FixedPoint:
    system = pc.vibrating_table_ball(amplitude=A, frequency=W, restitution=E)
    return pc.fixed_point(
        pc.impact_map(system),
        z,
        shift=np.array([T, 0.0, 0.0]),
        jacobian=lambda z: pc.impact_map_jacobian(system, z),
        drop_trivial=1,
    )


def ball_orbit(A: float) -> np.ndarray:
    phase, speed = pc.vibrating_table_period_one(amplitude=A, frequency=W, restitution=E)
    return np.array([phase / W, A * math.sin(phase), speed])


def table(points: int, out: Path) -> list[str]:
    A_flip = pc.vibrating_table_flip_amplitude(frequency=W, restitution=E)
    A = 0.8 * A_flip
    exact = ball_orbit(A)
    found = ball_solver(A, exact + np.array([0.01, 0.0, 0.05]))
    system = pc.vibrating_table_ball(amplitude=A, frequency=W, restitution=E)
    by_differences = pc.finite_difference_jacobian(pc.impact_map(system), found.z)
    fd_multipliers = np.linalg.eigvals(by_differences)
    fd_multipliers = fd_multipliers[np.argsort(-np.abs(fd_multipliers))][:2]
    sorted_multipliers = np.sort_complex(found.multipliers)
    branch = pc.continuation(
        ball_solver, np.linspace(0.7 * A_flip, 1.2 * A_flip, 8), ball_orbit(0.7 * A_flip)
    )
    flip = next(b for b in branch.bifurcations if b.kind == "period_doubling")

    def step(A: float, z: np.ndarray) -> np.ndarray:
        s = pc.vibrating_table_ball(amplitude=A, frequency=W, restitution=E, stick_velocity=1e-6)
        return pc.impact_map(s)(z)

    diagram = pc.orbit_diagram(
        step,
        np.linspace(0.8 * A_flip, 1.45 * A_flip, points),
        ball_orbit(0.8 * A_flip),
        coordinate=lambda z: z[0] % T,
        transient=200,
        keep=64,
    )
    figure = pc.bifurcation_figure(
        diagram,
        [branch],
        coordinate=lambda z: z[0] % T,
        xlabel="table amplitude A [m]",
        ylabel="impact phase t mod T [s]",
        title="Ball on a vibrating table (e = 0.8, ω = 2π rad/s)",
    )
    figure.savefig(out / "table_diagram.png", dpi=120)
    return [
        "## Ball on a vibrating table (e = 0.8, ω = 2π rad/s, g = 9.81 m/s²)",
        "",
        "| quantity | Poincaré tool | closed form | difference |",
        "|---|---|---|---|",
        f"| period-1 orbit at A = {A:.6f} m: (t*, y*, v+) | "
        f"{', '.join(f'{x:.12f}' for x in found.z)} | "
        f"{', '.join(f'{x:.12f}' for x in exact)} | {np.max(np.abs(found.z - exact)):.1e} |",
        f"| multipliers (saltation) | {', '.join(f'{m:.10f}' for m in found.multipliers)} | "
        f"modulus e = {E} | {abs(abs(found.multipliers[0]) - E):.1e} |",
        f"| multipliers (finite differences) | {', '.join(f'{m:.8f}' for m in fd_multipliers)} | "
        f"| {np.max(np.abs(np.sort_complex(fd_multipliers) - sorted_multipliers)):.1e} |",
        f"| period-doubling amplitude [m] | {flip.parameter:.12f} | {A_flip:.12f} | "
        f"{abs(flip.parameter / A_flip - 1):.1e} relative |",
        "",
    ]


def oscillator(points: int, out: Path) -> list[str]:
    solve = pc.stroboscopic_solver(lambda w: pc.impact_oscillator(frequency=w, **OSCILLATOR))

    branch = pc.continuation(solve, np.linspace(2.0, 2.9, 10), np.array([-3.3626, 3.2073]))
    flip = next(b for b in branch.bifurcations if b.kind == "period_doubling")
    at_flip = solve(flip.parameter, flip.z)
    s = pc.impact_oscillator(frequency=flip.parameter, **OSCILLATOR)
    fd = np.linalg.eigvals(pc.finite_difference_jacobian(pc.stroboscopic_map(s), at_flip.z))

    def step(w: float, x: np.ndarray) -> np.ndarray:
        system = pc.impact_oscillator(frequency=w, stick_velocity=1e-6, **OSCILLATOR)
        return pc.stroboscopic_map(system)(x)

    diagram = pc.orbit_diagram(
        step,
        np.linspace(2.0, 3.4, points),
        np.array([-3.3626, 3.2073]),
        coordinate=lambda x: x[0],
        transient=150,
        keep=48,
    )
    figure = pc.bifurcation_figure(
        diagram,
        [branch],
        coordinate=lambda x: x[0],
        xlabel="forcing frequency ω [rad/s]",
        ylabel="x(kT) [m]",
        title="Impact oscillator (c = 0.05, F = 1, stop at 0, r = 0.8): stroboscopic map",
    )
    figure.savefig(out / "oscillator_diagram.png", dpi=120)
    # grazing of the non-impacting orbit with the stop at 0.5 m
    w, sigma = 0.8, 0.5

    def graze_system(F: float) -> pc.ImpactSystem:
        return pc.impact_oscillator(frequency=w, **{**OSCILLATOR, "stop": sigma, "force": F})

    grazing = pc.continuation(
        pc.stroboscopic_solver(lambda F: pc.without_impacts(graze_system(F))),
        np.array([0.15, 0.17, 0.19]),
        np.array([0.4, 0.0]),
        grazing=lambda F, x: pc.smallest_gap(graze_system(F), 0.0, x),
        tol=1e-10,
    )
    F_graze = next(b for b in grazing.bifurcations if b.kind == "grazing").parameter
    F_exact = sigma * math.hypot(1.0 - w * w, 0.05 * w)
    return [
        "## Linear impact oscillator (m = k = 1, c = 0.05, F = 1, stop at 0, r = 0.8)",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| period doubling of the period-1 orbit, ω [rad/s] | {flip.parameter:.9f} |",
        f"| multipliers there (saltation) | {', '.join(f'{m:.8f}' for m in at_flip.multipliers)} |",
        f"| multipliers there (finite differences) | {', '.join(f'{m:.8f}' for m in fd)} |",
        f"| grazing force (stop at 0.5 m, ω = 0.8), tool [N] | {F_graze:.12f} |",
        f"| grazing force, free amplitude = σ [N] | {F_exact:.12f} |",
        f"| relative difference | {abs(F_graze / F_exact - 1):.1e} |",
        "",
    ]


def main(argv: Sequence[str] | None = None) -> list[Path]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=FIGURES, help="output directory")
    parser.add_argument("--points", type=int, default=120, help="parameter values per diagram")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    text = [
        "# Impact oscillators (experiments/impact_oscillator.py)",
        "",
        *table(args.points, args.out),
        *oscillator(args.points, args.out),
    ]
    report = args.out / "impact_oscillators.md"
    report.write_text("\n".join(text))
    print(f"wrote {report}")
    return [report, args.out / "table_diagram.png", args.out / "oscillator_diagram.png"]


if __name__ == "__main__":
    main()
