r"""LZB multiple impacts: the measured figures of docs/multiple_impacts.md.

- ``cradle``: a striker at 1 m/s on a chain of N - 1 equal balls at rest and touching, e = 1,
  linear and Hertz contacts (equal stiffness): post-impact velocities, the share of the kinetic
  energy the last ball takes, LZB against an independent compliant chain integrated in positions
  (k = 1e6), momentum and energy errors.
- ``mass_ratio``: a striker of mass m1 on two unit balls, Hertz, e = 1: last ball's share of
  the energy against m1.
- ``restitution``: the 3-ball Hertz chain with e in {1, 0.9, 0.7, 0.5}: velocities, dissipated
  energy per contact, and the balance (kinetic loss - dissipation) in [J].
- ``rocking``: the rocking block landing flat (two corners): slender (b = 0.1, h = 0.4) and squat
  (b = 0.4, h = 0.2) blocks, angular velocity ratio of LZB (frictionless) for several e against
  Housner's sticking-corner ratio 1 - 1.5 sin²α and the closed form of a slender block.
- ``steps``: the fixed impulse step against the adaptive integration (3 balls, Hertz, e = 0.9).

Run: ``python experiments/lzb_cases.py`` (about 30 s); writes ``docs/figures/lzb/lzb_cases.md``
and ``docs/figures/lzb/cradle_energy.png`` (``--out``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.integrate import solve_ivp

from ucontrol.integrators.lzb_impact import HERTZ, LINEAR, lzb_impact

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures" / "lzb"


def chain_jacobian(n: int) -> np.ndarray:
    """u_j = v_{j+1} - v_j, shape (n - 1, n)."""
    J = np.zeros((n - 1, n))
    for j in range(n - 1):
        J[j, j], J[j, j + 1] = -1.0, 1.0
    return J


def compliant_chain(masses: np.ndarray, v0: np.ndarray, k: float, exponent: float) -> np.ndarray:
    """Velocities after separation of the compliant chain (positions integrated, DOP853)."""
    n = masses.size

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        x, v = y[:n], y[n:]
        force = k * np.maximum(x[:-1] - x[1:], 0.0) ** exponent
        a = np.zeros(n)
        a[:-1] -= force
        a[1:] += force
        return np.concatenate((v, a / masses))

    y = np.concatenate((np.zeros(n), v0))
    for _ in range(500):
        y = solve_ivp(rate, (0, 5 / np.sqrt(k)), y, method="DOP853", rtol=1e-13, atol=1e-16).y[
            :, -1
        ]
        if np.all(np.diff(y[:n]) > 0) and np.all(np.diff(y[n:]) >= 0):
            return y[n:]
    raise RuntimeError("compliant chain did not separate")


def cradle(sizes: Sequence[int]) -> tuple[list[str], dict[str, list[float]]]:
    lines = [
        "| balls | contacts | post-impact velocities [m/s] | last ball's energy share | "
        "vs compliant chain | momentum error | energy error | steps |",
        "|---|---|---|---|---|---|---|---|",
    ]
    shares: dict[str, list[float]] = {"linear": [], "Hertz": []}
    for n in sizes:
        masses = np.ones(n)
        v0 = np.zeros(n)
        v0[0] = 1.0
        for name, exponent in (("linear", LINEAR), ("Hertz", HERTZ)):
            result = lzb_impact(np.diag(masses), chain_jacobian(n), v0, exponent=exponent)
            reference = compliant_chain(masses, v0, 1e6, exponent)
            share = result.v[-1] ** 2  # kinetic energy 1/2 shared: v_last² of it
            shares[name].append(share)
            shown = ", ".join(f"{x:.4f}" for x in result.v) if n <= 5 else "..."
            lines.append(
                f"| {n} | {name} | {shown} | {share:.4f} | "
                f"{np.max(np.abs(result.v - reference)):.1e} | "
                f"{abs(result.v.sum() - 1.0):.1e} | {abs(result.v @ result.v - 1.0) / 2:.1e} | "
                f"{result.steps} |"
            )
    return lines, shares


def mass_ratio() -> list[str]:
    lines = ["| striker mass m1 [kg] | velocities [m/s] | last ball's share |", "|---|---|---|"]
    for m1 in (0.5, 1.0, 2.0, 4.0):
        masses = np.array([m1, 1.0, 1.0])
        v0 = np.array([1.0, 0.0, 0.0])
        result = lzb_impact(np.diag(masses), chain_jacobian(3), v0, exponent=HERTZ)
        share = masses[-1] * result.v[-1] ** 2 / (m1 * 1.0)
        lines.append(f"| {m1:g} | {', '.join(f'{x:.4f}' for x in result.v)} | {share:.4f} |")
    return lines


def restitution() -> list[str]:
    lines = [
        "| e | velocities [m/s] | dissipated per contact [J] | kinetic loss - dissipation [J] |",
        "|---|---|---|---|",
    ]
    v0 = np.array([1.0, 0.0, 0.0])
    for e in (1.0, 0.9, 0.7, 0.5):
        result = lzb_impact(np.eye(3), chain_jacobian(3), v0, restitution=e, exponent=HERTZ)
        loss = 0.5 - 0.5 * result.v @ result.v
        lines.append(
            f"| {e:g} | {', '.join(f'{x:.4f}' for x in result.v)} | "
            f"{', '.join(f'{x:.4f}' for x in result.dissipated)} | "
            f"{loss - result.dissipated.sum():.1e} |"
        )
    return lines


def rocking() -> list[str]:
    lines = [
        "| block (b, h) [m] | sin²α | e | LZB ω+/ω- | closed form (slender) | Housner |",
        "|---|---|---|---|---|---|",
    ]
    mass = 2.0
    for b, h in ((0.1, 0.4), (0.4, 0.2)):
        M = np.diag([mass, mass, mass * (b * b + h * h) / 3.0])
        J = np.array([[0.0, 1.0, -b], [0.0, 1.0, b]])
        v0 = np.array([h, -b, -1.0])  # rotating about corner A at ω = -1 rad/s
        s2 = b * b / (b * b + h * h)
        for e in (0.0, 0.5, 1.0):
            result = lzb_impact(M, J, v0, restitution=e, exponent=HERTZ)
            closed = 1.0 - (1.0 + e) * 6.0 * s2 / (1.0 + 3.0 * s2) if s2 < 1 / 3 else np.nan
            lines.append(
                f"| ({b:g}, {h:g}) | {s2:.4f} | {e:g} | {result.v[2] / v0[2]:.6f} | "
                f"{closed:.6f} | {1 - 1.5 * s2:.6f} |"
            )
    return lines


def steps() -> list[str]:
    lines = ["| impulse step ΔP [N s] | steps | max velocity error [m/s] |", "|---|---|---|"]
    v0 = np.array([1.0, 0.0, 0.0])
    reference = lzb_impact(np.eye(3), chain_jacobian(3), v0, restitution=0.9)
    lines.append(f"| adaptive (DOP853, rtol 1e-13) | {reference.steps} | reference |")
    for dP in (1e-2, 3e-3, 1e-3, 3e-4):
        result = lzb_impact(np.eye(3), chain_jacobian(3), v0, restitution=0.9, impulse_step=dP)
        error = np.max(np.abs(result.v - reference.v))
        lines.append(f"| {dP:g} | {result.steps} | {error:.2e} |")
    return lines


def energy_figure(sizes: Sequence[int], shares: dict[str, list[float]]) -> Figure:
    figure = Figure(figsize=(6.0, 3.6), layout="constrained")
    axes = figure.add_subplot()
    for name, values in shares.items():
        axes.plot(sizes, values, "o-", label=f"{name} contacts")
    axes.set_xlabel("balls in the chain")
    axes.set_ylabel("last ball's share of the energy")
    axes.set_title("Newton's cradle with LZB (e = 1, equal stiffness)")
    axes.legend()
    return figure


def main(argv: Sequence[str] | None = None) -> list[Path]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=FIGURES, help="output directory")
    parser.add_argument("--max-balls", type=int, default=8, help="longest chain")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    sizes = list(range(2, args.max_balls + 1))
    cradle_lines, shares = cradle(sizes)
    text = [
        "# LZB cases (experiments/lzb_cases.py)",
        "",
        "## Newton's cradle, e = 1",
        "",
        *cradle_lines,
        "",
        "## Striker mass (Hertz, e = 1, two unit balls)",
        "",
        *mass_ratio(),
        "",
        "## Energetic restitution (3 balls, Hertz)",
        "",
        *restitution(),
        "",
        "## Rocking block landing flat",
        "",
        *rocking(),
        "",
        "## Fixed impulse step",
        "",
        *steps(),
        "",
    ]
    table = args.out / "lzb_cases.md"
    table.write_text("\n".join(text))
    figure = args.out / "cradle_energy.png"
    energy_figure(sizes, shares).savefig(figure, dpi=120)
    print(f"wrote {table} and {figure}")
    return [table, figure]


if __name__ == "__main__":
    main()
