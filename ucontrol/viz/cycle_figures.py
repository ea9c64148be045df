"""Figures of a run of the phase-machine controller: path, gaps, V, force, tracking error.

Uses matplotlib's object API with the Agg canvas (no pyplot state, no window).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ucontrol.control.brogliato_controller import BrogliatoController
from ucontrol.log import Log
from ucontrol.viz.figure_notes import annotate_clip, clip_note, legend_outside
from ucontrol.viz.phase_bands import phase_bands, phase_legend

if TYPE_CHECKING:
    from ucontrol.analysis.stability_check import StabilityCheck

#: Window of the moving mean of the measured contact force, in [s].
FORCE_WINDOW = 0.02
_AXIS_NAMES = "xyz"


def cycle_figures(
    log: Log,
    controller: BrogliatoController,
    out_dir: str | Path,
    name: str,
    *,
    plane: tuple[int, int] = (0, 1),
    check: StabilityCheck | None = None,
) -> list[Path]:
    r"""Write ``<name>_path.png`` and ``<name>_time.png`` into ``out_dir``.

    With ``check`` (:func:`~ucontrol.analysis.stability_check.check_scene` of the scene that
    ran), the time figure draws its bounds beside what the run measured: each contact's bound J
    on the jump of V over an accumulation of impacts (dashed, on V's panel, above its value
    before the first impact of each cycle) and the latest end of that accumulation,
    :math:`t_0 + T_\text{acc}` of each cycle (dotted, on the gaps' panel).

    Args:
        log: A run of ``controller`` (its fields V, phase, task_position, ...).
        controller: The controller that ran (its task, cycle and model are read).
        out_dir: Output folder, created if needed.
        name: Prefix of the file names.
        plane: World axes (0 = x, 1 = y, 2 = z) of the plane of the path figure.
        check: The a-priori stability check of the scene, or None (no bounds drawn).

    Returns:
        The paths of the two PNG files.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}_path.png", out_dir / f"{name}_time.png"]
    _path_figure(log, controller, plane).savefig(paths[0], dpi=110)
    _time_figure(log, controller, check).savefig(paths[1], dpi=110)
    return paths


def frame_positions(log: Log, controller: BrogliatoController) -> np.ndarray:
    """World positions of the controller's task frame at every sample in [m], shape (N, 3)."""
    return controller.robot.frame_path(log.q, controller.task.frame)


def _path_figure(log: Log, controller: BrogliatoController, plane: tuple[int, int]) -> Figure:
    a, b = plane
    figure = Figure(figsize=(7.5, 5.5), layout="constrained")
    ax = figure.add_subplot()
    cycle = controller.cycle
    nominal = np.array(
        [cycle.path(t)[0] for t in np.linspace(0.0, cycle.period, 400, endpoint=False)]
    )
    ax.plot(nominal[:, a], nominal[:, b], "k--", lw=1, label="nominal path")
    p = frame_positions(log, controller)
    ax.plot(p[:, a], p[:, b], lw=1.2, label=f"{controller.task.frame} (actual)")
    ax.plot(p[0, a], p[0, b], "o", label="start")
    ax.set_aspect("equal")
    ax.autoscale_view()
    for contact in controller.task.contacts:
        _draw_plane(ax, contact.surface.point, contact.surface.normal, plane, contact.name)
    ax.set_xlabel(f"{_AXIS_NAMES[a]} [m]")
    ax.set_ylabel(f"{_AXIS_NAMES[b]} [m]")
    legend_outside(ax, fontsize=8)
    ax.set_title("end-effector path")
    return figure


def _draw_plane(
    ax: Axes, point: np.ndarray, normal: np.ndarray, plane: tuple[int, int], label: str
) -> None:
    """The trace of a plane in the figure's plane, with its obstacle side hatched."""
    a, b = plane
    n2 = np.array([normal[a], normal[b]])
    if np.linalg.norm(n2) < 1e-9:
        return
    n2 /= np.linalg.norm(n2)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    span = 2.0 * max(x1 - x0, y1 - y0)
    view = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    centre = view - n2 * (n2 @ (view - np.array([point[a], point[b]])))  # on the trace
    direction = np.array([-n2[1], n2[0]])
    ends = np.array([centre - span * direction, centre + span * direction])
    ax.plot(ends[:, 0], ends[:, 1], color="0.3", lw=1.5, zorder=1)
    inside = np.array([*ends, ends[1] - span * n2, ends[0] - span * n2])
    ax.fill(
        inside[:, 0],
        inside[:, 1],
        facecolor="0.85",
        edgecolor="0.6",
        hatch="//",
        lw=0,
        zorder=0,
        label=label,
    )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)


def _time_figure(
    log: Log, controller: BrogliatoController, check: StabilityCheck | None = None
) -> Figure:
    figure = Figure(figsize=(9.0, 10.0), layout="constrained")
    axes = figure.subplots(4, 1, sharex=True)
    t = log.t
    task = controller.task
    for j in range(task.n_gaps):
        line = axes[0].plot(t, log.task_position[:, j], lw=1.2, label=f"{task.names[j]} gap")
        colour = line[0].get_color()
        axes[0].plot(t, log.task_desired[:, j], "--", color=colour, lw=1, label="desired")
        axes[0].plot(t, log.task_target[:, j], ":", color=colour, lw=1, label="target (virtual)")
    axes[0].set_ylabel("gap [m]")

    axes[1].semilogy(t, np.maximum(log.V, 1e-16), lw=1, label="V")
    axes[1].semilogy(t, np.maximum(log.V1, 1e-16), lw=0.8, alpha=0.7, label="V1")
    axes[1].set_ylabel("Lyapunov [J]")
    if check is not None:
        _draw_bounds(axes[0], axes[1], log, controller, check)
    legend_outside(axes[0])
    legend_outside(axes[1])

    window = max(1, round(FORCE_WINDOW / float(log.metadata["dt"])))
    peak = float(log.lambda_d.max(initial=1.0))
    for i, contact in enumerate(controller.machine.contacts):
        force = log.contact_force[:, i]
        line = axes[2].plot(t, force, lw=0.4, alpha=0.5, label=f"{contact} (impulse/dt)")
        colour = line[0].get_color()
        mean = np.convolve(force, np.ones(window) / window, mode="same")
        axes[2].plot(t, mean, color=colour, lw=1.4, label=f"{FORCE_WINDOW * 1e3:.0f} ms mean")
        axes[2].plot(t, log.lambda_d[:, i], "k--", lw=1, label="λ_d" if i == 0 else None)
    low, high = -0.1 * peak, 2.0 * peak  # [N] impact peaks above are left out
    axes[2].set_ylim(low, high)
    annotate_clip(axes[2], clip_note(log.contact_force, low, high, "N"))
    axes[2].set_ylabel("contact force [N]")
    legend_outside(axes[2])

    error = np.linalg.norm(log.task_position - log.task_desired, axis=1)
    axes[3].semilogy(t, np.maximum(error, 1e-12), lw=1)
    axes[3].set_ylabel("‖X − X_d‖ [m]")
    axes[3].set_xlabel("t [s]")
    for ax in axes:
        phase_bands(ax, t, log.phase)
    phase_legend(figure)
    return figure


def _draw_bounds(
    gaps: Axes, lyapunov: Axes, log: Log, controller: BrogliatoController, check: StabilityCheck
) -> None:
    """The check's jump bound of V and accumulation-end bound, cycle by cycle (time figure)."""
    period = controller.cycle.path.period  # [s]
    t = log.t
    for record in check.contacts:
        if not np.isfinite(record.accumulation_time_bound):
            continue  # no bound to draw (the check says the accumulation may not end)
        starts = np.arange(record.first_impact, t[-1], period)  # [s] each cycle's t0
        label = f"{record.contact}: bound J on the jump of V"
        for k, start in enumerate(starts):
            before = float(log.V[log.row_at(min(start, t[-1]))])  # V just before the impacts
            end = min(start + record.accumulation_time_bound, t[-1])
            lyapunov.hlines(
                before + record.jump_bound, start, end, colors="tab:red", linestyles="--",
                lw=1, label=label if k == 0 else "_",
            )  # fmt: skip
            gaps.axvline(
                start + record.accumulation_time_bound, color="tab:red", ls=":", lw=1,
                label="t0 + accumulation bound" if k == 0 else "_",
            )  # fmt: skip
