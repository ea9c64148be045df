r"""Monte Carlo of a tracking scene with sensors and actuators in the loop, and Dask's efficiency.

The campaign perturbs ``robots/two_link_one_constraint.toml`` (DESIGN §5; or
``panda_table.toml`` with ``--scene``) run by run:

- restitution of the end effector on the surface, ``contacts.0.restitution`` ~ U[0, 0.95];
- the controller's model, ``controller.model.mass_scale`` ~ U[0.8, 1.2] (every body of the
  controller's copy of the robot: ±20 % mass error; the plant keeps the nominal one);
- the surface height, ``surfaces.ground.point.1`` ~ U[-5, 5] mm, which the controller does not
  know: its model keeps the nominal surface (``controller.model.surfaces``);

and every run has joint-position noise (σ = 1e-4 rad, ``sensors.position_noise``), a
one-period measurement delay (``sensors.delay``) and the URDF's torque limits
(``actuators.torque_limit = "urdf"``).

A run succeeds when every cycle completes (landing, accumulation, constrained phase, takeoff),
the penetration stays below 1 mm, the mid-phase mean contact force is within 30 % of the
desired one and the free-motion error stays below 5 cm (the bounds say "the task is still
done", not "tracked as in the nominal case"). The script prints the success rate with its 95 %
Wilson interval and the worst runs, draws the campaign figures, then runs the first
``--efficiency-runs`` runs of the same campaign with one and with two workers side by side and
prints the parallel efficiency T1 / (2 T2).

Run: ``python experiments/campaign_two_link.py --runs 200 --workers 2 --duration 21
--figures docs/figures/campaigns``.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Sequence
from pathlib import Path

CAMPAIGN = """\
# Monte Carlo of a tracking scene with sensors and actuators in the loop
# (experiments/campaign_two_link.py)
[campaign]
name = "{name}"
scene = "{scene}"
duration = {duration!r}
dt = {dt!r}
seed = {seed}
runs = {runs}
metrics = [
    "max_penetration",
    "n_impacts",
    "tracking.free_error_max",
    "tracking.force_error_mid_max",
    "weak_stability.n_complete_cycles",
]
success = \"\"\"weak_stability.cycles_complete and max_penetration < 1e-3
    and tracking.force_error_mid_max < {force_within!r}
    and tracking.free_error_max < {free_error!r}\"\"\"
worst = "tracking.free_error_max"

[grid]  # held for every run: sensors, actuators, and the ground the controller believes
"sensors.position_noise" = [{noise!r}]
"sensors.delay" = [{delay}]
"actuators.torque_limit" = ["urdf"]
"controller.model.surfaces.{surface}.point" = [{nominal_point!r}]

[distributions]
"contacts.0.restitution" = {{ type = "uniform", low = 0.0, high = 0.95 }}
"controller.model.mass_scale" = {{ type = "uniform", low = 0.8, high = 1.2 }}
"surfaces.{surface}.point.{axis}" = {{ type = "uniform", low = {low!r}, high = {high!r} }}
"""

#: Each scene of the experiment: its surface, the index of the height coordinate, its height.
SCENES = {
    "two_link_one_constraint": ("ground", 1, [0.0, 0.0, 0.0]),
    "panda_table": ("table", 2, [0.0, 0.0, 0.2]),
}


def main(argv: Sequence[str] | None = None) -> dict[str, float]:
    """Run the Monte Carlo and the efficiency measurement; return the measured figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", choices=sorted(SCENES), default="two_link_one_constraint")
    parser.add_argument("--runs", type=int, default=200, help="Monte Carlo runs (0: skip)")
    parser.add_argument(
        "--noise", type=float, default=1e-4, help="joint-position noise std in [rad]"
    )
    parser.add_argument("--delay", type=int, default=1, help="measurement delay in periods")
    parser.add_argument("--workers", type=int, default=None, help="workers (default: cores)")
    parser.add_argument("--duration", type=float, default=11.0, help="simulated time in [s]")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the draws")
    parser.add_argument(
        "--ground-mm",
        type=float,
        nargs=2,
        default=(-5.0, 5.0),
        metavar=("LOW", "HIGH"),
        help="range of the ground height in [mm]",
    )
    parser.add_argument(
        "--force-within",
        type=float,
        default=0.3,
        help="largest relative error of the mid-phase mean contact force of a success",
    )
    parser.add_argument(
        "--free-error",
        type=float,
        default=0.05,
        help="largest free-motion tracking error of a success in [m]",
    )
    parser.add_argument(
        "--efficiency-runs",
        type=int,
        default=40,
        help="runs of the 1-worker / 2-worker comparison (0: skip it)",
    )
    parser.add_argument("--out", type=Path, default=Path("runs/campaign_two_link"))
    parser.add_argument("--figures", type=Path, default=None, help="folder of the figures")
    args = parser.parse_args(argv)

    args.out.mkdir(parents=True, exist_ok=True)
    figures: dict[str, float] = {}
    if args.runs > 0:
        figures.update(_monte_carlo(args))
    if args.efficiency_runs > 0:
        figures.update(_efficiency(args))
    return figures


def _monte_carlo(args: argparse.Namespace) -> dict[str, float]:
    """The Monte Carlo: success rate, Wilson interval, worst runs, figures."""
    from ucontrol.campaign import load, load_campaign, run_campaign, wilson_interval
    from ucontrol.campaign.command import success_line
    from ucontrol.campaign.figures import plot_campaign, worst_cases, worst_markdown

    path = _write_campaign(args.out / "campaign.toml", args, args.runs)
    campaign = load_campaign(path)
    start = time.perf_counter()
    outcome = run_campaign(campaign, args.out / "monte_carlo", workers=args.workers)
    elapsed = time.perf_counter() - start
    table = load(outcome.directory)
    k, n = int(table["success"].sum()), len(table)
    low, high = wilson_interval(k, n)
    print(
        f"{campaign.name}: {n} runs ({outcome.ran} now, {outcome.skipped} on disk) "
        f"in {elapsed:.1f} s"
    )
    print(success_line(table))
    completed = table[table["status"] == "ok"]
    print(
        f"completed runs: {len(completed)}; of those successful: "
        f"{int(completed['success'].sum())}; errors: "
        f"{table[table['status'] != 'ok']['error'].str.split(':').str[0].value_counts().to_dict()}"
    )
    print("worst 5 runs:")
    print(worst_markdown(worst_cases(outcome.directory, 5)))
    for path_written in plot_campaign(outcome.directory, args.figures):
        print(f"wrote {path_written}")
    return {"runs": n, "successes": k, "rate": k / n, "wilson_low": low, "wilson_high": high}


def _write_campaign(path: Path, args: argparse.Namespace, runs: int) -> Path:
    surface, axis, point = SCENES[args.scene]
    text = CAMPAIGN.format(
        name=f"{args.scene}_monte_carlo",
        scene=args.scene,
        surface=surface,
        axis=axis,
        nominal_point=point,
        noise=args.noise,
        delay=args.delay,
        duration=args.duration,
        dt=args.dt,
        seed=args.seed,
        runs=runs,
        low=point[axis] + 1e-3 * args.ground_mm[0],  # [m]
        high=point[axis] + 1e-3 * args.ground_mm[1],
        force_within=args.force_within,
        free_error=args.free_error,
    )
    path.write_text(text)
    return path


def _efficiency(args: argparse.Namespace) -> dict[str, float]:
    """The same campaign with 1 then 2 workers (clusters started before the clock)."""
    import dask
    from distributed import Client, LocalCluster

    from ucontrol.campaign import load, load_campaign, run_campaign

    path = _write_campaign(args.out / "efficiency.toml", args, args.efficiency_runs)
    campaign = load_campaign(path)
    times = {}
    for workers in (1, 2):
        out = args.out / f"efficiency_{workers}_workers"
        if out.exists():  # a fresh measurement every time
            import shutil

            shutil.rmtree(out)
        with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
            cluster = LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
            )
        with Client(cluster) as client:
            client.run(lambda: __import__("ucontrol.simulate"))  # imports outside the clock
            start = time.perf_counter()
            run_campaign(campaign, out, client=client)
            times[workers] = time.perf_counter() - start
        cluster.close()
    efficiency = times[1] / (2.0 * times[2])
    load1, load5, _ = os.getloadavg()
    print(
        f"parallel efficiency on {args.efficiency_runs} runs: T1 = {times[1]:.1f} s, "
        f"T2 = {times[2]:.1f} s, T1 / (2 T2) = {efficiency:.2f} "
        f"(load average {load1:.1f} / {load5:.1f}, {os.cpu_count()} cores)"
    )
    figures = {"T1": times[1], "T2": times[2], "efficiency": efficiency}
    for workers in (1, 2):  # where the time went: runs (slowed by other load) or Dask
        table = load(args.out / f"efficiency_{workers}_workers")
        busy = table["wall_time_s"].sum() / (workers * times[workers])
        print(
            f"{workers} worker(s): mean run {table['wall_time_s'].mean():.2f} s, workers busy "
            f"{100 * busy:.1f} % of the campaign (the rest is Dask: submit, transfer, write)"
        )
        figures[f"busy_{workers}"] = busy
    return figures


if __name__ == "__main__":
    main()
