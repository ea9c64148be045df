"""Figures of a designed cycle.

Joint and task trajectories with phase bands, torques against their limits, contact force
(matplotlib's object API, Agg canvas: no window).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ucontrol.design.designed_cycle import DesignedCycle

_BAND_COLOURS = {"flight": "#ffffff", "bounce": "#fde7c8", "contact": "#d8e8f8"}


def _bands(ax: Axes, cycle: DesignedCycle) -> None:
    for phase in cycle.phases:
        ax.axvspan(phase.t[0], phase.t[-1], color=_BAND_COLOURS[phase.kind], alpha=0.8, lw=0)
    for t in cycle.impact_times:
        ax.axvline(t, color="0.4", lw=0.8, ls=":")


def _stairs(ax: Axes, cycle: DesignedCycle, column: int, **style: Any) -> None:
    for k, phase in enumerate(cycle.phases):
        label = style.pop("label", None) if k == 0 else None
        ax.stairs(phase.tau[:, column], phase.t, baseline=None, label=label, **style)


def save_design_figures(
    cycle: DesignedCycle,
    torque_limit: np.ndarray,
    joint_names: list[str],
    out: str | Path,
    plane: tuple[int, int] | None = None,
) -> list[Path]:
    """Write ``joints.png``, ``task.png`` and ``torques_force.png`` into ``out``.

    Args:
        cycle: The designed cycle.
        torque_limit: Torque limits in [N m], shape (nv,).
        joint_names: Names of the joints, in order.
        out: Output directory (created).
        plane: World axes (0: x, 1: y, 2: z) of the task figure's path plot; default the two
            along which the frame moves most.

    Returns:
        The paths written.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "joints.png", out / "task.png", out / "torques_force.png"]
    nv = len(joint_names)

    figure = Figure(figsize=(8, 5), layout="constrained")
    axes = figure.subplots(2, 1, sharex=True)
    for ax, (key, unit) in zip(axes, (("q", "rad"), ("v", "rad/s")), strict=True):
        _bands(ax, cycle)
        for j in range(nv):
            for k, phase in enumerate(cycle.phases):
                ax.plot(
                    phase.t,
                    getattr(phase, key)[:, j],
                    color=f"C{j}",
                    marker=".",
                    ms=3,
                    label=joint_names[j] if k == 0 else None,
                )
        ax.set_ylabel(f"{key} [{unit}]")
        ax.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("t [s] (from takeoff)")
    axes[0].set_title("Joint trajectories (bands: flight, bounces, contact)")
    figure.savefig(paths[0], dpi=110)

    if plane is None:
        spread = np.ptp(np.vstack([phase.position for phase in cycle.phases]), axis=0)
        plane = tuple(sorted(int(i) for i in np.argsort(spread)[-2:]))  # type: ignore[assignment]
    assert plane is not None
    a, b = plane
    figure = Figure(figsize=(8, 4.5), layout="constrained")
    left, right = figure.subplots(1, 2)
    for k, phase in enumerate(cycle.phases):
        left.plot(
            phase.position[:, a],
            phase.position[:, b],
            marker=".",
            ms=3,
            color={"flight": "C0", "bounce": "C1", "contact": "C3"}[phase.kind],
            label=phase.kind if phase.kind not in [p.kind for p in cycle.phases[:k]] else None,
        )
    path = cycle.nominal_path()
    t = np.linspace(0.0, cycle.period, 800)
    smooth = np.array([path(float(s))[0] for s in t])
    left.plot(smooth[:, a], smooth[:, b], color="0.5", lw=0.8, label="nominal path (spline)")
    left.set_xlabel(f"{'xyz'[a]} [m]")
    left.set_ylabel(f"{'xyz'[b]} [m]")
    left.set_aspect("equal", adjustable="datalim")
    left.legend(fontsize=8)
    left.set_title(f"{cycle.frame} in the world")
    _bands(right, cycle)
    for i, name in enumerate("xyz"):
        if np.ptp(smooth[:, i]) > 1e-9:
            right.plot(t, smooth[:, i], label=name)
    right.set_xlabel("t [s]")
    right.set_ylabel("position [m]")
    right.legend(fontsize=8)
    figure.savefig(paths[1], dpi=110)

    figure = Figure(figsize=(8, 5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    _bands(top, cycle)
    for j in range(nv):
        _stairs(top, cycle, j, color=f"C{j}", label=joint_names[j])
        top.axhline(torque_limit[j], color=f"C{j}", ls="--", lw=0.8)
        top.axhline(-torque_limit[j], color=f"C{j}", ls="--", lw=0.8)
    top.set_ylabel("torque [N m]")
    top.set_ylim(-1.1 * np.max(torque_limit), 1.1 * np.max(torque_limit))
    top.legend(fontsize=8)
    top.set_title("Torques (dashed: limits) and normal contact force")
    _bands(bottom, cycle)
    for phase in cycle.phases:
        if phase.kind == "contact":
            bottom.plot(phase.t, phase.force, color="C3", marker=".", ms=3)
    bottom.axhline(cycle.force, color="0.5", ls=":", lw=0.8)
    bottom.set_ylabel("contact force [N]")
    bottom.set_xlabel("t [s] (from takeoff)")
    figure.savefig(paths[2], dpi=110)
    return paths
