"""The figure of a designed walking step (matplotlib, imported when a figure is drawn)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ucontrol.design.designed_gait import DesignedGait
from ucontrol.design.hzd_fit import BezierGait, phase

#: Length of the torso's line in the stick figures [m] (its direction is the pitch).
_TORSO_DRAWN = 0.3


def save_gait_figure(
    gait: DesignedGait,
    fit: BezierGait,
    path: str | Path,
    *,
    steps: Mapping[str, Sequence[float]] | None = None,
) -> None:
    """Draw the designed step, q_a(θ) with its fit, the torques and, given, a run's steps.

    Args:
        gait: The designed step.
        fit: Its Bézier virtual constraints.
        path: The PNG file to write.
        steps: A closed-loop run's ``lengths`` [m] and ``periods`` [s] of its steps, drawn
            against the design's; None: the fourth panel holds the stance-foot force.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robot = gait.robot
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5))
    ax = axes[0, 0]
    chains = list(gait.legs)
    for k in range(0, len(gait.q), max(1, len(gait.q) // 8)):
        q = gait.q[k]
        for chain, colour in zip(chains, ("C0", "C3"), strict=True):
            points = np.array([robot.frame_position(q, name)[[0, 2]] for name in chain])
            ax.plot(points[:, 0], points[:, 1], "-o", color=colour, ms=2, lw=1, alpha=0.7)
        hip = robot.frame_position(q, gait.legs[0][0])
        top = hip + _TORSO_DRAWN * np.array([np.sin(q[2]), 0.0, np.cos(q[2])])
        ax.plot([hip[0], top[0]], [hip[2], top[2]], "k-", lw=1.5, alpha=0.6)
    swing = robot.frame_path(gait.q, gait.swing)
    ax.plot(swing[:, 0], swing[:, 2], "C3--", lw=1, label="swing foot")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(
        f"designed step: L = {gait.step_length:.3g} m, T = {gait.step_time:.3g} s "
        "(left stance blue)"
    )
    ax.legend(loc="upper left", fontsize=8)

    ax = axes[0, 1]
    theta, _ = phase(gait, gait.q)
    dense = np.linspace(fit.theta_plus, fit.theta_minus, 200)
    labels = ("stance hip", "stance knee", "swing hip", "swing knee")
    for i, label in enumerate(labels):
        ax.plot(theta, gait.q[:, gait.actuated_indices[i]], "o", color=f"C{i}", ms=3)
        ax.plot(dense, fit.outputs(dense)[:, i], "-", color=f"C{i}", label=label)
    ax.set_xlabel("phase θ [rad]")
    ax.set_ylabel("q_a [rad]")
    ax.set_title(
        f"q_a(θ): design (dots), Bézier degree {fit.degree} "
        f"(max error {1e3 * fit.max_error:.2g} mrad)"
    )
    ax.legend(fontsize=8)

    ax = axes[1, 0]
    names = [robot.joint_names[i] for i in robot.actuated]
    for i, name in enumerate(names):
        ax.step(gait.t[:-1], gait.tau[:, i], where="post", label=name)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("τ [N m]")
    ax.set_title(f"torques; cost ∫|τ|² dt / L = {gait.cost:.4g} N² m² s/m")
    ax.legend(fontsize=8)

    ax = axes[1, 1]
    if steps is not None and len(steps["lengths"]):
        n = np.arange(1, len(steps["lengths"]) + 1)
        ax.plot(n, np.array(steps["lengths"]) / gait.step_length, "o-", label="step length / L")
        ax.plot(n, np.array(steps["periods"]) / gait.step_time, "s-", label="period / T")
        ax.axhline(1.0, color="0.5", lw=0.8)
        ax.set_xlabel("step of the closed loop")
        ax.set_ylabel("closed loop / designed")
        ax.set_title("HZD controller on the designed gait (Moreau–Jean)")
    else:
        ax.plot(gait.t, gait.force[:, 1], label="normal")
        ax.plot(gait.t, gait.force[:, 0], label="tangential")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("stance-foot force [N]")
        ax.set_title("stance-foot force of the design")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
