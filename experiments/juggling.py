r"""Juggling with a 1-DoF paddle: the measured figures of docs/juggling.md.

``robots/juggler_paddle.toml`` (1 kg paddle, 0.05 kg ball) with
:class:`~ucontrol.control.juggling_controller.JugglingController`, event-driven plant at
``--dt`` (2 ms: sampling and control period):

- ``steady``: e in {0.6, 0.8, 0.9}, apex 0.3 m, ``--hits`` hits: apexes after the first hit,
  largest relative error, hits within 1 % of the command;
- ``floquet``: the closed loop's impact-to-impact map (state at the replanning after a hit) by
  finite differences: its multipliers (one is the trivial 1 of an autonomous flow);
- ``robustness``: the controller assumes e = 0.8 while the ball has e in {0.7, 0.75, 0.85,
  0.9}, without and with e measured at each hit; apex commands 0.15 to 1 m; drops from 0.1
  to 1.5 m (the basin);
- ``arm``: the two-link arm's tip juggling at apex 0.5 m (``robots/juggler_arm.toml``);
- a figure of the ball and paddle heights over the first hits, and the apexes per hit.

Run: ``python experiments/juggling.py`` (about 2 min; ``--hits 10`` for a smoke run); writes
``docs/figures/juggling/juggling.md`` and ``juggling.png`` (``--out``).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ucontrol.analysis.poincare import finite_difference_jacobian
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.scene.juggling_table import juggling_from_table
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures" / "juggling"
CONTACT = "ball/paddle"


def juggler(
    e_ball: float,
    *,
    e_model: float | None = None,
    apex: float = 0.3,
    q0: Sequence[float] | None = None,
    v0: Sequence[float] | None = None,
    estimate: bool = False,
):
    scene = Scene.from_toml(ROOT / "robots" / "juggler_paddle.toml")
    pair = dataclasses.replace(scene.sphere_contacts[0], restitution=e_ball)
    changes: dict[str, object] = {"sphere_contacts": (pair,)}
    if q0 is not None:
        changes |= {"q0": np.asarray(q0, dtype=float), "v0": np.asarray(v0, dtype=float)}
    scene = dataclasses.replace(scene, **changes)
    table = {"type": "juggling", "apex": apex, "contact": CONTACT}
    if e_model is not None:
        table["restitution"] = e_model
    if estimate:
        table["estimate_restitution"] = True
    return scene, juggling_from_table(scene, table)


def apexes(log: Log) -> np.ndarray:
    hits = np.flatnonzero(log.impulse_of(CONTACT) > 0.0)
    z_ball = log.q[:, 0]
    return np.array([z_ball[a:b].max() for a, b in itertools.pairwise(hits)])


def flight_time(apex: float) -> float:
    return 2.0 * math.sqrt(2.0 * 9.81 * (apex - 0.05)) / 9.81  # [s]


def run(scene: Scene, controller, hits: int, apex: float, dt: float) -> Log:
    duration = (hits + 1.5) * flight_time(apex) + 0.5
    return simulate(scene, controller, duration=duration, dt=dt, progress=False).log


def steady(hits: int, dt: float) -> tuple[list[str], dict[float, tuple[Log, np.ndarray]]]:
    lines = [
        "| e | hits | apexes after the first hit: mean [m] | largest relative error | "
        "hits within 1 % |",
        "|---|---|---|---|---|",
    ]
    runs = {}
    for e in (0.6, 0.8, 0.9):
        scene, controller = juggler(e)
        log = run(scene, controller, hits, 0.3, dt)
        heights = apexes(log)
        errors = np.abs(heights[1:] / 0.3 - 1.0)
        lines.append(
            f"| {e:g} | {heights.size + 1} | {heights[1:].mean():.6f} | {errors.max():.2e} | "
            f"{int(np.sum(errors <= 0.01))} of {errors.size} |"
        )
        runs[e] = (log, heights)
    return lines, runs


def floquet(dt: float) -> list[str]:
    lines = ["| e | multipliers (trivial 1 first) |", "|---|---|"]
    for e in (0.6, 0.8, 0.9):
        scene, controller = juggler(e)
        log = run(scene, controller, 2, 0.3, dt)
        hits = np.flatnonzero(log.impulse_of(CONTACT) > 0.0)
        row = hits[1] + 1
        x_star = np.concatenate((log.q[row], log.v[row]))

        def next_hit(x: np.ndarray, e: float = e) -> np.ndarray:
            scene_x, controller_x = juggler(e, q0=x[:2], v0=x[2:])
            run_log = simulate(
                scene_x, controller_x, duration=flight_time(0.3) + 0.1, dt=dt, progress=False
            ).log
            first = np.flatnonzero(run_log.impulse_of(CONTACT) > 0.0)[0] + 1
            return np.concatenate((run_log.q[first], run_log.v[first]))

        multipliers = np.linalg.eigvals(finite_difference_jacobian(next_hit, x_star, 1e-6))
        multipliers = multipliers[np.argsort(np.abs(multipliers - 1.0))]
        lines.append(f"| {e:g} | {', '.join(f'{m:.3g}' for m in multipliers)} |")
    return lines


def robustness(hits: int, dt: float) -> list[str]:
    lines = [
        "| case | apexes after the transient (last 5): mean [m] | command [m] | relative error |",
        "|---|---|---|---|",
    ]
    for e_ball in (0.7, 0.75, 0.85, 0.9):
        scene, controller = juggler(e_ball, e_model=0.8)
        heights = apexes(run(scene, controller, hits, 0.3, dt))
        mean = heights[-5:].mean()
        lines.append(
            f"| ball e = {e_ball:g}, controller assumes 0.8 | {mean:.5f} | 0.3 | "
            f"{mean / 0.3 - 1:+.2e} |"
        )
        scene, controller = juggler(e_ball, e_model=0.8, estimate=True)
        heights = apexes(run(scene, controller, 8, 0.3, dt))
        mean = heights[-5:].mean()
        lines.append(f"| same, e measured at each hit | {mean:.5f} | 0.3 | {mean / 0.3 - 1:+.2e} |")
    for apex in (0.15, 0.5, 1.0):
        scene, controller = juggler(0.8, apex=apex)
        heights = apexes(run(scene, controller, min(hits, 12), apex, dt))
        mean = heights[-5:].mean()
        lines.append(f"| apex command | {mean:.5f} | {apex:g} | {mean / apex - 1:+.2e} |")
    for drop in (0.1, 0.6, 1.5):
        scene, controller = juggler(0.8, q0=[drop, 0.0], v0=[0.0, 0.0])
        heights = apexes(run(scene, controller, 8, max(drop, 0.3), dt))
        mean = heights[-5:].mean()
        lines.append(f"| dropped from {drop:g} m | {mean:.5f} | 0.3 | {mean / 0.3 - 1:+.2e} |")
    return lines


def arm(hits: int, dt: float) -> list[str]:
    """The two-link arm's tip juggling at apex 0.5 m (robots/juggler_arm.toml)."""
    scene = Scene.from_toml(ROOT / "robots" / "juggler_arm.toml")
    lines = [
        "| e | hits | apexes after the first hit: mean [m] | largest relative error |",
        "|---|---|---|---|",
    ]
    for e in (0.6, 0.8, 0.9):
        pair = dataclasses.replace(scene.sphere_contacts[0], restitution=e)
        scene_e = dataclasses.replace(scene, sphere_contacts=(pair,))
        table = {
            "type": "juggling",
            "frame": "end_effector",
            "apex": 0.5,
            "hit_height": 0.2,
            "hit_x": 0.6,
            "contact": "ball/tip",
        }
        controller = juggling_from_table(scene_e, table)
        duration = (hits + 1.5) * 2.0 * math.sqrt(2.0 * 9.81 * 0.25) / 9.81 + 0.5
        log = simulate(scene_e, controller, duration=duration, dt=dt, progress=False).log
        impacts = np.flatnonzero(log.impulse_of("ball/tip") > 0.0)
        heights = np.array([log.q[a:b, 0].max() for a, b in itertools.pairwise(impacts)])
        errors = np.abs(heights[1:] / 0.5 - 1.0)
        lines.append(
            f"| {e:g} | {heights.size + 1} | {heights[1:].mean():.6f} | {errors.max():.2e} |"
        )
    return lines


def figure(runs: dict[float, tuple[Log, np.ndarray]]) -> Figure:
    fig = Figure(figsize=(8.0, 5.0), layout="constrained")
    top, bottom = fig.subplots(2, 1)
    log, _ = runs[0.8]
    shown = log.t <= 3.0
    top.plot(log.t[shown], log.q[shown, 0], label="ball centre")
    top.plot(log.t[shown], log.q[shown, 1], label="paddle")
    top.axhline(0.3, color="grey", ls=":", label="commanded apex")
    top.set_xlabel("t [s]")
    top.set_ylabel("height [m]")
    top.set_title("1-DoF paddle juggling, e = 0.8 (event-driven plant)")
    top.legend(fontsize="small", loc="upper right")
    for e, (_, heights) in runs.items():
        bottom.plot(np.arange(1, heights.size + 1), heights / 0.3 - 1.0, ".-", label=f"e = {e:g}")
    bottom.axhspan(-0.01, 0.01, color="tab:green", alpha=0.15, label="±1 %")
    bottom.set_yscale("symlog", linthresh=1e-6)
    bottom.set_xlabel("hit")
    bottom.set_ylabel("apex / command - 1")
    bottom.legend(fontsize="small", ncols=4)
    return fig


def main(argv: Sequence[str] | None = None) -> list[Path]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=FIGURES, help="output directory")
    parser.add_argument("--hits", type=int, default=55, help="hits per steady run")
    parser.add_argument("--dt", type=float, default=2e-3, help="plant sampling period [s]")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    steady_lines, runs = steady(args.hits, args.dt)
    text = [
        "# Juggling (experiments/juggling.py)",
        "",
        f"Apex 0.3 m (ball centre), hit height 0, event-driven plant, dt = {args.dt:g} s.",
        "",
        "## Steady juggling",
        "",
        *steady_lines,
        "",
        "## Closed-loop Floquet multipliers (finite differences of the hit-to-hit map)",
        "",
        *floquet(args.dt),
        "",
        "## Robustness",
        "",
        *robustness(min(args.hits, 20), args.dt),
        "",
        "## Two-link arm (robots/juggler_arm.toml), apex 0.5 m, tip at (0.6, 0.2) m at the hits",
        "",
        *arm(args.hits, args.dt),
        "",
    ]
    report = args.out / "juggling.md"
    report.write_text("\n".join(text))
    picture = args.out / "juggling.png"
    figure(runs).savefig(picture, dpi=120)
    print(f"wrote {report} and {picture}")
    return [report, picture]


if __name__ == "__main__":
    main()
