r"""Coulomb friction cases: the measured figures of docs/friction.md.

- ``incline``: the block of ``robots/block_incline.toml`` (planar) and
  ``robots/block_incline_spatial.toml`` (free body, four corners) on inclines of several angles
  α with μ = 0.5: it must stick for ever iff tan α <= μ, else slide with acceleration
  g (sin α - μ cos α); the measured acceleration and its relative error.
- ``stop``: the planar block launched at 1 m/s on flat ground with μ = 0.5 stops at
  t* = v0 / (μ g), after d* = v0² / (2 μ g); the measured time and distance against h.
- ``admm``: seeded random Coulomb problems (1 to 20 contacts, planar and spatial, half of them
  redundant) solved by :class:`~ucontrol.solvers.ProxsuiteCoulombSolver` and by Pinocchio's
  ADMM (:class:`~ucontrol.solvers.PinocchioContactSolver`); how many each solves, and how far
  apart their velocities are.
- ``painleve``: ``robots/painleve_rod.toml`` (μ = 1.5 above the critical 1.375 of its angle)
  against μ = 1.0: the first step's normal impulse over m g h for several h (a tangential
  impact has an impulse independent of h), and the acceleration-level problem at t = 0.
- ``beads``: ``robots/beads.toml`` (frictionless, 3 s) and the same column with μ = 0.3
  (2 s): penetration against h times the largest closing speed, energy at impacts.

Run: ``python experiments/friction_cases.py`` (about 1 min); writes
``docs/figures/friction_cases.md`` and ``docs/figures/painleve_rod.png`` (``--out``).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.analysis.impacts import impact_mask
from ucontrol.contact import Plane
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import SimulationResult, simulate
from ucontrol.solvers import CoulombProblem, PinocchioContactSolver, ProxsuiteCoulombSolver

GRAVITY = 9.81  # [m/s²]
HALF_HEIGHT = 0.05  # [m], of the block: its centre is this far above its bottom face
OVERLAP = 1e-10  # [m], initial overlap of the block's corners: active from the first step
FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"

Vector = NDArray[np.float64]


def incline(alpha: float, mu: float, *, spatial: bool = False, dt: float = 1e-3) -> Scene:
    """The block at rest on an incline of angle ``alpha`` [rad] with friction ``mu``.

    Planar (robots/block_incline.toml, q = (x, z, pitch)) or spatial
    (robots/block_incline_spatial.toml, free-flyer).
    """
    name = "block_incline_spatial.toml" if spatial else "block_incline.toml"
    scene = load_scene(builtin_scene(name))
    normal = np.array([np.sin(alpha), 0.0, np.cos(alpha)])
    surface = Plane(normal=normal, name="incline")
    contacts = tuple(
        dataclasses.replace(contact, surface=surface, friction=mu) for contact in scene.contacts
    )
    centre = (HALF_HEIGHT - OVERLAP) * normal
    if spatial:
        q0 = np.concatenate((centre, [0.0, np.sin(alpha / 2.0), 0.0, np.cos(alpha / 2.0)]))
    else:
        q0 = np.array([centre[0], centre[2], alpha])
    integrator = dataclasses.replace(scene.integrator, dt=dt)
    return dataclasses.replace(scene, contacts=contacts, q0=q0, integrator=integrator)


def slope_velocity(result: SimulationResult, alpha: float, *, spatial: bool = False) -> Vector:
    """Velocity of the block down the slope at every sample in [m/s], shape (N,)."""
    v = result.log.v
    if spatial:  # free-flyer velocity in the block's frame, whose x axis is down the slope
        return np.asarray(v[:, 0])
    return np.asarray(v[:, 0] * np.cos(alpha) - v[:, 1] * np.sin(alpha))


def incline_case(
    alpha: float, mu: float, *, spatial: bool = False, duration: float = 1.0, dt: float = 1e-3
) -> dict[str, Any]:
    """Run the block on the incline; its measured and expected acceleration [m/s²]."""
    result = simulate(incline(alpha, mu, spatial=spatial, dt=dt), duration=duration)
    velocity = slope_velocity(result, alpha, spatial=spatial)
    acceleration = np.diff(velocity) / dt  # [m/s²], one per step
    expected = max(GRAVITY * (np.sin(alpha) - mu * np.cos(alpha)), 0.0)
    error = np.max(np.abs(acceleration - expected))
    return {
        "alpha_deg": np.degrees(alpha),
        "spatial": spatial,
        "sticks": bool(np.tan(alpha) <= mu),
        "expected": expected,
        "measured": float(np.mean(acceleration)),
        "error": float(error),
        "relative_error": float(error / expected) if expected > 0.0 else None,
        "max_speed_if_stuck": float(np.max(np.abs(velocity))),
        "max_residual": result.summary["max_complementarity_residual"],
    }


def flat_slide(v0: float, mu: float, dt: float) -> Scene:
    """The planar block on flat ground, launched along x at ``v0`` [m/s], friction ``mu``."""
    scene = incline(0.0, mu, dt=dt)
    return dataclasses.replace(scene, v0=np.array([v0, 0.0, 0.0]))


def stop_case(v0: float, mu: float, dt: float) -> dict[str, float]:
    """Stop time [s] and distance [m] of the sliding block against t* = v0/(μg), d* = v0²/(2μg)."""
    t_star = v0 / (mu * GRAVITY)
    result = simulate(flat_slide(v0, mu, dt), duration=1.5 * t_star)
    log = result.log
    stopped = np.flatnonzero(np.abs(log.v[:, 0]) <= 1e-12)[0]
    return {
        "dt": dt,
        "t_stop": float(log.t[stopped]),
        "t_error": float(log.t[stopped] - t_star),
        "distance": float(log.q[-1, 0] - log.q[0, 0]),
        "d_error": float(log.q[-1, 0] - log.q[0, 0] - v0**2 / (2.0 * mu * GRAVITY)),
    }


def random_problem(
    rng: np.random.Generator,
    m: int,
    *,
    spatial: bool,
    redundant: bool,
    mu_max: float = 0.6,
    tangential_scale: float = 0.5,
) -> CoulombProblem:
    r"""A Coulomb problem of m contacts built like a Moreau–Jean step, solvable by construction.

    Rows H (r × n): normal rows :math:`w + \tfrac12 \xi` sharing a direction w that opens every
    contact, tangential rows ``tangential_scale`` times Gaussian; n = r + 3 degrees of freedom,
    or 1 to 3 fewer than the r rows when ``redundant``. A random SPD mass matrix M,
    :math:`D = H M^{-1} H^T`, :math:`b = H v_\text{free}` (approaching, :math:`v_\text{free}`
    has -w in it) plus a restitution term on half of the contacts; μ uniform in
    [0.1, ``mu_max``].
    """
    tangents = np.full(m, 2 if spatial else 1)
    r = m + int(tangents.sum())
    n = max(1, r - int(rng.integers(1, 4))) if redundant else r + 3
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    w = rng.standard_normal(n)
    w /= np.linalg.norm(w)
    H = rng.standard_normal((r, n))
    H[:m] = w + 0.5 * H[:m]
    H[m:] *= tangential_scale
    D = H @ np.linalg.solve(M, H.T)
    v_free = rng.standard_normal(n) - w
    b = H @ v_free
    restitution = rng.uniform(0.0, 1.0, m) * (rng.random(m) < 0.5)
    b[:m] += restitution * np.minimum(H[:m] @ rng.standard_normal(n), 0.0)
    return CoulombProblem(0.5 * (D + D.T), b, rng.uniform(0.1, mu_max, m), tangents)


def admm_case(seed: int, count: int, **options: float) -> dict[str, Any]:
    """``count`` random problems (:func:`random_problem`) solved by ucontrol and by ADMM.

    Returns the problems solved by each, the largest velocity difference where both solved
    (relative to max |b|) and the number of those above 1e-6.
    """
    rng = np.random.default_rng(seed)
    ours, admm = ProxsuiteCoulombSolver(), PinocchioContactSolver("admm")
    solved = {"ucontrol": 0, "admm": 0}
    differences = []
    for _ in range(count):
        m = int(rng.integers(1, 21))
        spatial, redundant = bool(rng.random() < 0.5), bool(rng.random() < 0.5)
        problem = random_problem(rng, m, spatial=spatial, redundant=redundant, **options)
        first, second = ours.solve_coulomb(problem), admm.solve_coulomb(problem)
        solved["ucontrol"] += first.status == "solved"
        solved["admm"] += second.status == "solved"
        if first.status == second.status == "solved":
            scale = np.max(np.abs(problem.b))
            differences.append(np.max(np.abs(first.velocity - second.velocity)) / scale)
    return {
        "seed": seed,
        "problems": count,
        **solved,
        "max_difference": float(max(differences, default=0.0)),
        "above_1e-6": int(np.sum(np.asarray(differences) > 1e-6)),
    }


def painleve(mu: float, dt: float = 1e-3) -> Scene:
    """robots/painleve_rod.toml with friction ``mu`` on both ends and step ``dt`` [s]."""
    scene = load_scene(builtin_scene("painleve_rod.toml"))
    contacts = tuple(dataclasses.replace(c, friction=mu) for c in scene.contacts)
    integrator = dataclasses.replace(scene.integrator, dt=dt)
    return dataclasses.replace(scene, contacts=contacts, integrator=integrator)


def acceleration_problem(scene: Scene) -> tuple[float, float]:
    r"""The acceleration-level problem of the rod's sliding end at the initial state.

    While the end slides (u_t > 0), Coulomb's force is :math:`\lambda (n - \mu t)`, so the normal
    acceleration of the end is :math:`a_n = k \lambda + a_\text{free}` with
    :math:`k = J_n M^{-1} (J_n - \mu\, \mathrm{sign}(u_t) J_t)^T`. It has a solution
    :math:`\lambda \ge 0, a_n \ge 0, \lambda a_n = 0` unless k < 0 and :math:`a_\text{free} < 0`.

    Returns:
        k in [1/kg] and :math:`a_\text{free}` in [m/s²] (the free normal acceleration,
        centripetal term included).
    """
    robot, constraints = scene.robot, scene.constraints
    model, data = robot.model, pin.Data(robot.model)
    q, v = scene.q0, scene.v0
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    J_n = constraints.jacobian(data, [0])[0]
    J_t = constraints.tangent_rows(data, [0])[0][0]
    Minv = np.linalg.inv(data.M)
    sign = np.sign(J_t @ v)
    k = float(J_n @ Minv @ (J_n - scene.contacts[0].friction * sign * J_t))
    a_free = pin.aba(model, data, q, v, np.zeros(robot.nv))
    drift = constraints.normal_drift(_zero_acceleration_kinematics(scene, data), [0])[0]
    return k, float(J_n @ a_free + drift)


def _zero_acceleration_kinematics(scene: Scene, data: pin.Data) -> pin.Data:
    """``data`` with the kinematics of (q0, v0) at zero joint acceleration."""
    model = scene.robot.model
    pin.forwardKinematics(model, data, scene.q0, scene.v0, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    return data


def painleve_case(mu: float, dt: float) -> dict[str, float]:
    """First step of the rod: its normal impulse [N s] (and / m g h), sliding speed after."""
    scene = painleve(mu, dt)
    log = simulate(scene, duration=10 * dt).log
    mass = pin.computeTotalMass(scene.robot.model)  # [kg]
    return {
        "mu": mu,
        "dt": dt,
        "impulse": float(log.impulse[0, 0]),
        "impulse_over_mgh": float(log.impulse[0, 0] / (mass * GRAVITY * dt)),
        "sliding_speed_after": float(end_speed(log)[1]),
    }


def end_speed(log: Any) -> Vector:
    """Velocity of the rod's end rod_end along x in [m/s] (its sliding speed), shape (N,)."""
    return np.asarray(log.v[:, 0] - 0.5 * np.sin(log.q[:, 2]) * log.v[:, 2])


def beads_case(friction: float, duration: float) -> dict[str, float]:
    """The column of beads: penetration against h × closing speed, energy at impacts."""
    scene = load_scene(builtin_scene("beads.toml"))
    if friction > 0.0:
        scene = dataclasses.replace(
            scene,
            contacts=tuple(dataclasses.replace(c, friction=friction) for c in scene.contacts),
            sphere_contacts=tuple(
                dataclasses.replace(c, friction=friction) for c in scene.sphere_contacts
            ),
        )
    result = simulate(scene, duration=duration)
    summary, log = result.summary, result.log
    closing = float(np.max(-log.normal_velocity))  # [m/s]
    return {
        "friction": friction,
        "max_penetration": summary["max_penetration"],
        "h_times_closing_speed": scene.integrator.dt * closing,
        "n_impacts": summary["n_impacts"],
        "steps_with_several_impacts": int(np.sum(impact_mask(log).sum(axis=1) >= 2)),
        "energy_increase_at_impacts": summary["energy_increase_at_impacts"],
        "n_plastic_steps": summary["n_plastic_steps"],
        "max_lateral_position": float(np.max(np.abs(log.q[:, 0::3]))),
    }


def painleve_figure(path: Path, dt: float = 1e-3, duration: float = 0.3) -> None:
    """Normal impulse and sliding speed of the rod's end, μ = 1.5 against μ = 1.0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.6))
    for mu, colour in ((1.5, "tab:red"), (1.0, "tab:blue")):
        log = simulate(painleve(mu, dt), duration=duration).log
        speed = end_speed(log)
        top.semilogy(log.t, np.maximum(log.impulse[:, 0], 1e-6), color=colour, label=f"μ = {mu}")
        bottom.plot(log.t, speed, color=colour, label=f"μ = {mu}")
    top.axhline(GRAVITY * dt, color="grey", ls=":", label="m g h")
    top.set_ylabel("end's normal impulse [N s]")
    bottom.set_ylabel("end's sliding speed [m/s]")
    bottom.set_xlabel("t [s]")
    top.legend(loc="upper right")
    top.set_title("Painlevé's rod at 1 rad, end sliding forward at 1 m/s")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _table(rows: Sequence[dict[str, Any]]) -> str:
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---:|" * len(keys)]
    for row in rows:
        cells = [
            f"{value:.4g}" if isinstance(value, float) else str(value) for value in row.values()
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> dict[str, list[dict[str, Any]]]:
    """Run every case, print the tables, write them and the Painlevé figure."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0, help="incline runs [s]")
    parser.add_argument(
        "--angles", type=float, nargs="+", default=[10, 20, 26.56505117707799, 30, 45]
    )
    parser.add_argument("--dts", type=float, nargs="+", default=[1e-2, 1e-3, 1e-4], help="[s]")
    parser.add_argument("--problems", type=int, default=200, help="random problems per seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--beads-duration", type=float, default=3.0, help="[s]")
    parser.add_argument("--out", type=Path, default=FIGURES, help="folder of the outputs")
    args = parser.parse_args(argv)
    mu = 0.5
    tables: dict[str, list[dict[str, Any]]] = {
        "incline": [
            incline_case(np.radians(angle), mu, spatial=spatial, duration=args.duration)
            for spatial in (False, True)
            for angle in args.angles
        ],
        "stop": [stop_case(1.0, mu, dt) for dt in args.dts],
        "admm": [admm_case(seed, args.problems) for seed in args.seeds]
        + [
            {
                **admm_case(seed, args.problems, mu_max=1.0, tangential_scale=1.0),
                "seed": f"{seed} (hard)",
            }
            for seed in args.seeds
        ],
        "painleve": [painleve_case(m, dt) for m in (1.5, 1.0) for dt in args.dts],
        "beads": [
            beads_case(0.0, args.beads_duration),
            beads_case(0.3, min(args.beads_duration, 2.0)),
        ],
    }
    k, a_free = acceleration_problem(painleve(1.5))
    text = [f"Friction cases (mu = {mu} for incline and stop)", ""]
    for name, rows in tables.items():
        text += [f"## {name}", "", _table(rows), ""]
    text.append(
        f"Painlevé's rod at t = 0, mu = 1.5: k = {k:.4g} 1/kg, free normal acceleration "
        f"{a_free:.4g} m/s^2 (no lambda >= 0 solves the acceleration-level problem)"
    )
    output = "\n".join(text)
    print(output)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "friction_cases.md").write_text(output + "\n")
    painleve_figure(args.out / "painleve_rod.png")
    return tables


if __name__ == "__main__":
    main()
