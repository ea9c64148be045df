r"""Solo-12 landing from 0.3 m and pronking ten times: the measured figures of docs/legged.md.

``robots/solo_landing.toml`` and ``robots/solo_pronk.toml`` (four point feet, Coulomb
friction μ = 0.7, e = 0) under :class:`~ucontrol.control.pronking_controller.PronkingController`,
Moreau–Jean at ``--dt``. Measured from the logs alone (the plant's normal impulses say when a
foot is in contact, the feet's positions come from the logged configurations):

- hops: flights where no foot carries any impulse, their apexes (centre of mass above the
  feet's level) against the command;
- slip: each foot's largest tangential displacement from where a stance began, over the stance;
- no fall: the lowest base height and the largest base tilt;
- the real-time factor of each run (simulated time over wall time, and over the process's CPU
  time: the machine may be shared) and the controller's share of the CPU time;
- a figure of the centre of mass height and the feet's normal forces over the ten hops;
- the CPU time per step [µs] of the controller and of the rest of the step (the plant's
  evaluation and step, the log), each the least over ``--repeat`` runs, on both scenes and on
  a standing Solo with friction (``quadruped_stand.toml`` with μ = 0.7 on its four feet, under
  its joint PD). ``UCONTROL_NO_COMPILE=1`` runs the pronking controller's numpy reference
  instead of its compiled law (and nothing else changes for these scenes: their plant has no
  compiled path).

Run: ``python experiments/solo_pronk.py`` (about 20 s; ``--repeat 5`` about a minute); writes
``docs/figures/legged/solo_pronk.md`` and ``solo_pronk.png`` (``--out``).

``--replay MODE`` only replays the controller on the states of the first 2 s of solo_pronk
(each state's plant evaluation first, as the closed loop does), for instruction counts that a
loaded machine does not change: ``valgrind --tool=callgrind python experiments/solo_pronk.py
--replay MODE`` for MODE ``none`` (no controller), ``reference``, ``compiled-own`` (its own
Pinocchio passes) and ``compiled`` (on the plant's evaluation); each mode's count less that of
``none``, over the 2000 calls, is the controller's per call.
"""

from __future__ import annotations

import argparse
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from matplotlib.figure import Figure

from ucontrol.control.controller import ContactState, Controller
from ucontrol.control.pronking_controller import PronkingController
from ucontrol.log import Log
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures" / "legged"
SCENES = ("solo_landing", "solo_pronk")
#: The standing Solo of the speed table: quadruped_stand.toml with this friction on its feet.
STAND_FRICTION = 0.7
STAND = "quadruped_stand (mu = 0.7)"


@dataclass(frozen=True)
class Stance:
    """One foot's contact: rows [start, stop) of the log and its largest slip [m]."""

    foot: str
    start: int
    stop: int
    slip: float


#: A foot is in contact at a row when it carried a normal impulse in the step ending there or
#: its gap is at most this [m] (a foot may carry none for a step of a stance).
CONTACT_GAP = 1e-4


def in_contact(log: Log) -> np.ndarray:
    """Whether each foot is in contact at each row, shape (n, n_feet)."""
    return (log.impulse > 0.0) | (log.gap <= CONTACT_GAP)


def _runs(rows: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs [start, stop) of consecutive row indices."""
    if rows.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(rows) > 1)
    starts = np.concatenate([[rows[0]], rows[breaks + 1]])
    stops = np.concatenate([rows[breaks], [rows[-1]]]) + 1
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def feet_positions(scene: Scene, log: Log) -> np.ndarray:
    """World positions of the contacts' frames at each row, shape (n, n_feet, 3) [m]."""
    model = scene.robot.model
    data = pin.Data(model)
    frames = [model.getFrameId(pair.frame) for pair in scene.contacts]
    positions = np.empty((len(log), len(frames), 3))
    for k, q in enumerate(log.q):
        pin.framesForwardKinematics(model, data, q)
        positions[k] = [data.oMf[f].translation for f in frames]
    return positions


def stances(scene: Scene, log: Log) -> list[Stance]:
    """Every stance of every foot with its slip.

    The slip is the largest distance, in the ground's plane, of the foot from where it was at
    the stance's first row.
    """
    positions = feet_positions(scene, log)
    contact = in_contact(log)
    result = []
    for j, pair in enumerate(scene.contacts):
        normal = np.asarray(pair.surface.normal, dtype=float)
        for start, stop in _runs(np.flatnonzero(contact[:, j])):
            moved = positions[start:stop, j] - positions[start, j]  # [m]
            tangential = moved - np.outer(moved @ normal, normal)
            slip = float(np.max(np.linalg.norm(tangential, axis=1)))
            result.append(Stance(pair.frame, start, stop, slip))
    return result


def flights(log: Log) -> list[tuple[int, int]]:
    """Rows [start, stop) where no foot carries an impulse, after a stance and before one."""
    airborne = np.flatnonzero(~in_contact(log).any(axis=1))
    return [(a, b) for a, b in _runs(airborne) if a > 0 and b < len(log)]


def apexes(log: Log) -> np.ndarray:
    """The centre of mass's largest height in each flight, [m]."""
    height = log.com_height
    return np.array([height[a:b].max() for a, b in flights(log)])


def tilt(log: Log) -> np.ndarray:
    """The base's tilt from the vertical at each row, [rad]."""
    up = np.array([0.0, 0.0, 1.0])
    z_axis = np.array([pin.Quaternion(q[3:7]).matrix()[:, 2] for q in log.q])
    return np.arccos(np.clip(z_axis @ up, -1.0, 1.0))


class _TimedController:
    """The scene's controller, with the CPU time [s] its calls take.

    It passes the closed loop's offer of the plant's evaluation on to the controller
    (``use_plant_data``), so that the controller runs as in a user's run.
    """

    def __init__(self, controller: Controller) -> None:
        self.controller: Any = controller
        self.robot = getattr(controller, "robot", None)
        self.cpu_time = 0.0

    def use_plant_data(self, data: pin.Data | None) -> bool:
        use = getattr(self.controller, "use_plant_data", None)
        return False if use is None else bool(use(data))

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray, contacts: ContactState):
        start = time.process_time()
        torque = self.controller(t, q, v, contacts)
        self.cpu_time += time.process_time() - start
        return torque


class _TimedLoggingController(_TimedController):
    """A timed controller that writes fields of its own to the log."""

    def prepare_log(self, log: Log) -> None:
        self.controller.prepare_log(log)

    def record(self, log: Log) -> None:
        self.controller.record(log)


def load(name: str) -> Scene:
    """A scene of ``robots/``, or :data:`STAND`: quadruped_stand with friction on its feet."""
    if name != STAND:
        return Scene.from_toml(ROOT / "robots" / f"{name}.toml")
    table = tomllib.loads((ROOT / "robots" / "quadruped_stand.toml").read_text())
    for contact in table["contacts"]:
        contact["friction"] = STAND_FRICTION
    return Scene.from_dict(table, base_dir=ROOT / "robots", default_name="quadruped_stand")


def run(name: str, dt: float, duration: float | None = None) -> tuple[Scene, Log, dict]:
    """The scene's run and its summary, with ``cpu_time_s`` and ``controller_cpu_time_s``."""
    scene = load(name)
    built = scene.build_controller()
    timed = _TimedLoggingController if hasattr(built, "prepare_log") else _TimedController
    controller = timed(built)
    scene.build_integrator(dt)  # its first build imports the friction solver: not timed
    start = time.process_time()
    result = simulate(scene, controller, duration=duration, dt=dt, progress=False)
    summary = dict(result.summary)
    summary["cpu_time_s"] = time.process_time() - start
    summary["controller_cpu_time_s"] = controller.cpu_time
    compiled = getattr(built, "compiled", None)
    law = {True: "compiled", False: "numpy reference"}
    summary["controller_law"] = type(built).__name__ if compiled is None else law[compiled]
    return scene, result.log, summary


def speed(name: str, dt: float, duration: float | None, repeat: int) -> dict[str, float | str]:
    """CPU time per step [µs], each the least over ``repeat`` runs of scene ``name``.

    Keys: ``step`` (the closed loop's step), ``controller``, ``rest`` (the step less the
    controller: the plant's evaluation and step, contact solves included, and the log),
    ``factor`` (simulated time over the least CPU time) and ``law``. (The solver times its
    solves on the wall clock, ``summary.json``'s ``contact_solve_time_s``: on a loaded machine
    that is not comparable with these CPU times.)
    """
    best: dict[str, float | str] = {}
    for _ in range(repeat):
        _, log, summary = run(name, dt, duration)
        steps = len(log) - 1
        step = 1e6 * summary["cpu_time_s"] / steps  # [µs]
        controller = 1e6 * summary["controller_cpu_time_s"] / steps  # [µs]
        figures = {"step": step, "controller": controller, "rest": step - controller}
        for key, value in figures.items():
            best[key] = min(float(best.get(key, np.inf)), value)
        best["factor"] = float(log.t[-1]) / (1e-6 * float(best["step"]) * steps)
        best["law"] = summary["controller_law"]
    return best


def figure(log: Log, apex: float, stand: float) -> Figure:
    """Centre of mass height and the feet's normal forces (measured and commanded)."""
    fig = Figure(figsize=(9.0, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(log.t, log.com_height, label="centre of mass")
    top.axhline(apex, color="k", ls="--", lw=0.8, label="commanded apex")
    top.axhline(stand, color="k", ls=":", lw=0.8, label="standing height")
    top.set_ylim(0.14, 0.32)
    top.set_ylabel("height above the feet [m]")
    top.legend(loc="lower center", ncols=3)
    dt = float(log.metadata["dt"])
    for j, name in enumerate(log.metadata["feet"]):
        bottom.plot(log.t, log.impulse[:, j] / dt, lw=0.8, label=f"{name} (plant)")
    commanded = log.foot_force_command[:, :, 2].sum(axis=1) / len(log.metadata["feet"])
    bottom.plot(log.t, commanded, "k--", lw=0.8, label="commanded, mean of the feet")
    bottom.set_ylim(0.0, 30.0)  # the touchdown impulses / dt (about 100 N) are cut
    bottom.set_ylabel("normal force [N]")
    bottom.set_xlabel("t [s]")
    bottom.legend(loc="upper center", ncols=3, fontsize="small")
    return fig


#: What ``--replay`` runs: the controller of each mode (None: the plant evaluations alone).
REPLAY_MODES = ("none", "reference", "compiled-own", "compiled")


def replay(mode: str, duration: float = 2.0) -> int:
    """Replay the pronking controller of ``mode`` on the states of solo_pronk's first seconds.

    Every mode records the same states and builds every controller, so that the instruction
    counts of two modes differ by the calls of the controller alone. Returns the calls made.
    """
    scene = load("solo_pronk")
    states: list[tuple[float, np.ndarray, np.ndarray, ContactState]] = []
    built = scene.build_controller()
    assert isinstance(built, PronkingController)

    def recording(t: float, q: np.ndarray, v: np.ndarray, contacts: ContactState):
        states.append((t, q.copy(), v.copy(), contacts._replace(gap=contacts.gap.copy())))
        return built(t, q, v, contacts)

    simulate(scene, recording, duration=duration, progress=False)
    model = scene.robot.model
    data = pin.Data(model)  # the plant's evaluation of each state
    frames = [pair.frame for pair in scene.contacts]
    controllers = {
        name: PronkingController(
            built.robot,
            feet=built.feet,
            contacts=[frames.index(foot) for foot in built.feet],
            normals=np.array(
                [scene.contacts[frames.index(foot)].surface.normal for foot in built.feet]
            ),
            posture=built.posture,
            settings=built.settings,
            compiled=name != "reference",
        )
        for name in REPLAY_MODES[1:]
    }
    controllers["compiled"].use_plant_data(data)
    controller = controllers.get(mode)
    for t, q, v, contacts in states:
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        if controller is not None:
            controller(t, q, v, contacts)
    return 0 if controller is None else len(states)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dt", type=float, default=1e-3, help="time step [s]")
    parser.add_argument(
        "--duration", type=float, default=None, help="simulated time [s] (default the scenes')"
    )
    parser.add_argument("--out", type=Path, default=FIGURES, help="output folder")
    parser.add_argument(
        "--repeat", type=int, default=1, help="runs of each scene for the CPU times per step"
    )
    parser.add_argument(
        "--replay", choices=REPLAY_MODES, help="only replay a controller (for callgrind)"
    )
    args = parser.parse_args(argv)
    if args.replay is not None:
        print(f"{args.replay}: {replay(args.replay)} controller calls")
        return
    args.out.mkdir(parents=True, exist_ok=True)
    lines = [
        "| scene | hops | apex [m] | worst slip [mm] | lowest base [m] | "
        "largest tilt [deg] | real-time factor (wall) | (CPU) | controller's CPU share |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in SCENES:
        scene, log, summary = run(name, args.dt, args.duration)
        duration = float(log.t[-1])  # [s]
        factor, cpu = duration / summary["wall_time_s"], duration / summary["cpu_time_s"]
        share = summary["controller_cpu_time_s"] / summary["cpu_time_s"]
        slips = [stance.slip for stance in stances(scene, log)]
        heights = apexes(log)
        apex_text = f"{heights.min():.4f} to {heights.max():.4f}" if heights.size else "-"
        lines.append(
            f"| {name} | {heights.size} | {apex_text} | {1e3 * max(slips):.3f} | "
            f"{log.q[:, 2].min():.3f} | {np.degrees(tilt(log).max()):.3f} | {factor:.2f} | "
            f"{cpu:.2f} | {100 * share:.0f} % |"
        )
        if name == "solo_pronk":
            table = scene.controller
            figure(log, table["apex"], table["stand_height"]).savefig(
                args.out / "solo_pronk.png", dpi=120
            )
    lines += [
        "",
        f"CPU time per step [µs], the least of {args.repeat} run(s) at dt = {args.dt:g} s:",
        "",
        "| scene | controller | step | controller's part | rest of the step | "
        "real-time factor (CPU) |",
        "|---|---|---|---|---|---|",
    ]
    for name in (*SCENES, STAND):
        best = speed(name, args.dt, args.duration, max(args.repeat, 1))
        lines.append(
            f"| {name} | {best['law']} | {best['step']:.1f} | {best['controller']:.1f} | "
            f"{best['rest']:.1f} | {best['factor']:.2f} |"
        )
    text = "\n".join(lines) + "\n"
    (args.out / "solo_pronk.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
