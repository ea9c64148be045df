r"""Error against run time of each integrator: the figures and tables of docs/accuracy.md.

Cases (:func:`ucontrol.convergence.run_convergence` on each):

- ``ball_e09``: robots/ball.toml, e = 0.9, against the analytic :class:`BouncingBall`;
- ``ball_e05``: the same ball with e = 0.5, through its accumulation point (t∞ = 1.35 s) and the
  rest after it, against the analytic solution;
- ``two_link_drop``: robots/two_link_drop.toml (the two-link arm falling open loop onto the
  ground and the wall, stops at e = 0), against the tightest event-driven run;
- ``two_link_tracking``: robots/two_link_one_constraint.toml, Brogliato's tracking controller in
  closed loop (landing, sliding with a desired force, takeoff) over its first cycle, every run
  with the same 1 kHz controller, against the tightest event-driven run;
- ``two_link_flexible_drop``: robots/two_link_flexible_drop.toml, the same drop with flexible
  joints (K = 1e4 N m/rad, B = 0.1 kg m²), Moreau–Jean with and without ``midpoint`` as two
  curves, against the tightest event-driven run (the error is that of the links), over its
  first 0.45 s only (five impacts): later impacts, and the chattering on the ground with the
  springs ringing after 1 s, amplify any difference about tenfold each, so that over the
  scene's 3 s even two event-driven runs at rtol = 1e-12 differ by 9e-4 rad (docs/accuracy.md).

and two side studies on the e = 0.9 and e = 0.5 balls:

- ``compliant_stiffness``: error against k of both compliant force laws (linear, Hunt–Crossley);
- ``zeno_threshold``: the event-driven error the Zeno threshold costs, against its bound
  zeno_velocity² / (2 g), sampled finely enough to see the skipped flights.

Every figure is a PNG written into ``--out`` (default docs/figures) with the CSV and markdown
tables beside it. Wall times are those of the machine that runs the script.

Run: ``python experiments/work_precision.py`` (about 7 minutes on 2 cores). CI shortens it with
``--ball-duration 0.5 --arm-duration 0.2 --flexible-duration 0.2 --dts 1e-2 1e-3 ...``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ucontrol.analysis import BouncingBall
from ucontrol.convergence import ConvergenceStudy, plot_work_precision, run_convergence
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate

DOCS_FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
GRAVITY = 9.81  # [m/s²], that of the ball scene
#: Simulated time of the flexible-joint arm in [s]: its first five impacts (module docstring).
FLEXIBLE_DURATION = 0.45
CASES = (
    "ball_e09",
    "ball_e05",
    "two_link_drop",
    "two_link_tracking",
    "two_link_flexible_drop",
    "compliant_stiffness",
    "zeno_threshold",
)


def _ball(restitution: float) -> Scene:
    """robots/ball.toml with another restitution (its [reference] follows the contact)."""
    scene = load_scene(builtin_scene("ball.toml"))
    contact = dataclasses.replace(scene.contacts[0], restitution=restitution)
    return dataclasses.replace(scene, name=f"ball e = {restitution:g}", contacts=(contact,))


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DOCS_FIGURES, help="output folder")
    parser.add_argument("--cases", nargs="+", choices=CASES, default=CASES, help="what to run")
    parser.add_argument(
        "--ball-duration", type=float, default=3.0, help="simulated time of the balls in [s]"
    )
    parser.add_argument(
        "--arm-duration", type=float, default=3.0, help="simulated time of the arm in [s]"
    )
    parser.add_argument(
        "--flexible-duration",
        type=float,
        default=FLEXIBLE_DURATION,
        help="simulated time of the flexible-joint arm in [s]",
    )
    parser.add_argument(
        "--tracking-duration",
        type=float,
        default=12.0,
        help="simulated time of the tracking case in [s] (its first cycle ends at 10 s)",
    )
    parser.add_argument(
        "--control-period",
        type=float,
        default=1e-3,
        help="controller period of the tracking case in [s]",
    )
    parser.add_argument(
        "--dts",
        type=float,
        nargs="+",
        default=(1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5),
        help="moreau_jean steps in [s]",
    )
    parser.add_argument(
        "--tolerances",
        type=float,
        nargs="+",
        default=(1e-4, 1e-6, 1e-8, 1e-10, 1e-12),
        help="event_driven relative tolerances (atol = rtol / 100)",
    )
    parser.add_argument(
        "--stiffnesses",
        type=float,
        nargs="+",
        default=(1e4, 1e5, 1e6, 1e7, 1e8),
        help="compliant (linear) stiffnesses in [N/m]",
    )
    parser.add_argument(
        "--tracking-stiffnesses",
        type=float,
        nargs="+",
        default=(1e5, 1e6, 1e7),
        help="compliant stiffnesses of the tracking case in [N/m]",
    )
    parser.add_argument(
        "--hunt-crossley-stiffnesses",
        type=float,
        nargs="+",
        default=(1e5, 1e6, 1e7, 1e8, 1e9, 1e10),
        help="Hunt–Crossley stiffnesses in [N/m^1.5]",
    )
    parser.add_argument(
        "--sample-dt",
        type=float,
        default=1e-3,
        help="sampling period of event_driven and compliant in [s]",
    )
    parser.add_argument(
        "--zeno-velocities",
        type=float,
        nargs="+",
        default=(1e-1, 3e-2, 1e-2, 1e-3, 1e-5),
        help="event_driven Zeno thresholds in [m/s]",
    )
    parser.add_argument(
        "--zeno-sample-dt",
        type=float,
        default=1e-4,
        help="sampling period of the Zeno threshold study in [s]",
    )
    return parser


def _write(study: ConvergenceStudy, out: Path, case: str) -> None:
    (out / f"{case}.csv").write_text(study.to_csv())
    (out / f"{case}.md").write_text(study.to_markdown())
    plot_work_precision(study, out / f"work_precision_{case}.png")
    print(f"## {case}\n\n{study.to_markdown()}")


def _compliant_stiffness(args: argparse.Namespace) -> str:
    """Error against k of both force laws on the e = 0.9 ball; figure and markdown table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
    lines = [
        "| force law | k | error [m] | wall time [s] | events |",
        "|---|---|---|---|---|",
    ]
    csv = ["contact_model,stiffness,error,wall_time_s,n_events"]
    for model, stiffnesses in (
        ("linear", args.stiffnesses),
        ("hunt_crossley", args.hunt_crossley_stiffnesses),
    ):
        scene = _ball(0.9)
        scene = dataclasses.replace(
            scene, integrator=dataclasses.replace(scene.integrator, contact_model=model)
        )
        study = run_convergence(
            scene,
            duration=args.ball_duration,
            integrators=["compliant"],
            stiffnesses=stiffnesses,
            sample_dt=args.sample_dt,
        )
        runs = study.of("compliant")
        axes.loglog([r.value for r in runs], [r.error for r in runs], marker="o", label=model)
        for run in runs:
            lines.append(
                f"| {model} | {run.value:.0e} | {run.error:.3e} | {run.wall_time_s:.3g} "
                f"| {run.n_events} |"
            )
            csv.append(
                f"{model},{run.value:g},{run.error:.6e},{run.wall_time_s:.6g},{run.n_events}"
            )
        order = study.orders().get("compliant")
        if order is not None:
            lines.append(f"| {model}: slope of log error against log k | | {order:.3f} | | |")
    axes.set_xlabel("stiffness k [N/m] (linear), [N/m^1.5] (Hunt–Crossley)")
    axes.set_ylabel("largest height error [m]")
    axes.set_title(f"compliant ball, e = 0.9, {args.ball_duration:g} s: error against k")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.savefig(args.out / "compliant_stiffness.png", dpi=120)
    plt.close(figure)
    (args.out / "compliant_stiffness.csv").write_text("\n".join(csv) + "\n")
    table = "\n".join(lines) + "\n"
    (args.out / "compliant_stiffness.md").write_text(table)
    return table


def _zeno_threshold(args: argparse.Namespace) -> str:
    """Event-driven height error on the e = 0.5 ball against the Zeno threshold."""
    reference = BouncingBall(height=1.0, restitution=0.5, gravity=GRAVITY)
    lines = [
        f"Ball e = 0.5, {args.ball_duration:g} s sampled every {args.zeno_sample_dt:g} s "
        f"(t∞ = {reference.accumulation_time:.4f} s).",
        "",
        "| zeno_velocity [m/s] | bound v²/(2g) [m] | error [m] | events | wall time [s] |",
        "|---|---|---|---|---|",
    ]
    for zeno_velocity in args.zeno_velocities:
        scene = _ball(0.5)
        settings = dataclasses.replace(
            scene.integrator, name="event_driven", zeno_velocity=zeno_velocity
        )
        start = time.perf_counter()
        result = simulate(
            dataclasses.replace(scene, integrator=settings),
            duration=args.ball_duration,
            dt=args.zeno_sample_dt,
            progress=False,
        )
        wall = time.perf_counter() - start
        log = result.log
        error = float(np.max(np.abs(log.gap[:, 0] - reference.state(log.t)[0])))
        lines.append(
            f"| {zeno_velocity:.0e} | {zeno_velocity**2 / (2.0 * GRAVITY):.3e} | {error:.3e} "
            f"| {result.summary['n_events']} | {wall:.3g} |"
        )
    table = "\n".join(lines) + "\n"
    (args.out / "zeno_threshold.md").write_text(table)
    return table


def main(argv: Sequence[str] | None = None) -> dict[str, ConvergenceStudy]:
    """Run the cases asked for; returns the convergence studies by case name."""
    args = _parser().parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    studies = {}
    common = {"dts": args.dts, "tolerances": args.tolerances, "sample_dt": args.sample_dt}
    if "ball_e09" in args.cases:
        studies["ball_e09"] = run_convergence(
            _ball(0.9), duration=args.ball_duration, stiffnesses=args.stiffnesses, **common
        )
    if "ball_e05" in args.cases:
        studies["ball_e05"] = run_convergence(
            _ball(0.5), duration=args.ball_duration, stiffnesses=args.stiffnesses, **common
        )
    if "two_link_drop" in args.cases:
        studies["two_link_drop"] = run_convergence(
            load_scene(builtin_scene("two_link_drop.toml")),
            duration=args.arm_duration,
            stiffnesses=args.stiffnesses,
            **common,
        )
    if "two_link_tracking" in args.cases:
        studies["two_link_tracking"] = run_convergence(
            load_scene(builtin_scene("two_link_one_constraint.toml")),
            duration=args.tracking_duration,
            dts=[dt for dt in args.dts if dt <= args.control_period],
            tolerances=args.tolerances,
            stiffnesses=args.tracking_stiffnesses,
            sample_dt=args.control_period,
            control_period=args.control_period,
        )
    if "two_link_flexible_drop" in args.cases:
        studies["two_link_flexible_drop"] = run_convergence(
            load_scene(builtin_scene("two_link_flexible_drop.toml")),
            duration=args.flexible_duration,
            stiffnesses=args.stiffnesses,
            variants={"moreau_jean midpoint": {"name": "moreau_jean", "midpoint": True}},
            **common,
        )
    for case, study in studies.items():
        _write(study, args.out, case)
    if "compliant_stiffness" in args.cases:
        print(f"## compliant_stiffness\n\n{_compliant_stiffness(args)}")
    if "zeno_threshold" in args.cases:
        print(f"## zeno_threshold\n\n{_zeno_threshold(args)}")
    return studies


if __name__ == "__main__":
    main()
