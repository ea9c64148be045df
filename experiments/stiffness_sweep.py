r"""Flexible joints against their rigid limit: end-effector distance for K from 1e2 to 1e8.

At a fixed step h the two-link arm (robots/two_link.urdf, both joints flexible with motor
inertia B = 0.1 kg m²) runs with joint stiffness K = 1e2 … 1e8 N m/rad beside its rigid limit,
the rigid arm whose joints carry the motors' inertia (``FlexibleJoints.rigid_limit``):

- open loop, free swing: released from q0 = (0.9, -1.6) rad without contact, 3 s;
- open loop, with impacts: the same release onto the ground (e = 0.7) and the wall, 1 s
  (robots/two_link_drop.toml);
- closed loop: the flexible one-constraint cycle (robots/two_link_flexible_one_constraint.toml,
  passivity-based law with the same K, one cycle) against the same law on the rigid limit,
  which measures its motors at their links (:func:`on_rigid_plant`).

For each K it reports the largest distance between the two end-effector paths, in [m], writes
``stiffness_sweep.md`` and ``stiffness_sweep.png`` into ``--figures`` and shows a progress bar.

Run: ``python experiments/stiffness_sweep.py`` (about a minute).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ucontrol.control import ContactState, Controller, Phase
from ucontrol.log import Log
from ucontrol.model import FlexibleJoints
from ucontrol.scene import IntegratorSettings, Scene, load_scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
STIFFNESSES = (1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8)  # [N m/rad]
MOTOR_INERTIA = 0.1  # [kg m²]
TIP = "end_effector"  # the frame whose paths are compared


def flexible(scene: Scene, stiffness: float) -> Scene:
    """``scene`` with both joints flexible at ``stiffness``, motors starting at the links."""
    joints = FlexibleJoints.from_robot(
        scene.robot, ["shoulder", "elbow"], stiffness=stiffness, motor_inertia=MOTOR_INERTIA
    )
    return dataclasses.replace(scene, flexible=joints, motor_q0=None, motor_v0=None)


def rigid_limit(scene: Scene) -> Scene:
    """The rigid arm carrying the motors' inertia, in the settings of ``scene``."""
    joints = FlexibleJoints.from_robot(
        scene.robot, ["shoulder", "elbow"], stiffness=1.0, motor_inertia=MOTOR_INERTIA
    )
    return dataclasses.replace(scene, robot=joints.rigid_limit(scene.robot))


def open_loop_distances(scene: Scene, duration: float, dt: float, theta: float) -> list[float]:
    """Largest end-effector distance [m] to the rigid limit, per stiffness, zero torque."""
    settings = IntegratorSettings(dt=dt, theta=theta)
    scene = dataclasses.replace(scene, integrator=settings)
    rigid_q = simulate(rigid_limit(scene), duration=duration).log.q
    reference = scene.robot.frame_path(rigid_q, TIP)
    distances = []
    for stiffness in STIFFNESSES:
        log = simulate(flexible(scene, stiffness), duration=duration).log
        path = scene.robot.frame_path(log.q, TIP)
        distances.append(float(np.max(np.linalg.norm(path - reference, axis=1))))
    return distances


def on_rigid_plant(controller: Controller, flexible_joints: FlexibleJoints) -> Controller:
    """``controller`` of a flexible robot run on its rigid limit: each motor reads its link."""
    links = flexible_joints.q_index
    velocities = flexible_joints.v_index

    def rigid(t: float, q: np.ndarray, v: np.ndarray, contacts: ContactState) -> np.ndarray:
        return controller(
            t, np.concatenate((q, q[links])), np.concatenate((v, v[velocities])), contacts
        )

    return rigid


def closed_loop_runs(stiffness: float, dt: float, duration: float) -> tuple[Log, Log, Scene]:
    """The flexible one-constraint cycle at ``stiffness`` and the same law on its rigid limit.

    Returns:
        The flexible run's log, the rigid-limit run's log, and the flexible scene.
    """
    case = load_scene(ROOT / "robots" / "two_link_flexible_one_constraint.toml")
    joints = case.flexible
    assert joints is not None
    stiff = dataclasses.replace(joints, stiffness=np.full(joints.nf, stiffness))
    scene = dataclasses.replace(case, flexible=stiff, integrator=IntegratorSettings(dt=dt))
    rigid = dataclasses.replace(
        scene, robot=stiff.rigid_limit(scene.robot), flexible=None, motor_q0=None, motor_v0=None
    )
    controller = on_rigid_plant(scene.build_controller(), stiff)
    return (
        simulate(scene, duration=duration).log,
        simulate(rigid, controller, duration).log,
        scene,
    )


def closed_loop_distances(dt: float, cycles: int) -> dict[str, list[float]]:
    """Largest end-effector distance [m] of the flexible cycle to its rigid limit, per K.

    Over the free motion before the first approach, and over the whole run.
    """
    free, whole = "closed loop, free motion", "closed loop, whole cycle"
    distances: dict[str, list[float]] = {free: [], whole: []}
    for stiffness in STIFFNESSES:
        flexible_log, rigid_log, scene = closed_loop_runs(stiffness, dt, cycles * 10.0 + 0.5)
        distance = np.linalg.norm(
            scene.robot.frame_path(flexible_log.q, TIP) - scene.robot.frame_path(rigid_log.q, TIP),
            axis=1,
        )  # [m]
        first_approach = np.argmax(flexible_log.phase != Phase.FREE)
        distances[free].append(float(distance[:first_approach].max()))
        distances[whole].append(float(distance.max()))
    return distances


def main(argv: Sequence[str] | None = None) -> dict[str, list[float]]:
    """Run the sweep; return the distances [m] per case and stiffness."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dt", type=float, default=1e-3, help="time step h in [s]")
    parser.add_argument("--cycles", type=int, default=1, help="cycles of the closed loop")
    parser.add_argument(
        "--figures", type=Path, default=ROOT / "docs" / "figures", help="folder of the outputs"
    )
    args = parser.parse_args(argv)
    drop = load_scene(ROOT / "robots" / "two_link_drop.toml")
    swing = dataclasses.replace(drop, contacts=(), stops=())
    cases: dict[str, Callable[[], list[float]]] = {
        "open loop, free swing, θ = 1/2": lambda: open_loop_distances(swing, 3.0, args.dt, 0.5),
        "open loop, impacts, θ = 1/2": lambda: open_loop_distances(drop, 1.0, args.dt, 0.5),
        "open loop, impacts, θ = 1": lambda: open_loop_distances(drop, 1.0, args.dt, 1.0),
    }
    results = {}
    for name, run in tqdm(cases.items(), desc="stiffness sweep", unit="case"):
        results[name] = run()
    results.update(closed_loop_distances(args.dt, args.cycles))
    table = _table(results, args.dt)
    print(table)
    args.figures.mkdir(parents=True, exist_ok=True)
    (args.figures / "stiffness_sweep.md").write_text(table + "\n")
    print(f"wrote {_figure(results, args.dt, args.figures / 'stiffness_sweep.png')}")
    return results


def _table(results: dict[str, list[float]], dt: float) -> str:
    head = "| K [N m/rad] | " + " | ".join(f"{name} [m]" for name in results) + " |"
    rule = "|---:|" + "---:|" * len(results)
    rows = [
        f"| {stiffness:.0e} | "
        + " | ".join(f"{distances[i]:.2e}" for distances in results.values())
        + " |"
        for i, stiffness in enumerate(STIFFNESSES)
    ]
    caption = (
        f"Largest end-effector distance to the rigid limit, h = {dt:g} s, B = {MOTOR_INERTIA} "
        "kg m² (experiments/stiffness_sweep.py)"
    )
    return "\n".join([caption, "", head, rule, *rows])


def _figure(results: dict[str, list[float]], dt: float, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6.4, 4.4))
    for name, distances in results.items():
        axes.loglog(STIFFNESSES, distances, "o-", label=name)
    slope = np.array(STIFFNESSES) ** -1.0
    axes.loglog(STIFFNESSES, slope * 0.05, "k:", label="∝ 1/K")
    axes.set_xlabel("joint stiffness K [N m/rad]")
    axes.set_ylabel("largest end-effector distance [m]")
    axes.set_title(f"Flexible arm against its rigid limit (h = {dt:g} s)")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


if __name__ == "__main__":
    main()
