"""Figures of any saved run: configuration, gaps, contact forces, energy, and tracking.

``q.png``, ``gaps.png``, ``forces.png`` and ``energy.png`` for every run; ``tracking.png``
(task coordinates against the desired and virtual ones, tracking error, Lyapunov function V)
when the controller logged them; with the scene of a phase-machine run, the end-effector path
and the cycle summary of :func:`ucontrol.viz.cycle_figures.cycle_figures`. Phase bands shade
the time axes of runs with a ``phase`` field. Uses matplotlib's object API with the Agg canvas.

Curves are named after the URDF's joints when the scene is known, legends sit to the right of
the axes (never over a curve), and a panel whose scale leaves samples out says how many and
the range of the values left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ucontrol.analysis.coordinates import UNKNOWN_UNIT, coordinate_names, coordinate_units
from ucontrol.analysis.energy_balance import actuator_work
from ucontrol.analysis.impacts import impact_mask
from ucontrol.analysis.stability_check import StabilityCheck
from ucontrol.control.brogliato_controller import BrogliatoController
from ucontrol.exceptions import InvalidParameterError
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.viz.cycle_figures import FORCE_WINDOW, cycle_figures, frame_positions
from ucontrol.viz.figure_notes import annotate_clip, clip_note, legend_outside
from ucontrol.viz.phase_bands import phase_bands, phase_legend

#: Resolution of the PNG files in [dots per inch].
DPI = 110
#: Height of one panel of the per-constraint figures in [in].
PANEL_HEIGHT = 1.8
#: Colour of the impact lines of the energy figure: dark, to stand out on every phase band.
IMPACT_LINE_COLOUR = "0.15"


def run_figures(log: Log, out_dir: str | Path, *, scene: Scene | None = None) -> list[Path]:
    """Write the figures of a run as PNG files into ``out_dir``.

    Args:
        log: The run (e.g. ``Log.load(DIR / "log.npz")``).
        out_dir: Output folder, created if needed.
        scene: The scene of the run; it names the joints after the URDF, and with a
            phase-machine controller (``type = "brogliato"``) it names the task coordinates and
            adds ``cycle_path.png`` and ``cycle_time.png``.

    Returns:
        The paths of the files written.

    Raises:
        InvalidParameterError: The scene's controller does not match the logged task
            coordinates.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    controller = _phase_controller(log, scene)
    figures = run_figure_set(log, scene=scene, controller=controller)
    paths = []
    for name, figure in figures.items():
        paths.append(out_dir / f"{name}.png")
        figure.savefig(paths[-1], dpi=DPI)
    if controller is not None:
        positions = frame_positions(log, controller)
        plane = tuple(int(axis) for axis in np.sort(np.argsort(positions.std(axis=0))[-2:]))
        paths += cycle_figures(
            log,
            controller,
            out_dir,
            "cycle",
            plane=(plane[0], plane[1]),
            check=_stability_check(scene),
        )
    return paths


def _stability_check(scene: Scene | None) -> StabilityCheck | None:
    """The a-priori check of a rigid Brogliato scene (its bounds on the cycle figure), or None."""
    if scene is None or scene.flexible is not None:
        return None
    from ucontrol.analysis.stability_check import check_scene

    return check_scene(scene)


def run_figure_set(
    log: Log, *, scene: Scene | None = None, controller: BrogliatoController | None = None
) -> dict[str, Figure]:
    """The figures :func:`run_figures` writes (but the cycle ones), by file stem, unsaved.

    Args:
        log: The run.
        scene: The scene of the run: joint names for the configuration figure.
        controller: The phase-machine controller of the run: names of the task coordinates.

    Returns:
        ``q``, ``gaps``, ``forces``, ``energy`` and, when the controller logged task
        coordinates, ``tracking``.
    """
    units = constraint_units(log, scene)
    figures = {
        "q": _configuration_figure(log, None if scene is None else scene.robot.model),
        "gaps": _gap_figure(log, [gap for gap, _ in units]),
        "forces": _force_figure(log, [force for _, force in units]),
        "energy": _energy_figure(log),
    }
    if "task_position" in log.fields:
        names = None if controller is None else controller.task.names
        figures["tracking"] = _tracking_figure(log, names)
    return figures


def _phase_controller(log: Log, scene: Scene | None) -> BrogliatoController | None:
    """The scene's phase-machine controller when the log is a run of it, else None."""
    if scene is None or "phase" not in log.fields:
        return None
    controller = scene.build_controller()
    if not isinstance(controller, BrogliatoController):
        return None
    m = log.task_position.shape[1]
    if controller.task.m != m:
        raise InvalidParameterError(
            "scene", scene.name, f"a controller with the run's {m} task coordinates"
        )
    return controller


def _time_axes(log: Log, rows: int, height: float) -> tuple[Figure, list[Axes]]:
    """A figure of ``rows`` panels sharing the time axis, shaded by phase when logged."""
    figure = Figure(figsize=(9.0, max(3.0, height * rows + 1.0)), layout="constrained")
    axes = list(np.atleast_1d(figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]))
    if "phase" in log.fields:
        for ax in axes:
            phase_bands(ax, log.t, log.phase)
        phase_legend(figure)
    axes[-1].set_xlabel("t [s]")
    return figure, axes


def constraint_units(log: Log, scene: Scene | None) -> list[tuple[str, str]]:
    """Units of the gap and of the force of each constraint of the log.

    Contacts have gaps in [m] and forces in [N]; a joint stop has the unit of its joint's
    coordinate, [rad] and [N m] on a revolute joint, [m] and [N] on a prismatic one. Without
    the scene (or with one of other constraints), names ending in ``/lower`` or ``/upper``
    (those of stops) get both units, e.g. ``rad or m``.

    Args:
        log: The run.
        scene: The scene of the run, or None.

    Returns:
        (gap unit, force unit) of each of ``log.constraint_names``.
    """
    contact, angle = ("m", "N"), ("rad", "N m")
    if scene is None or scene.constraints.names != log.constraint_names:
        either = ("rad or m", "N m or N")
        return [
            either if name.endswith(("/lower", "/upper")) else contact
            for name in log.constraint_names
        ]
    constraints = scene.constraints
    model = scene.robot.model
    q_units, _ = coordinate_units(model, model.nq, model.nv)
    stops = [angle if q_units[q] == "rad" else contact for q, _ in constraints.stop_coordinates]
    return [contact] * constraints.n_contacts + stops + [contact] * len(constraints.clearances)


def _unit_groups(units: list[str]) -> list[tuple[str, list[int]]]:
    """The distinct units of a list in order of appearance, each with its indices."""
    groups: dict[str, list[int]] = {}
    for i, unit in enumerate(units):
        groups.setdefault(unit, []).append(i)
    return list(groups.items())


def _unit_label(symbol: str, unit: str) -> str:
    """Axis label of a quantity in a unit: ``q [rad]``; ``[-]`` for dimensionless ones."""
    if unit == UNKNOWN_UNIT:
        return f"{symbol} (unit unknown without the scene)"
    return f"{symbol} [{'-' if unit == '1' else unit}]"


def _configuration_figure(log: Log, model: pin.Model | None) -> Figure:
    """Configuration and velocity, one panel per unit (angles apart from lengths)."""
    nq, nv = log.q.shape[1], log.v.shape[1]
    q_names, v_names = coordinate_names(model, nq, nv)
    q_units, v_units = coordinate_units(model, nq, nv)
    panels = [("q", log.q, q_names, unit, rows) for unit, rows in _unit_groups(q_units)]
    panels += [("v", log.v, v_names, unit, rows) for unit, rows in _unit_groups(v_units)]
    figure, axes = _time_axes(log, len(panels), 2.2)
    for ax, (symbol, values, names, unit, rows) in zip(axes, panels, strict=True):
        for i in rows:
            ax.plot(log.t, values[:, i], lw=1, label=names[i])
        ax.set_ylabel(_unit_label(symbol, unit))
        legend_outside(ax, ncol=1 if len(rows) <= 12 else 2)
    axes[0].set_title("configuration q and velocity v, one axis per unit")
    return figure


def _gap_figure(log: Log, units: list[str]) -> Figure:
    names = log.constraint_names
    figure, axes = _time_axes(log, max(1, len(names)), PANEL_HEIGHT)
    impacts = impact_mask(log)
    for i, (ax, name) in enumerate(zip(axes, names, strict=False)):
        ax.plot(log.t, log.gap[:, i], lw=1.2, label="gap")
        ax.axhline(0.0, color="0.3", lw=0.8)
        rows = np.flatnonzero(impacts[:, i])
        ax.plot(log.t[rows], log.gap[rows, i], "v", ms=4, color="C3", label="impact")
        ax.set_ylabel(f"{name}\n[{units[i]}]", fontsize=8)
        legend_outside(ax)
    axes[0].set_title("gaps; negative = penetration")
    return figure


def _force_figure(log: Log, units: list[str]) -> Figure:
    """Mean force impulse / dt of each constraint, its moving mean and the desired force.

    Constraints that never carry an impulse are only named in the title. The y scale of a panel
    is set by the forces carried between impacts and the desired force, or, on a constraint
    that only takes impacts, by the largest moving mean (the impulses spread over
    :data:`~ucontrol.viz.cycle_figures.FORCE_WINDOW`); the impact peaks above it are clipped
    and their number and range written in the panel.
    """
    desired = _desired_forces(log)
    names = log.constraint_names
    shown = [i for i, name in enumerate(names) if log.impulse[:, i].any() or name in desired]
    figure, axes = _time_axes(log, max(1, len(shown)), PANEL_HEIGHT)
    dt = float(log.metadata["dt"])  # [s]
    window = max(1, round(FORCE_WINDOW / dt))
    t = log.t[:-1]  # [s] start of each step
    impacts = impact_mask(log)
    for ax, i in zip(axes, shown, strict=False):
        name = names[i]
        force = log.impulse[:-1, i] / dt  # [N] (or [N m]) over each step; the last row has none
        ax.plot(t, force, lw=0.5, alpha=0.5, label="impulse / dt")
        kernel = np.ones(window)
        mean = np.convolve(force, kernel, "same") / np.convolve(np.ones_like(force), kernel, "same")
        ax.plot(t, mean, lw=1.3, label=f"{FORCE_WINDOW * 1e3:.0f} ms mean")
        # The scale is that of the forces carried between impacts (and the desired force):
        # impact peaks above it are clipped, and the panel says so with their range.
        carried = force[(force > 0.0) & ~impacts[:-1, i]]
        if carried.size:
            top = float(np.percentile(carried, 99))
        else:  # impacts only: their mean over the window sets the scale
            top = float(mean.max()) if (mean > 0.0).any() else 1.0
        if name in desired:
            ax.plot(t, desired[name][:-1], "k--", lw=1, label="λ_d (desired)")
            top = max(top, 1.5 * float(desired[name].max()))
        low, high = -0.05 * top, 1.3 * top  # [N] impact peaks above are left out
        ax.set_ylim(low, high)
        annotate_clip(ax, clip_note(force, low, high, units[i]))
        ax.set_ylabel(f"{name}\n[{units[i]}]", fontsize=8)
        legend_outside(ax)
    title = "contact forces: impulse / dt"
    idle = [name for i, name in enumerate(names) if i not in shown]
    if idle:
        title += f"\nno force on: {', '.join(idle)}"
    axes[0].set_title(title, fontsize=10)
    return figure


def _desired_forces(log: Log) -> dict[str, np.ndarray]:
    """The desired force λ_d of each constraint the controller logged one for, in [N]."""
    if "lambda_d" not in log.fields:
        return {}
    contacts = log.metadata.get("controller_contacts", [])
    return {name: log.lambda_d[:, j] for j, name in enumerate(contacts)}


def _energy_figure(log: Log) -> Figure:
    figure, (ax,) = _time_axes(log, 1, 3.5)
    work = actuator_work(log)  # [J]
    ax.plot(log.t, log.energy, lw=1.2, label="E = kinetic + potential")
    if np.any(work != 0.0):
        ax.plot(log.t, log.energy - work, lw=1.2, label="E − actuator work")
    for k, row in enumerate(np.flatnonzero(impact_mask(log).any(axis=1))):
        label = "impact" if k == 0 else None  # one legend entry for all the lines
        ax.axvline(log.t[row], color=IMPACT_LINE_COLOUR, lw=0.8, ls="--", label=label, zorder=1)
    ax.set_ylabel("energy [J]")
    ax.set_title("energy")
    legend_outside(ax, fontsize=8)
    return figure


def _tracking_figure(log: Log, names: list[str] | None) -> Figure:
    """Task coordinates against desired and virtual ones, tracking error, V and V1."""
    m = log.task_position.shape[1]
    labels = names if names is not None else [f"X[{j}]" for j in range(m)]
    figure, axes = _time_axes(log, m + 2, 2.0)
    for j in range(m):
        ax = axes[j]
        ax.plot(log.t, log.task_position[:, j], lw=1.2, label="X")
        ax.plot(log.t, log.task_desired[:, j], "k--", lw=1, label="X_d (desired)")
        ax.plot(log.t, log.task_target[:, j], ":", color="C3", lw=1, label="X_d* (virtual)")
        ax.set_ylabel(f"{labels[j]} [m]", fontsize=8)
        legend_outside(ax)
    error = np.abs(log.task_position - log.task_desired)  # [m]
    ax = axes[m]
    for j in range(m):
        ax.semilogy(log.t, np.maximum(error[:, j], 1e-12), lw=0.8, label=f"|X̃| {labels[j]}")
    ax.semilogy(log.t, np.maximum(np.linalg.norm(error, axis=1), 1e-12), "k", lw=1, label="‖X̃‖")
    ax.set_ylabel("tracking error [m]")
    legend_outside(ax)
    ax = axes[m + 1]
    ax.semilogy(log.t, np.maximum(log.V, 1e-16), lw=1.2, label="V")
    ax.semilogy(log.t, np.maximum(log.V1, 1e-16), lw=0.8, alpha=0.7, label="V1 = ½ sᵀ M̄ s")
    ax.set_ylabel("Lyapunov [J]")
    legend_outside(ax)
    axes[0].set_title("task coordinates X = (gaps, tangential) against the desired ones")
    return figure
