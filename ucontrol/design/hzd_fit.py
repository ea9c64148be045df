r"""Virtual constraints fitted to a designed step, and the walking scene that tracks them.

The hybrid-zero-dynamics controller (``[controller] type = "hzd"``) drives the actuated joints
:math:`q_a = (\text{stance hip}, \text{stance knee}, \text{swing hip}, \text{swing knee})` to
:math:`h_d(s) = \sum_{i=0}^{M} \alpha_i \binom{M}{i} s^i (1 - s)^{M - i}` along the phase

.. math::

    \theta(q) = \operatorname{atan2}(x_{hip} - x_{st},\; z_{hip} - z_{st}), \qquad
    s = \frac{\theta - \theta^+}{\theta^- - \theta^+}.

:func:`fit_bezier` fits the designed :math:`q_a(\theta)` by least squares with the four
endpoint coefficients fixed by the heel strike (Westervelt et al., *Feedback Control of Dynamic
Bipedal Robot Locomotion*, 2007, §6.3): :math:`\alpha_M = q_a^-`, :math:`\alpha_{M-1} =
\alpha_M - \frac{\Delta\theta}{M} \frac{\dot q_a^-}{\dot\theta^-}`, :math:`\alpha_0 = P
\alpha_M` (the legs swapped) and :math:`\alpha_1 = \alpha_0 + \frac{\Delta\theta}{M}
\frac{\dot q_a^+}{\dot\theta^+}` from the relabelled post-impact velocity, so that the
impact maps the fitted curve's end onto its start, positions and slopes.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ucontrol.design.designed_gait import DesignedGait
from ucontrol.design.gait_task import GaitTask
from ucontrol.exceptions import DesignError

Vector = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class BezierGait:
    """Bézier virtual constraints of a designed step.

    Attributes:
        alpha: Coefficients in [rad], shape (4, M + 1): rows stance hip, stance knee, swing
            hip, swing knee.
        theta_plus: Phase just after the heel strike in [rad].
        theta_minus: Phase just before it in [rad].
        rms_error: Root mean square of the fit's error at the design's grid points in [rad].
        max_error: Largest error in [rad].
    """

    alpha: Vector
    theta_plus: float
    theta_minus: float
    rms_error: float
    max_error: float

    @property
    def degree(self) -> int:
        """Degree M of the polynomials."""
        return int(self.alpha.shape[1] - 1)

    def outputs(self, theta: Vector) -> Vector:
        """h_d at the phases ``theta`` (n,) in [rad], shape (n, 4)."""
        s = (np.asarray(theta, dtype=float) - self.theta_plus) / (
            self.theta_minus - self.theta_plus
        )
        return bernstein(self.degree, s) @ self.alpha.T


def bernstein(degree: int, s: Vector) -> Vector:
    """Bernstein basis of ``degree`` at ``s`` (n,), shape (n, degree + 1)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))[:, None]
    i = np.arange(degree + 1)[None, :]
    binomial = np.array([math.comb(degree, k) for k in range(degree + 1)])[None, :]
    return np.asarray(binomial * s**i * (1.0 - s) ** (degree - i))


def phase(gait: DesignedGait, q: Vector, v: Vector | None = None) -> tuple[Vector, Vector]:
    """Phase θ (n,) in [rad] and its rate (n,) in [rad/s] (zeros without ``v``) along ``q``.

    The hip is the stance hip joint's origin, the stance foot ``gait.stance``.
    """
    robot = gait.robot
    hip = next(leg[0] for leg in gait.legs if leg[2] == gait.stance)
    q = np.atleast_2d(q)
    d = robot.frame_path(q, hip)[:, [0, 2]] - robot.frame_path(q, gait.stance)[:, [0, 2]]
    theta = np.arctan2(d[:, 0], d[:, 1])
    rate = np.zeros(len(q))
    if v is not None:
        for k, (qk, vk) in enumerate(zip(q, np.atleast_2d(v), strict=True)):
            dd = (robot.frame_jacobian(qk, hip) - robot.frame_jacobian(qk, gait.stance))[
                [0, 2]
            ] @ vk
            rate[k] = (d[k, 1] * dd[0] - d[k, 0] * dd[1]) / float(d[k] @ d[k])
    return theta, rate


def fit_bezier(gait: DesignedGait, degree: int) -> BezierGait:
    r"""Least-squares Bézier fit of the designed :math:`q_a(\theta)` (module docstring).

    Args:
        gait: The designed step.
        degree: Bézier degree M, >= 4 (four coefficients fixed by the heel strike).

    Raises:
        DesignError: The phase is not strictly increasing along the step (no virtual
            constraint of θ describes it), or the degree is below 4.
    """
    if degree < 4:
        raise DesignError(f"`degree` must be >= 4 (four endpoint coefficients), got {degree}")
    a = gait.actuated_indices
    R = gait.relabelling()
    theta, rate = phase(gait, gait.q, gait.v)
    if not np.all(np.diff(theta) > 0.0):
        raise DesignError(
            "the designed step's phase θ is not strictly increasing "
            f"(θ from {theta[0]:.4g} to {theta[-1]:.4g} rad): no Bézier virtual constraint of it"
        )
    q_plus, v_plus = R @ gait.q[-1], R @ gait.v_plus  # the next step's start
    theta_p, rate_p = phase(gait, q_plus[None, :], v_plus[None, :])
    span = float(theta[-1] - theta[0])
    alpha = np.zeros((4, degree + 1))
    alpha[:, -1] = gait.q[-1, a]
    alpha[:, -2] = alpha[:, -1] - span / degree * gait.v[-1, a] / rate[-1]
    alpha[:, 0] = q_plus[a]
    alpha[:, 1] = alpha[:, 0] + span / degree * v_plus[a] / rate_p[0]
    s = (theta - theta[0]) / span
    basis = bernstein(degree, s)
    fixed = [0, 1, degree - 1, degree]
    free = list(range(2, degree - 1))
    target = gait.q[:, a] - basis[:, fixed] @ alpha[:, fixed].T  # (n, 4)
    alpha[:, free] = np.linalg.lstsq(basis[:, free], target, rcond=None)[0].T
    error = basis @ alpha.T - gait.q[:, a]
    return BezierGait(
        alpha=alpha,
        theta_plus=float(theta_p[0]),
        theta_minus=float(theta[-1]),
        rms_error=float(np.sqrt(np.mean(error**2))),
        max_error=float(np.max(np.abs(error))),
    )


def hzd_scene_text(
    gait: DesignedGait,
    fit: BezierGait,
    *,
    urdf: str,
    friction: float,
    kp: float,
    kd: float,
    duration: float = 5.0,
    dt: float = 1e-3,
    name: str = "rabbit_walk_designed",
) -> str:
    """The TOML text of a scene walking the designed step under the HZD controller.

    Planar robot on the flat ground z = 0, point feet with Coulomb friction, plastic impacts
    (e = 0), Moreau–Jean; q0 and v0 the designed step's start (q0 raised by the swing foot's
    depth below the ground, the RK4 drift of the design's pinned foot, if any).

    Args:
        gait: The designed step.
        fit: Its Bézier virtual constraints.
        urdf: The robot's URDF path as the scene should name it (relative to the scene).
        friction: Coulomb coefficient of the feet.
        kp: Proportional gain of the controller in [1/s²].
        kd: Derivative gain in [1/s].
        duration: Simulated time in [s].
        dt: Moreau–Jean step in [s].
        name: The scene's name.
    """
    robot = gait.robot
    # the swing foot starts where the stance foot ended, below the ground by the RK4 drift of
    # the pinned foot (~1e-6 m): the robot is lifted by it so that the plant starts clear
    q0 = gait.q[0].copy()
    feet = [robot.frame_position(q0, leg[2])[2] for leg in gait.legs]
    q0[1] += max(0.0, -min(feet))

    def numbers(values: Vector) -> str:
        return "[" + ", ".join(repr(float(x)) for x in values) + "]"

    legs = ", ".join("[" + ", ".join(f'"{n}"' for n in leg) + "]" for leg in gait.legs)
    bezier = ",\n    ".join(numbers(row) for row in fit.alpha)
    contacts = "".join(
        f'\n[[contacts]]\nframe = "{leg[2]}"\nsurface = "ground"\nrestitution = 0.0\n'
        f"friction = {friction!r}\n"
        for leg in gait.legs
    )
    return f"""# {name}: a walking step of {robot.name} designed by optimal control (casadi,
# IPOPT) and tracked by the hybrid-zero-dynamics controller, its virtual constraints the Bézier
# fit of the designed step (degree {fit.degree}, rms error {fit.rms_error:.2e} rad). Written by
# `ucontrol design` / experiments/biped_gait_ocp.py (docs/legged.md, "Designing a gait"):
# step length {gait.step_length:.4g} m, step time {gait.step_time:.6g} s,
# speed {gait.speed:.4g} m/s.
# Released at the designed step's start, just after a heel strike of {gait.stance}.
name = "{name}"
duration = {duration!r}

[robot]
urdf = "{urdf}"
passive = {list(robot.joint_names[:3])!r}
planar_axis = [0.0, 1.0, 0.0]
q0 = {numbers(q0)}
v0 = {numbers(gait.v[0])}
gravity = {numbers(robot.gravity)}

[surfaces.ground]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
{contacts}
[integrator]
name = "moreau_jean"
dt = {dt!r}

[controller]
type = "hzd"
bezier = [
    {bezier},
]
theta_plus = {fit.theta_plus!r}      # [rad]
theta_minus = {fit.theta_minus!r}    # [rad]
kp = {kp!r}
kd = {kd!r}
legs = [{legs}]
stance = "{gait.stance}"
""".replace("passive = ['x', 'z', 'pitch']", 'passive = ["x", "z", "pitch"]')


def write_hzd_scene(
    path: str | Path,
    task: GaitTask,
    gait: DesignedGait,
    fit: BezierGait,
    *,
    duration: float = 5.0,
    name: str = "rabbit_walk_designed",
) -> Path:
    """Write :func:`hzd_scene_text` of a task's designed step to ``path`` (a TOML file).

    The scene names the task's URDF relative to itself and takes the task's scene friction
    and controller gains.

    Returns:
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # a task file always names its URDF
    urdf = os.path.relpath(str(task.robot.urdf_path), path.resolve().parent)
    text = hzd_scene_text(
        gait,
        fit,
        urdf=urdf,
        friction=task.written_friction,
        kp=task.kp,
        kd=task.kd,
        duration=duration,
        name=name,
    )
    path.write_text(text)
    return path
