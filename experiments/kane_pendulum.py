r"""Kane & Levinson's double pendulum striking a rough surface: energy ratio against friction.

Two uniform links (1 kg, 1 m each), the upper one pinned, absolute angles θ1 = ``--theta1`` and
θ2 = ``--theta2`` from the downward vertical; the lower link swings into a horizontal rough
surface (θ̇ = (0, -1) rad/s) and its tip strikes it. For each impact law of
:func:`ucontrol.integrators.frictional_impact.frictional_impact` (Newton's kinematic, Poisson's
kinetic and Stronge's energetic coefficient, all ``--restitution``) and friction coefficients μ
from 0 to ``--max-friction``, the ratio T⁺/T⁻ of the kinetic energies after and before the
impact. Newton's law exceeds 1 (creates energy) when the tip's slip reverses or stops during
restitution (μ above about 0.68 with the defaults); the energetic law never does.

Writes ``kane_pendulum.png`` and ``kane_pendulum.md`` into ``--out`` (default docs/figures) and
prints the table. Run: ``python experiments/kane_pendulum.py`` (a few seconds).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ucontrol.integrators.frictional_impact import (
    FRICTIONAL_IMPACT_LAWS,
    frictional_impact_velocity,
)

DOCS_FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
#: Pre-impact joint velocities [rad/s]: the lower link swings into the surface.
V_MINUS = np.array([0.0, -1.0])


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--theta1", type=float, default=0.4, help="upper link angle [rad]")
    parser.add_argument("--theta2", type=float, default=0.6, help="lower link angle [rad]")
    parser.add_argument("--restitution", type=float, default=0.5, help="e of every law")
    parser.add_argument("--max-friction", type=float, default=1.5, help="largest μ")
    parser.add_argument("--points", type=int, default=61, help="friction coefficients")
    parser.add_argument("--out", type=Path, default=DOCS_FIGURES, help="output folder")
    return parser


def kane_pendulum(theta1: float, theta2: float) -> tuple[np.ndarray, np.ndarray]:
    """Inertia M (2, 2) [kg m²] and contact Jacobian H (3, 2) [m] of the double pendulum.

    Two uniform links of 1 kg and 1 m, absolute angles from the downward vertical, upper link
    pinned at the origin; H rows: the tip's velocity along the surface normal (up), along the
    surface (horizontal), and out of the plane (zero).
    """
    c12 = math.cos(theta1 - theta2)
    M = np.array([[4.0 / 3.0, 0.5 * c12], [0.5 * c12, 1.0 / 3.0]])
    H = np.array(
        [
            [math.sin(theta1), math.sin(theta2)],
            [math.cos(theta1), math.cos(theta2)],
            [0.0, 0.0],
        ]
    )
    return M, H


def energy_ratios(
    theta1: float, theta2: float, restitution: float, frictions: np.ndarray
) -> dict[str, np.ndarray]:
    """T⁺/T⁻ of each law at each friction coefficient."""
    M, H = kane_pendulum(theta1, theta2)
    before = 0.5 * V_MINUS @ M @ V_MINUS  # [J]
    ratios = {}
    for law in FRICTIONAL_IMPACT_LAWS:
        values = []
        for mu in frictions:
            v_plus, _ = frictional_impact_velocity(
                M, H, V_MINUS, friction=float(mu), restitution=restitution, law=law
            )
            values.append(0.5 * v_plus @ M @ v_plus / before)
        ratios[law] = np.array(values)
    return ratios


def table(ratios: dict[str, np.ndarray], frictions: np.ndarray) -> str:
    """Markdown table of T⁺/T⁻, one row per law, at six friction coefficients at most."""
    every = slice(None, None, max(1, (len(frictions) - 1) // 5))
    header = "| law | " + " | ".join(f"μ = {mu:.3g}" for mu in frictions[every]) + " |"
    rule = "|---|" + "---|" * len(frictions[every])
    rows = [
        f"| {law} | " + " | ".join(f"{r:.6f}" for r in values[every]) + " |"
        for law, values in ratios.items()
    ]
    return "\n".join([header, rule, *rows]) + "\n"


def plot(ratios: dict[str, np.ndarray], frictions: np.ndarray, title: str, path: Path) -> Path:
    """T⁺/T⁻ against μ for each law."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6.0, 4.0), layout="constrained")
    for law, values in ratios.items():
        axes.plot(frictions, values, label=law)
    axes.axhline(1.0, color="grey", linewidth=0.8)
    axes.set_xlabel("friction coefficient μ")
    axes.set_ylabel("kinetic energy ratio T⁺ / T⁻")
    axes.set_title(title, fontsize="medium")
    axes.grid(True, alpha=0.3)
    axes.legend()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def main(argv: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Compute the ratios, print and write the table, draw the figure; return the ratios."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.points < 2 or not args.max_friction > 0.0:
        parser.error("need --points >= 2 and --max-friction > 0")
    frictions = np.linspace(0.0, args.max_friction, args.points)
    ratios = energy_ratios(args.theta1, args.theta2, args.restitution, frictions)
    text = table(ratios, frictions)
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "kane_pendulum.md").write_text(text)
    title = (
        f"Kane's double pendulum, θ = ({args.theta1:g}, {args.theta2:g}) rad, "
        f"e = {args.restitution:g}"
    )
    plot(ratios, frictions, title, args.out / "kane_pendulum.png")
    return ratios


if __name__ == "__main__":
    main()
