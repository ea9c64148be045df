r"""Campaign start-up: the share of a run outside its time-stepping loop, fresh builds vs reused.

Each campaign runs ``--runs`` runs of ``--duration`` simulated seconds of a tracking scene
(``two_link_one_constraint`` or ``panda_table``) with sensors and actuators in the loop, on the
``LocalCluster`` of ``--workers`` workers that :func:`~ucontrol.campaign.run_campaign` starts
(its start inside the clock, as with ``ucontrol campaign``, and with it each worker's
preparation, :func:`~ucontrol.campaign.runner.prepare_worker`: imports, libraries and the first
run's builds, kept with reuse), twice: every run building its
integrator and controller (``fresh``: ``reuse=False``, as before) and each worker reusing them
where the run's overrides allow (``reused``: ``reuse=True``, the default). Two campaigns:

- ``sensors``: runs that differ by the sensor-noise seed (the plant and the controller as built
  are those of every run: built once per worker with reuse);
- ``monte_carlo``: the Monte Carlo of ``experiments/campaign_two_link.py`` (restitution, the
  controller's mass scale and the ground height drawn per run: everything rebuilt per run).

Per campaign it prints the start-up share, Σ (run time - loop time) / Σ run time over the runs
(run time: the task's wall time; loop time: the run's ``wall_time_s``, its time-stepping loop);
the campaign's rate in runs/s; and its efficiency against the in-process loop, the rate of
``--workers`` processes doing nothing but the runs' loops back to back:
``runs / T / (workers · runs / Σ loop time)``. The load average is printed with them.

Run: ``python experiments/campaign_startup.py --scene two_link_one_constraint --runs 12
--duration 10 --workers 2``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import campaign_two_link  # experiments/: the Monte Carlo campaign of that study

SENSORS = """\
[campaign]
name = "{scene}_sensors"
scene = "{scene}"
duration = {duration!r}
seed = {seed}
metrics = ["wall_time_s", "max_penetration"]

[grid]
"sensors.seed" = {seeds!r}
"sensors.position_noise" = [1e-4]
"sensors.delay" = [1]
"actuators.torque_limit" = ["urdf"]
"""
#: The campaigns measured.
CAMPAIGNS = ("monte_carlo", "sensors")


def main(argv: Sequence[str] | None = None) -> dict[str, float]:
    """Run each campaign with fresh and with reused builds; return the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scene", choices=sorted(campaign_two_link.SCENES), default="two_link_one_constraint"
    )
    parser.add_argument("--campaigns", nargs="+", choices=CAMPAIGNS, default=CAMPAIGNS)
    parser.add_argument("--runs", type=int, default=12, help="runs per campaign")
    parser.add_argument("--duration", type=float, default=10.0, help="simulated time in [s]")
    parser.add_argument("--workers", type=int, default=2, help="Dask worker processes")
    parser.add_argument("--seed", type=int, default=None, help="seed (default: from the clock)")
    parser.add_argument("--out", type=Path, default=Path("runs/campaign_startup"))
    args = parser.parse_args(argv)

    # A new seed by default: the Monte Carlo's draws then compile anew, as in a new campaign.
    seed = int(time.time()) % 100_000 if args.seed is None else args.seed
    figures: dict[str, float] = {}
    print(f"{args.scene}, {args.runs} runs of {args.duration:g} s, {args.workers} workers")
    print("| campaign | builds | start-up share | runs/s | efficiency | load (1 min) |")
    print("|---|---|---|---|---|---|")
    for offset, kind in enumerate(args.campaigns):
        for reuse in (False, True):
            label = f"{kind}_{'reused' if reuse else 'fresh'}"
            out = args.out / label
            spec = _write_spec(out.with_suffix(".toml"), args, kind, seed + 2 * offset + reuse)
            result = _measure(spec, out, args.workers, reuse)
            figures.update({f"{label}_{key}": value for key, value in result.items()})
            print(
                f"| {kind} | {'reused' if reuse else 'fresh'} | "
                f"{100 * result['startup_share']:.1f} % | {result['runs_per_s']:.3f} | "
                f"{result['efficiency']:.2f} | {result['load']:.1f} |"
            )
    return figures


def _write_spec(path: Path, args: argparse.Namespace, kind: str, seed: int) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "sensors":
        seeds = [seed + i for i in range(args.runs)]
        text = SENSORS.format(scene=args.scene, duration=args.duration, seed=seed, seeds=seeds)
        path.write_text(text)
        return path
    settings = argparse.Namespace(  # experiments/campaign_two_link.py's defaults
        scene=args.scene,
        noise=1e-4,
        delay=1,
        duration=args.duration,
        dt=1e-3,
        seed=seed,
        ground_mm=(-5.0, 5.0),
        force_within=0.3,
        free_error=0.05,
    )
    campaign_two_link._write_campaign(path, settings, args.runs)
    text = path.read_text().replace("metrics = [\n", 'metrics = [\n    "wall_time_s",\n', 1)
    path.write_text(text)  # with the loop's time among the metrics
    return path


def _measure(spec: Path, out: Path, workers: int, reuse: bool) -> dict[str, float]:
    """One campaign on a new cluster: start-up share, runs/s, efficiency, load."""
    from ucontrol.campaign import load_campaign, run_campaign

    campaign = load_campaign(spec)
    if out.exists():  # a fresh measurement every time
        shutil.rmtree(out)
    start = time.perf_counter()  # the cluster's start is part of the campaign, as on the CLI
    outcome = run_campaign(campaign, out, workers=workers, progress=False, reuse=reuse)
    elapsed = time.perf_counter() - start
    records: list[dict[str, Any]] = [
        json.loads(path.read_text()) for path in sorted((out / "runs").glob("*.json"))
    ]
    ok = [r for r in records if r["status"] == "ok"]
    run_time = sum(r["wall_time_s"] for r in ok)  # [s]
    loop_time = sum(r["metrics"]["wall_time_s"] for r in ok)  # [s]
    return {
        "runs": float(outcome.ran),
        "failed": float(outcome.failed),
        "startup_share": (run_time - loop_time) / run_time,
        "runs_per_s": outcome.ran / elapsed,
        "efficiency": (outcome.ran / elapsed) / (workers * len(ok) / loop_time),
        "load": os.getloadavg()[0],
    }


if __name__ == "__main__":
    main()
