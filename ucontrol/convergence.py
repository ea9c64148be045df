r"""Error against run time: each integrator over a range of steps, tolerances or stiffnesses.

:func:`run_convergence` runs a scene through :func:`ucontrol.simulate.simulate` with

- ``moreau_jean`` over time steps h (``dts``), whose observed order is the slope of
  :math:`\log(\text{error})` against :math:`\log h`;
- ``event_driven`` over solve_ivp tolerances (``tolerances``: rtol, with atol = rtol / 100),
  sampled every ``sample_dt``; its order is the slope against :math:`\log(\text{rtol})`;
- ``compliant`` over contact stiffnesses (``stiffnesses``), sampled every ``sample_dt``; its
  order is the slope against :math:`\log k` (about -1/2: the error is the penetration and the
  contact duration, both :math:`\propto k^{-1/2}`),

and measures each run's error against a reference:

- analytic, where the scene declares one (``[reference] type = "bouncing_ball"``): the largest
  difference in [m] between the gap of the declared contact and the
  :class:`~ucontrol.analysis.BouncingBall` height over every sample of the run;
- otherwise the tightest event-driven run (rtol = ``reference_tolerance``), made with the other
  Runge–Kutta pair than the event-driven runs (RK45 against DOP853 and conversely) so that it
  does not repeat their computation: the largest configuration difference
  :math:`\|q \ominus q_\text{ref}\|_\infty` in [m] or [rad] at the times the runs share
  (multiples of the largest step).

A *variant* adds a curve: one integrator swept over its range with other settings (e.g.
Moreau–Jean with ``midpoint = True``), labelled in the tables and the figure.

The wall time is the simulation loop's. :meth:`ConvergenceStudy.equal_error` puts each
event-driven run beside the Moreau–Jean wall time at the same error, interpolated along
Moreau–Jean's power law of time against error inside the range of errors its runs measured;
outside it the markdown table says "not reached" and gives a bound from the nearest run.

This module imports the simulation loop, so it is not re-exported by ``ucontrol.analysis``
(whose summary the loop itself imports).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.analysis.bouncing_ball import BouncingBall
from ucontrol.analysis.coordinates import coordinate_units
from ucontrol.exceptions import InvalidParameterError, NotFoundError, UnknownKeyError
from ucontrol.integrators.methods import INTEGRATORS, IVP_METHODS
from ucontrol.log import Log
from ucontrol.scene import IntegratorSettings, Scene
from ucontrol.simulate import simulate

#: Default Moreau–Jean steps in [s].
DEFAULT_DTS = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)
#: Default event-driven relative tolerances.
DEFAULT_TOLERANCES = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
#: Default compliant stiffnesses in [N/m] (linear law).
DEFAULT_STIFFNESSES = (1e4, 1e5, 1e6, 1e7)
#: Parameter swept for each integrator.
PARAMETERS = {"moreau_jean": "dt", "event_driven": "rtol", "compliant": "stiffness"}
#: Integrator settings the sweep of each integrator sets, which a variant may not.
_SWEPT = {"moreau_jean": {"dt"}, "event_driven": {"rtol", "atol"}, "compliant": {"stiffness"}}
#: atol / rtol of the event-driven and compliant runs, in the state's units.
ATOL_RATIO = 1e-2
#: Relative tolerance of the compliant runs.
COMPLIANT_RTOL = 1e-8

_CSV_FIELDS = (
    "integrator",
    "parameter",
    "value",
    "dt_s",
    "error",
    "wall_time_s",
    "steps",
    "n_events",
    "variant",
)
#: Markers of the curves of a work-precision figure, in order.
_MARKERS = "osD^v<>"


@dataclass(frozen=True, kw_only=True)
class ConvergenceRun:
    """One run of a convergence study.

    Attributes:
        integrator: Integrator name.
        parameter: What was varied: ``"dt"`` [s], ``"rtol"`` [-] or ``"stiffness"`` [N/m].
        value: Its value.
        dt: Step (Moreau–Jean) or sampling period (others) in [s].
        error: Error against the reference, in [m] (or [rad] for joint coordinates).
        wall_time_s: Wall time of the simulation loop in [s].
        steps: Number of steps.
        n_events: Events located (event-driven and compliant integrators).
        variant: Label of the settings variant of the run, or ``""`` for the scene's settings.
    """

    integrator: str
    parameter: str
    value: float
    dt: float
    error: float
    wall_time_s: float
    steps: int
    n_events: int
    variant: str = ""

    @property
    def curve(self) -> str:
        """The curve the run belongs to: its variant's label, else its integrator's name."""
        return self.variant or self.integrator


@dataclass(frozen=True, kw_only=True)
class EqualError:
    """An event-driven run beside Moreau–Jean's wall time at the same error.

    Attributes:
        error: The event-driven run's error.
        event_driven_s: Its wall time in [s].
        moreau_jean_s: Moreau–Jean's wall time at that error in [s], from its power law.
        extrapolated: Whether that error lies outside the Moreau–Jean runs' range.
    """

    error: float
    event_driven_s: float
    moreau_jean_s: float
    extrapolated: bool


@dataclass(frozen=True, kw_only=True)
class ConvergenceStudy:
    """The runs of :func:`run_convergence` and what they show.

    Attributes:
        scene: Scene name.
        duration: Simulated time of every run in [s].
        reference: How the error was measured.
        error_unit: Unit of the errors: ``"m"``, ``"rad"``, or ``"m or rad"`` for a
            configuration error over lengths and angles.
        runs: Every run, grouped by integrator.
    """

    scene: str
    duration: float
    reference: str
    error_unit: str
    runs: tuple[ConvergenceRun, ...]

    def of(self, curve: str) -> list[ConvergenceRun]:
        """The runs of one curve, in the order they were made.

        Args:
            curve: An integrator name (its runs with the scene's settings) or a variant label.
        """
        return [run for run in self.runs if run.curve == curve]

    def curves(self) -> list[str]:
        """The curves of the study (integrator names, then variant labels), in run order."""
        return list(dict.fromkeys(run.curve for run in self.runs))

    def orders(self) -> dict[str, float]:
        """Observed order of each curve with two runs or more of positive error.

        Least-squares slope of log(error) against log(parameter): against h for
        Moreau–Jean, rtol for event-driven, k for compliant. NaN when the error does not vary.
        """
        orders = {}
        for curve in self.curves():
            runs = [run for run in self.of(curve) if run.error > 0.0]
            if len(runs) >= 2:
                x = np.log([run.value for run in runs])
                y = np.log([run.error for run in runs])
                orders[curve] = float(np.polyfit(x, y, 1)[0]) if np.ptp(y) > 0 else math.nan
        return orders

    def equal_error(self) -> list[EqualError]:
        """Each event-driven run beside Moreau–Jean's wall time at its error.

        Moreau–Jean's time is the power law time = C error^s fitted (least squares in log-log)
        to its runs; empty without two Moreau–Jean and one event-driven run. Event-driven runs
        of zero error (equal to their reference to the last bit) are left out.
        """
        reference = [run for run in self.of("moreau_jean") if run.error > 0.0]
        if len(reference) < 2:
            return []
        log_error = np.log([run.error for run in reference])
        slope, intercept = np.polyfit(log_error, np.log([run.wall_time_s for run in reference]), 1)
        low, high = log_error.min(), log_error.max()
        rows = []
        for run in self.of("event_driven"):
            if run.error <= 0.0:
                continue
            log_run_error = math.log(run.error)
            rows.append(
                EqualError(
                    error=run.error,
                    event_driven_s=run.wall_time_s,
                    moreau_jean_s=float(np.exp(intercept + slope * log_run_error)),
                    extrapolated=not low <= log_run_error <= high,
                )
            )
        return rows

    def to_csv(self) -> str:
        """The runs as CSV text, one row per run (columns of ``_CSV_FIELDS``)."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(_CSV_FIELDS)
        for run in self.runs:
            writer.writerow(
                [
                    run.integrator,
                    run.parameter,
                    f"{run.value:.6g}",
                    f"{run.dt:.6g}",
                    f"{run.error:.6e}",
                    f"{run.wall_time_s:.6g}",
                    run.steps,
                    run.n_events,
                    run.variant,
                ]
            )
        return buffer.getvalue()

    def to_markdown(self) -> str:
        """Runs, observed orders and the equal-error comparison as markdown tables.

        Consecutive runs of one curve whose errors agree at rounding level (relative
        difference at most :data:`ERROR_AGREEMENT`) share one row that gives the range of their
        parameter, wall time and steps. Moreau–Jean's time at an event-driven run's error is
        given only inside the range of errors its runs measured; outside it the table says
        "not reached" and bounds the ratio by Moreau–Jean's most accurate (or least accurate)
        run instead of extrapolating its power law.
        """
        lines = [
            f"Scene `{self.scene}`, {self.duration:g} s; error: {self.reference}.",
            "",
            "| integrator | parameter | value | step / sampling [s] | error | wall time [s] "
            "| steps | events |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for curve in self.curves():
            for group in _agreeing_groups(self.of(curve), lambda run: run.error):
                lines.append(_run_row(curve, group))
        orders = self.orders()
        if orders:
            lines += ["", "| integrator | observed order | against |", "|---|---|---|"]
            lines += [
                f"| {curve} | {_order_text(order)} | log {self.of(curve)[0].parameter} |"
                for curve, order in orders.items()
            ]
        moreau_jean = self.of("moreau_jean")
        best = min(moreau_jean, key=lambda run: run.error, default=None)
        if best is not None and self.of("event_driven"):
            worst = max(self.of("event_driven"), key=lambda run: run.error)
            slowest = max(run.wall_time_s for run in self.of("event_driven"))
            lines += [
                "",
                f"Most accurate moreau_jean run: h = {best.value:.3g} s, error "
                f"{best.error:.3e} in {best.wall_time_s:.3g} s; event_driven: error at most "
                f"{worst.error:.3e} in at most {slowest:.3g} s.",
            ]
        equal = self.equal_error()
        if equal:
            measured = [run for run in moreau_jean if run.error > 0.0]
            most = min(measured, key=lambda run: run.error)
            least = max(measured, key=lambda run: run.error)
            lines += [
                "",
                "| error | event_driven [s] | moreau_jean at equal error [s] | ratio |",
                "|---|---|---|---|",
            ]
            for group in _agreeing_groups(equal, lambda row: row.error):
                lines.append(_equal_error_row(group, most, least))
        return "\n".join(lines) + "\n"


#: Largest relative difference of two errors printed as one (rounding level: the tables print
#: four significant digits).
ERROR_AGREEMENT = 5e-4


def _agree(a: float, b: float) -> bool:
    """Whether two errors agree at rounding level (:data:`ERROR_AGREEMENT`)."""
    return abs(a - b) <= ERROR_AGREEMENT * max(abs(a), abs(b))


def _agreeing_groups(items: Sequence[Any], error: Any) -> list[list[Any]]:
    """``items`` cut into runs of consecutive items whose errors agree with the first one's."""
    groups: list[list[Any]] = []
    for item in items:
        if groups and _agree(error(groups[-1][0]), error(item)):
            groups[-1].append(item)
        else:
            groups.append([item])
    return groups


def _span(values: Sequence[float], fmt: str) -> str:
    """``values`` as one number when they print alike, else as their range ``low–high``."""
    low, high = format(min(values), fmt), format(max(values), fmt)
    return low if low == high else f"{low}–{high}"


def _run_row(curve: str, group: list[ConvergenceRun]) -> str:
    """One row of the runs table: one run, or runs of one curve whose errors agree."""
    first, last = group[0], group[-1]
    if len(group) == 1:
        value = f"{first.value:.3g}"
    else:  # the parameter in run order, e.g. rtol 1e-04 … 1e-12
        value = f"{first.value:.3g} … {last.value:.3g} ({len(group)} runs, same error)"
    errors = [run.error for run in group]
    return (
        f"| {curve} | {first.parameter} | {value} | {_span([run.dt for run in group], '.3g')} "
        f"| {_span(errors, '.3e')} | {_span([run.wall_time_s for run in group], '.3g')} "
        f"| {_span([run.steps for run in group], 'd')} "
        f"| {_span([run.n_events for run in group], 'd')} |"
    )


def _equal_error_row(group: list[EqualError], most: ConvergenceRun, least: ConvergenceRun) -> str:
    """One row of the equal-error table; outside Moreau–Jean's measured errors, "not reached".

    Args:
        group: Event-driven runs whose errors agree.
        most: Moreau–Jean's most accurate run (smallest error).
        least: Moreau–Jean's least accurate run (largest error).
    """
    error = group[0].error
    times = [row.event_driven_s for row in group]
    event_driven = _span(times, ".3g")
    if len(group) > 1:
        event_driven += f" ({len(group)} runs)"
    if not group[0].extrapolated:
        moreau_jean = f"{group[0].moreau_jean_s:.3g}"
        ratio = _span([group[0].moreau_jean_s / time for time in times], ".3g")
    elif error < most.error:  # more accurate than any Moreau–Jean run: at least its cost
        moreau_jean = (
            f"not reached (its best, {most.error:.3e} at h = {most.value:.3g} s, "
            f"took {most.wall_time_s:.3g} s)"
        )
        ratio = f"> {min(most.wall_time_s / time for time in times):.3g}"
    else:  # less accurate than any Moreau–Jean run: at most the cost of its coarsest
        moreau_jean = (
            f"not reached (its coarsest, {least.error:.3e} at h = {least.value:.3g} s, "
            f"took {least.wall_time_s:.3g} s)"
        )
        ratio = f"< {max(least.wall_time_s / time for time in times):.3g}"
    errors = _span([row.error for row in group], ".3e")
    return f"| {errors} | {event_driven} | {moreau_jean} | {ratio} |"


def run_convergence(
    scene: Scene,
    *,
    duration: float | None = None,
    integrators: Sequence[str] = INTEGRATORS,
    dts: Sequence[float] = DEFAULT_DTS,
    tolerances: Sequence[float] = DEFAULT_TOLERANCES,
    stiffnesses: Sequence[float] = DEFAULT_STIFFNESSES,
    sample_dt: float | None = None,
    control_period: float | None = None,
    reference_tolerance: float = 1e-12,
    variants: Mapping[str, Mapping[str, Any]] | None = None,
) -> ConvergenceStudy:
    """Run ``scene`` with each integrator over its parameter range and measure the errors.

    Args:
        scene: The scene; its ``[reference]`` table, if any, gives the analytic reference.
        duration: Simulated time in [s]; default the scene's.
        integrators: Which integrators to run, among :data:`ucontrol.scene.INTEGRATORS`.
        dts: Moreau–Jean steps in [s].
        tolerances: Event-driven relative tolerances (atol = rtol / 100).
        stiffnesses: Compliant stiffnesses in [N/m] (or [N/m^1.5] for Hunt–Crossley).
        sample_dt: Sampling period of the event-driven and compliant runs in [s]; default the
            scene's step.
        control_period: Controller period in [s] of every run (zero-order hold), which every
            step and sampling period must divide; default every step. A closed loop is only
            the same system across runs with a common control period.
        reference_tolerance: rtol of the event-driven reference run when the scene declares
            no analytic reference.
        variants: Extra curves, each a label and the :class:`~ucontrol.scene.IntegratorSettings`
            fields that differ from the scene's, ``name`` (the integrator, swept over its
            range above) included: e.g. ``{"moreau_jean midpoint": {"name": "moreau_jean",
            "midpoint": True}}``. Run after the ``integrators``.

    Raises:
        NotFoundError: An integrator name is unknown.
        InvalidParameterError: A range is empty or holds a non-positive value, a step does
            not divide the control period, or (numerical reference) the largest step; a
            variant's label is empty or an integrator's name, it sets the swept parameter,
            or a setting is out of range.
        UnknownKeyError: A variant sets a field that integrator settings do not have.
    """
    duration = as_positive("duration", scene.duration if duration is None else duration)
    for name in integrators:
        if name not in INTEGRATORS:
            raise NotFoundError("integrator", name, INTEGRATORS)
    sample_dt = as_positive("sample_dt", scene.integrator.dt if sample_dt is None else sample_dt)
    sweeps = {
        "moreau_jean": _positive_range("dts", dts),
        "event_driven": _positive_range("tolerances", tolerances),
        "compliant": _positive_range("stiffnesses", stiffnesses),
    }
    curves: list[tuple[str, str, dict[str, Any]]] = [(name, name, {}) for name in integrators]
    curves += [_variant(label, changes) for label, changes in (variants or {}).items()]
    settings = [
        (curve, name, value, _settings(name, value, sample_dt, changes))
        for curve, name, changes in curves
        for value in sweeps[name]
    ]
    if control_period is not None:
        control_period = as_positive("control_period", control_period)
        for *_, (step, _) in settings:
            _check_divides(step, control_period, "the control period")
    if scene.reference is not None:
        ball, index = _bouncing_ball(scene, scene.reference["contact"])
        reference = (
            f"largest |gap - BouncingBall height| of contact "
            f"{scene.constraints.names[index]!r} over every sample, in [m]"
        )

        error_unit = "m"

        def error(log: Log) -> float:
            height, _ = ball.state(log.t)
            return float(np.max(np.abs(log.gap[:, index] - height)))

    else:
        period = max(sample_dt, *(step for *_, (step, _) in settings))
        for *_, (step, _) in settings:
            _check_divides(step, period, "the largest step or sampling period")
        method = "DOP853" if scene.integrator.method == "RK45" else "RK45"
        options = {
            "rtol": reference_tolerance,
            "atol": ATOL_RATIO * reference_tolerance,
            "method": method,
        }
        reference_log, _ = _simulate(
            scene, "event_driven", period, options, duration, control_period
        )
        model = scene.robot.model
        _, v_units = coordinate_units(model, model.nq, model.nv)  # those of q ⊖ q_ref
        error_unit = " or ".join(sorted({unit.removesuffix("/s") for unit in v_units}))
        reference = (
            f"largest |q - q_ref| (inf-norm, [{error_unit}]) every {period:g} s against "
            f"event_driven ({method}) at rtol = {reference_tolerance:g}"
        )

        def error(log: Log) -> float:
            return _configuration_error(scene, log, reference_log, period)

    runs = []
    for curve, name, value, (step, options) in settings:
        log, summary = _simulate(scene, name, step, options, duration, control_period)
        runs.append(
            ConvergenceRun(
                integrator=name,
                parameter=PARAMETERS[name],
                value=value,
                dt=step,
                error=error(log),
                wall_time_s=summary["wall_time_s"],
                steps=summary["steps"],
                n_events=summary["n_events"],
                variant="" if curve == name else curve,
            )
        )
    return ConvergenceStudy(
        scene=scene.name,
        duration=duration,
        reference=reference,
        error_unit=error_unit,
        runs=tuple(runs),
    )


def plot_work_precision(study: ConvergenceStudy, path: str | Path) -> Path:
    """Save :func:`work_precision_figure` of ``study`` to ``path`` (PNG at 120 dpi)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    work_precision_figure(study).savefig(path, dpi=120)
    return path


def work_precision_figure(study: ConvergenceStudy) -> Any:
    """Log-log plot of error against wall time, one line per curve, unsaved.

    Each point is labelled, in its curve's colour, with its step, tolerance or stiffness where
    the label fits: it takes the first of four places around the point that overlaps no label
    placed before, no marker and no border of the axes, and is left out when none does. The
    legend sits below the axes.

    Returns:
        The matplotlib figure.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(6.4, 5.0), layout="constrained")
    canvas = FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    floor = np.finfo(float).eps
    points: list[tuple[ConvergenceRun, float, float]] = []
    colours: dict[str, Any] = {}  # of each curve: its labels take it
    for curve, marker in zip(study.curves(), itertools.cycle(_MARKERS), strict=False):
        runs = study.of(curve)
        times = [run.wall_time_s for run in runs]
        errors = [max(run.error, floor) for run in runs]
        (line,) = axes.loglog(times, errors, marker=marker, label=curve)
        colours[curve] = line.get_color()
        points += zip(runs, times, errors, strict=True)
    axes.set_xlabel("wall time [s]")
    axes.set_ylabel(f"error [{study.error_unit}]")
    axes.set_title(f"{study.scene}: error against run time ({study.duration:g} s simulated)")
    axes.grid(True, which="both", alpha=0.3)
    figure.legend(
        title="labels: h [s], rtol, k [N/m]",
        loc="outside lower center",
        ncol=min(4, len(study.curves())),
        fontsize=8,
        title_fontsize=8,
    )
    canvas.draw()  # the layout, hence where each point lands
    figure.set_layout_engine("none")  # the labels below must not move the axes
    _label_points(canvas.get_renderer(), axes, points, colours)
    return figure


#: Places of a point's label tried in order, as (dx, dy) offsets in points and alignments.
_LABEL_PLACES = (
    ((4, 3), "left", "bottom"),
    ((4, -3), "left", "top"),
    ((-4, 3), "right", "bottom"),
    ((-4, -3), "right", "top"),
)


def _label_points(
    renderer: Any,
    axes: Any,
    points: list[tuple[ConvergenceRun, float, float]],
    colours: Mapping[str, Any],
) -> None:
    """Label each point where its label overlaps no other label, marker or axes border.

    Consecutive runs of one curve drawn on top of each other share one label, the range of
    their values (``1e-04…1e-12``). A label takes the colour of its curve.
    """
    inside = axes.get_window_extent(renderer)
    marker = 4.0 * axes.figure.dpi / 72.0  # [px] half the side of a marker's box
    markers = [axes.transData.transform((time, error)) for _, time, error in points]
    groups: list[list[int]] = []
    for k, (run, _, _) in enumerate(points):
        last = groups[-1][-1] if groups else None
        if (
            last is not None
            and points[last][0].curve == run.curve
            and np.all(np.abs(markers[k] - markers[last]) < marker)
        ):
            groups[-1].append(k)
        else:
            groups.append([k])
    taken: list[Any] = []  # window extents of the labels placed
    for group in groups:
        first = points[group[0]][0]
        low, high = points[group[0]][0].value, points[group[-1]][0].value
        text = f"{low:.0e}" if len(group) == 1 else f"{low:.0e}…{high:.0e}"
        for offset, horizontal, vertical in _LABEL_PLACES:
            label = axes.annotate(
                text,
                points[group[0]][1:],
                textcoords="offset points",
                xytext=offset,
                ha=horizontal,
                va=vertical,
                fontsize=7,
                color=colours[first.curve],
            )
            box = label.get_window_extent(renderer)
            clash = any(box.overlaps(other) for other in taken) or any(
                j not in group
                and box.x0 - marker < x < box.x1 + marker
                and box.y0 - marker < y < box.y1 + marker
                for j, (x, y) in enumerate(markers)
            )
            if not clash and inside.contains(box.x0, box.y0) and inside.contains(box.x1, box.y1):
                taken.append(box)
                break
            label.remove()


def write_report(study: ConvergenceStudy, out: str | Path) -> dict[str, Path]:
    """Write ``convergence.csv``, ``convergence.md`` and ``work_precision.png`` into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "csv": out / "convergence.csv",
        "markdown": out / "convergence.md",
        "png": out / "work_precision.png",
    }
    paths["csv"].write_text(study.to_csv())
    paths["markdown"].write_text(study.to_markdown())
    plot_work_precision(study, paths["png"])
    return paths


def _settings(
    name: str, value: float, sample_dt: float, changes: Mapping[str, Any]
) -> tuple[float, dict[str, Any]]:
    """Step [s] and integrator settings of one run, a variant's ``changes`` included."""
    if name == "moreau_jean":
        return value, {**changes}
    if name == "event_driven":
        return sample_dt, {"rtol": value, "atol": ATOL_RATIO * value, **changes}
    return sample_dt, {
        "stiffness": value,
        "rtol": COMPLIANT_RTOL,
        "atol": ATOL_RATIO * COMPLIANT_RTOL,
        **changes,
    }


def _variant(label: str, changes: Mapping[str, Any]) -> tuple[str, str, dict[str, Any]]:
    """A checked variant: (label, integrator name, the other settings it changes)."""
    section = f"variants[{label!r}]"
    if not label or label in INTEGRATORS:
        raise InvalidParameterError("variant label", label, "a non-empty name of no integrator")
    fields = {field.name for field in dataclasses.fields(IntegratorSettings)}
    unknown = set(changes) - fields
    if unknown:
        raise UnknownKeyError(section, unknown, fields)
    if "name" not in changes:
        raise InvalidParameterError(f"{section} name", None, f"one of {list(INTEGRATORS)}")
    name = changes["name"]
    if name not in INTEGRATORS:
        raise NotFoundError("integrator", str(name), INTEGRATORS)
    swept = _SWEPT[name]
    if swept & set(changes):
        raise InvalidParameterError(
            section, dict(changes), f"no setting the sweep sets ({', '.join(sorted(swept))})"
        )
    others = {key: value for key, value in changes.items() if key != "name"}
    IntegratorSettings(name=name, **others)  # checks the values now, not after the first runs
    return label, name, others


def _simulate(
    scene: Scene,
    name: str,
    dt: float,
    options: dict[str, Any],
    duration: float,
    control_period: float | None,
) -> tuple[Log, dict[str, Any]]:
    methods = IVP_METHODS.get(name, ())
    if "method" not in options and scene.integrator.method not in methods:
        options = {**options, "method": None}  # the scene's method is another integrator's
    settings = dataclasses.replace(scene.integrator, name=name, dt=dt, **options)
    result = simulate(
        dataclasses.replace(scene, integrator=settings),
        duration=duration,
        control_period=control_period,
        progress=False,
    )
    return result.log, result.summary


def _bouncing_ball(scene: Scene, name: str) -> tuple[BouncingBall, int]:
    """The analytic motion of the gap of contact ``name``, and that contact's index."""
    names = [contact.name for contact in scene.contacts]
    if name not in names:
        raise NotFoundError("contact", name, names)
    index = names.index(name)  # contacts come first among the constraints
    contact = scene.contacts[index]
    gravity = -float(contact.surface.normal @ scene.robot.gravity)  # [m/s²] into the surface
    if gravity <= 0.0:
        raise InvalidParameterError(
            "[reference] bouncing_ball",
            gravity,
            f"gravity pressing contact {contact.name!r} onto its surface (> 0 along -normal)",
        )
    start = scene.build_integrator().evaluate(*scene.initial_state())
    ball = BouncingBall(
        height=float(start.gap[index]),
        velocity=float(start.normal_velocity[index]),
        restitution=contact.restitution,
        gravity=gravity,
    )
    return ball, index


def _configuration_error(scene: Scene, log: Log, reference: Log, period: float) -> float:
    """Largest ‖q ⊖ q_ref‖∞ at the multiples of ``period`` [s] both logs hold."""
    stride = round(period / float(log.metadata["dt"]))
    reference_stride = round(period / float(reference.metadata["dt"]))
    q = log.q[::stride]
    q_reference = reference.q[::reference_stride]
    n = min(len(q), len(q_reference))
    model = scene.robot.model
    return max(float(np.max(np.abs(pin.difference(model, q_reference[j], q[j])))) for j in range(n))


def _order_text(order: float) -> str:
    return "- (the error does not vary)" if math.isnan(order) else f"{order:.3f}"


def _positive_range(name: str, values: Sequence[float]) -> NDArray[np.float64]:
    array = np.array([as_positive(name, value) for value in values], dtype=float)
    if array.size == 0:
        raise InvalidParameterError(name, list(values), "at least one value")
    return array


def _check_divides(step: float, period: float, what: str) -> None:
    ratio = period / step
    if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * ratio:
        raise InvalidParameterError("dts", step, f"a step that divides {what}, {period:g} s")
