r"""Basin of attraction of the simplest walker's gait, probed as a campaign on Dask.

Garcia et al.'s simplest walker at slope γ (``--slope``, default 0.009 rad) is started just
after a heel strike from every point of a grid of the chart (θ⁺, θ̇⁺) (``--grid`` points per
axis over ``--theta`` and ``--rate``); its strides run until they come within ``--tol`` of the
stable gait (found first by :func:`~ucontrol.analysis.gait.find_gait`), fail (the walker falls)
or run out (``--strides``): :func:`ucontrol.analysis.basin.probe_basin`, each start a task of a
``LocalCluster`` of ``--workers`` processes (or of the scheduler at ``--scheduler``).

Writes ``walker_basin.png`` (outcome and strides to the gait over the grid) and
``walker_basin.md`` (counts) into ``--out`` (default docs/figures/legged).
Run: ``python experiments/walker_basin.py`` (about two minutes on 2 workers at 60 × 60).
"""

from __future__ import annotations

import argparse
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from ucontrol.analysis.basin import probe_basin
from ucontrol.analysis.gait import find_gait
from ucontrol.analysis.simplest_walker import SimplestWalker

OUT = Path(__file__).resolve().parents[1] / "docs" / "figures" / "legged"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--slope", type=float, default=0.009, help="γ [rad]")
    parser.add_argument("--grid", type=int, default=60, help="points per axis")
    parser.add_argument("--theta", type=float, nargs=2, default=(0.15, 0.3), help="θ⁺ range")
    parser.add_argument("--rate", type=float, nargs=2, default=(-0.32, -0.14), help="θ̇⁺ range")
    parser.add_argument("--strides", type=int, default=60, help="strides at most per start")
    parser.add_argument("--tol", type=float, default=1e-6, help="distance to the gait reached")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scheduler", default=None, help="address of a Dask scheduler")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()

    from distributed import Client, LocalCluster

    walker = SimplestWalker(slope=args.slope)
    gait = find_gait(walker, walker.to_state, walker.from_state, np.array([0.2, -0.2]))
    theta = np.linspace(*args.theta, args.grid)
    rate = np.linspace(*args.rate, args.grid)
    grid_theta, grid_rate = np.meshgrid(theta, rate)
    starts = np.column_stack((grid_theta.ravel(), grid_rate.ravel()))
    with ExitStack() as stack:
        if args.scheduler is None:
            cluster = stack.enter_context(
                LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True)
            )
            client = stack.enter_context(Client(cluster))
        else:
            client = stack.enter_context(Client(args.scheduler))
        table = probe_basin(
            walker,
            SimplestWalker.to_state,
            SimplestWalker.from_state,
            gait.z,
            starts,
            max_strides=args.strides,
            tol=args.tol,
            client=client,
        )
    counts = table["outcome"].value_counts().reindex(["gait", "fall", "unsettled"])
    lines = [
        f"Simplest walker, γ = {args.slope:g} rad: gait z* = ({gait.z[0]:.10f}, "
        f"{gait.z[1]:.10f}), multipliers {np.round(gait.multipliers, 6).tolist()}; "
        f"{len(table)} starts on a {args.grid} × {args.grid} grid, θ⁺ in {list(args.theta)}, "
        f"θ̇⁺ in {list(args.rate)}, at most {args.strides} strides, tol {args.tol:g}:",
        "",
        "| outcome | starts | share |",
        "|---|---|---|",
        *(f"| {name} | {n} | {n / len(table):.1%} |" for name, n in counts.items()),
    ]
    print("\n".join(lines))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "walker_basin.md").write_text("\n".join(lines) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    codes = table["outcome"].cat.codes.to_numpy().reshape(grid_theta.shape)
    strides = np.where(codes == 0, table["strides"].to_numpy().reshape(grid_theta.shape), np.nan)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), sharey=True)
    colours = ListedColormap(["tab:green", "tab:red", "tab:orange"])
    axes[0].pcolormesh(theta, rate, codes, cmap=colours, vmin=-0.5, vmax=2.5, shading="nearest")
    for name, colour in zip(("gait", "fall", "unsettled"), colours.colors, strict=True):
        axes[0].plot([], [], "s", color=colour, label=name)
    axes[0].set_title("outcome of the strides from each start")
    mesh = axes[1].pcolormesh(theta, rate, strides, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=axes[1], label=f"strides to come within {args.tol:g} of the gait")
    axes[1].set_title("strides to the gait (basin only)")
    for axis in axes:
        axis.plot(*gait.z, "k*", markersize=12, label="the gait z*")
        axis.set_xlabel("θ⁺ [rad]")
    axes[0].set_ylabel("θ̇⁺ [rad per unit time √(l/g)]")
    axes[0].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "walker_basin.png", dpi=110)


if __name__ == "__main__":
    main()
