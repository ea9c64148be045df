r"""Order of Moreau–Jean between impacts, θ = 1/2, with and without ``midpoint``.

Cases, each a smooth motion (no impact in the window), each run by
:func:`ucontrol.convergence.run_convergence` over the steps ``--dts`` against the tightest
event-driven run (rtol = ``--reference-tolerance``, the other Runge–Kutta pair), the error being
the largest :math:`\|q \ominus q_\text{ref}\|_\infty` in [rad] over the run:

- ``four_bar``: robots/four_bar.toml, the four-bar linkage falling under gravity, its loop held
  by a bilateral point closure (mixed problem, configuration projected after every step);
- ``two_link_drop``: robots/two_link_drop.toml up to ``--drop-duration``, before its first
  impact (the end effector reaches the wall at 0.131 s): the contacts and stops are in the
  scene, their predicted gaps open;
- ``two_link_free``: the same arm and release without its contacts and stops, over
  ``--duration``.

For each case the table gives the error of every step and the order observed between
consecutive steps (:math:`\log(e_i/e_{i+1}) / \log(h_i/h_{i+1})`), and the least-squares
slope over all of them; the figure puts the errors against h on log axes (docs/moreau_jean.md).

Run: ``python experiments/midpoint_order.py`` (about 15 s on 2 cores); CI shortens it with
``--duration 0.2 --drop-duration 0.05 --dts 2e-3 1e-3``. Writes ``midpoint_order.md``,
``midpoint_order.csv`` and ``midpoint_order.png`` into ``--out`` (default docs/figures).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ucontrol.convergence import ConvergenceRun, ConvergenceStudy, run_convergence
from ucontrol.exceptions import UControlError
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate

DOCS_FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
CASES = ("four_bar", "two_link_drop", "two_link_free")
#: Label of the midpoint curve in the studies.
MIDPOINT = "moreau_jean midpoint"
CURVES = ("moreau_jean", MIDPOINT)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DOCS_FIGURES, help="output folder")
    parser.add_argument("--cases", nargs="+", choices=CASES, default=CASES, help="what to run")
    parser.add_argument(
        "--duration",
        type=float,
        default=1.0,
        help="simulated time of the four-bar and of the free arm in [s]",
    )
    parser.add_argument(
        "--drop-duration",
        type=float,
        default=0.12,
        help="simulated time of the two-link drop in [s], before its first impact (0.131 s)",
    )
    parser.add_argument(
        "--dts",
        type=float,
        nargs="+",
        default=(4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4),
        help="moreau_jean steps in [s], each dividing the largest",
    )
    parser.add_argument(
        "--reference-tolerance",
        type=float,
        default=1e-12,
        help="rtol of the event-driven reference run",
    )
    return parser


def _half_theta(scene: Scene, duration: float) -> Scene:
    """``scene`` with θ = 1/2 and the given simulated time in [s]."""
    integrator = dataclasses.replace(scene.integrator, name="moreau_jean", theta=0.5)
    return dataclasses.replace(scene, integrator=integrator, duration=duration)


def scenes(duration: float, drop_duration: float) -> dict[str, Scene]:
    """The three cases (module docstring), θ = 1/2."""
    drop = load_scene(builtin_scene("two_link_drop.toml"))
    free = dataclasses.replace(drop, name="two_link_free", contacts=(), stops=())
    return {
        "four_bar": _half_theta(load_scene(builtin_scene("four_bar.toml")), duration),
        "two_link_drop": _half_theta(drop, drop_duration),
        "two_link_free": _half_theta(free, duration),
    }


def _impact_free(scene: Scene, dt: float) -> bool:
    """Whether ``scene`` runs without any impulse at step ``dt`` [s], with and without midpoint."""
    for midpoint in (False, True):
        integrator = dataclasses.replace(scene.integrator, dt=dt, midpoint=midpoint)
        log = simulate(dataclasses.replace(scene, integrator=integrator), progress=False).log
        if np.asarray(log.impulse).size and np.any(np.asarray(log.impulse) > 0.0):
            return False
    return True


def local_orders(runs: Sequence[ConvergenceRun]) -> list[float]:
    """Observed order between consecutive runs (sorted by decreasing step), len(runs) - 1."""
    runs = sorted(runs, key=lambda run: -run.dt)
    return [
        math.log(a.error / b.error) / math.log(a.dt / b.dt) for a, b in itertools.pairwise(runs)
    ]


def markdown(studies: dict[str, ConvergenceStudy]) -> str:
    """One table per case: h, the errors and orders of both curves, then the fitted slopes."""
    parts = []
    for case, study in studies.items():
        runs = {curve: sorted(study.of(curve), key=lambda run: -run.dt) for curve in CURVES}
        orders = {curve: [math.nan, *local_orders(runs[curve])] for curve in CURVES}
        slopes = study.orders()
        lines = [
            f"**{case}** ({study.duration:g} s; error: {study.reference})",
            "",
            "| h [s] | θ = 1/2 error [rad] | order | midpoint error [rad] | order |",
            "|---|---|---|---|---|",
        ]
        for k, run in enumerate(runs["moreau_jean"]):
            cells = [f"{run.dt:g}"]
            for curve in CURVES:
                order = orders[curve][k]
                cells += [
                    f"{runs[curve][k].error:.3e}",
                    "" if math.isnan(order) else f"{order:.2f}",
                ]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("| slope | | " + f"{slopes['moreau_jean']:.2f} | | {slopes[MIDPOINT]:.2f} |")
        parts.append("\n".join(lines))
    return "\n\n".join(parts) + "\n"


def to_csv(studies: dict[str, ConvergenceStudy]) -> str:
    """Every run of every case: case, curve, h [s], error [rad], wall time [s]."""
    rows = ["case,curve,dt_s,error,wall_time_s"]
    for case, study in studies.items():
        for run in study.runs:
            curve = run.curve
            rows.append(f"{case},{curve},{run.dt:g},{run.error:.6e},{run.wall_time_s:.6g}")
    return "\n".join(rows) + "\n"


def plot(studies: dict[str, ConvergenceStudy], path: Path) -> Path:
    """Error against h of both curves, one panel per case, slopes 1 and 2 for the eye."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    figure, axes = plt.subplots(
        1, len(studies), figsize=(4.2 * len(studies), 3.8), layout="constrained", squeeze=False
    )
    for axis, (case, study) in zip(axes[0], studies.items(), strict=True):
        for curve, marker in zip(CURVES, ("o", "s"), strict=True):
            runs = sorted(study.of(curve), key=lambda run: run.dt)
            h = np.array([run.dt for run in runs])
            error = np.array([run.error for run in runs])
            label = "θ = 1/2, midpoint" if curve == MIDPOINT else "θ = 1/2"
            axis.loglog(h, error, marker=marker, label=label)
            order = 2 if curve == MIDPOINT else 1
            axis.loglog(h, error[-1] * (h / h[-1]) ** order, "k:", linewidth=0.8)
        axis.set_title(f"{case} ({study.duration:g} s)")
        axis.xaxis.set_minor_formatter(NullFormatter())  # decades only: no crowded labels
        axis.set_xlabel("h [s]")
        axis.set_ylabel("max |q - q_ref| [rad]")
        axis.grid(True, which="both", alpha=0.3)
        axis.legend(title="dotted: slopes 1 and 2")
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def main(argv: Sequence[str] | None = None) -> dict[str, ConvergenceStudy]:
    """Run the cases, print the tables, write the tables and the figure into ``--out``.

    A bad flag (a step that is not positive or does not divide the largest, a window of the
    drop that holds an impact) ends the run with a one-line message and exit status 2.
    """
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        cases = scenes(args.duration, args.drop_duration)
        if "two_link_drop" in args.cases and not _impact_free(
            cases["two_link_drop"], max(args.dts)
        ):
            parser.error(
                f"--drop-duration {args.drop_duration} s reaches the drop's first impact "
                "(0.131 s): the window must be smooth"
            )
        studies = {
            case: run_convergence(
                cases[case],
                integrators=["moreau_jean"],
                dts=args.dts,
                reference_tolerance=args.reference_tolerance,
                variants={MIDPOINT: {"name": "moreau_jean", "midpoint": True}},
            )
            for case in args.cases
        }
    except UControlError as error:
        parser.error(str(error))
    args.out.mkdir(parents=True, exist_ok=True)
    table = markdown(studies)
    (args.out / "midpoint_order.md").write_text(table)
    (args.out / "midpoint_order.csv").write_text(to_csv(studies))
    plot(studies, args.out / "midpoint_order.png")
    print(table)
    return studies


if __name__ == "__main__":
    main()
