r"""RABBIT walking under the HZD law: its gait judged on the stride map, and 100 steps.

``robots/rabbit_walk.toml`` (Moreau–Jean, ``--dt``) and its event-driven closed loop
(:class:`~ucontrol.analysis.stance_flow.StanceFlow` with the law,
:class:`~ucontrol.analysis.biped_section.BipedSection` as the chart):

- ``gait``: :func:`~ucontrol.analysis.gait.find_gait` with ``section="heel_strike"`` from the
  scene's start: the fixed point, the step period, every multiplier, and the zero dynamics'
  multiplier δ² (angular momenta about the new and old stance foot across the strike);
- ``walk``: ``--steps`` steps under Moreau–Jean from the scene's start: the step periods and
  lengths, the speed, the lowest hip, the largest output error and torque, the stance feet's
  slip;
- ``robustness``: runs of ``--robustness-duration`` under a heavier model in the controller
  and under pushes;
- the figure ``biped_walk.png``: the limit cycle θ–θ̇ of every step (Moreau–Jean) over the
  event-driven gait, the step lengths and periods, the torques of the last two steps.

Run: ``python experiments/biped_walk.py`` (about 3 min on a quiet machine; ``--steps 3`` for a
smoke run); writes ``biped_walk.png`` and ``biped_walk.md`` to ``--out`` (default
docs/figures/legged).
"""

from __future__ import annotations

import argparse
import itertools
import tomllib
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from biped_gait_design import FEET, momentum
from matplotlib.figure import Figure
from scipy.integrate import solve_ivp

from ucontrol.analysis.biped_section import BipedSection, find_biped_gait
from ucontrol.analysis.gait import Gait
from ucontrol.campaign.overrides import apply_overrides
from ucontrol.control.hzd_controller import HZDController
from ucontrol.exceptions import PhysicsWarning
from ucontrol.log import Log
from ucontrol.scene import Scene, load_scene
from ucontrol.scene.builtin_scenes import builtin_scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures" / "legged"
#: Moreau–Jean's steps last up to 5 % longer than the event-driven gait's (measured).
SLOWER = 1.06


def gait_cycle(section: BipedSection, gait: Gait, samples: int = 200) -> np.ndarray:
    """θ and θ̇ along the event-driven gait's stance, shape (samples, 2)."""
    flow, law = section.flow, section.law
    nv = flow.robot.nv

    def rate(_: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:nv], y[nv:]
        return np.concatenate((v, flow.acceleration(q, v, 0, flow.law_input(q, v, 0))[0]))

    times = np.linspace(0.0, gait.period, samples)
    solution = solve_ivp(
        rate,
        (0.0, gait.period),
        np.concatenate((gait.q, gait.v)),
        method="DOP853",
        rtol=1e-10,
        atol=1e-10,
        t_eval=times,
    )
    return np.array([law.phase_variable(y[:nv], 0, y[nv:])[:2] for y in solution.y.T])


def walk(scene: Scene, law: HZDController, log: Log) -> dict[str, np.ndarray]:
    """Per-step figures of a logged walk, and θ, θ̇ and u at every sample."""
    t, q, v = np.asarray(log.t), np.asarray(log.q), np.asarray(log.v)
    stance = np.asarray(log.stance).astype(int)
    swaps = np.flatnonzero(np.diff(stance)) + 1  # first sample of each new step
    feet = np.array([[scene.robot.frame_position(qk, f)[0] for f in FEET] for qk in q])
    phase = np.array(
        [law.phase_variable(qk, sk, vk)[:2] for qk, vk, sk in zip(q, v, stance, strict=True)]
    )
    starts = np.concatenate(([0], swaps))
    lengths = np.array([feet[k, stance[k]] - feet[k, 1 - stance[k]] for k in swaps])
    slip = [float(np.ptp(feet[a + 2 : b - 2, stance[a]])) for a, b in itertools.pairwise(starts)]
    return {
        "t": t,
        "q": q,
        "u": np.asarray(log.u),
        "y": np.asarray(log.outputs),
        "stance": stance,
        "swaps": t[swaps],
        "periods": np.diff(t[starts]),
        "lengths": lengths,
        "slip": np.array(slip),
        "phase": phase,
    }


def figure(cycle: np.ndarray, walked: dict[str, np.ndarray], path: Path) -> None:
    """The limit cycle, the steps and the torques (module docstring)."""
    fig = Figure(figsize=(13, 4))
    ax = fig.subplots(1, 3)
    phase, swaps, t = walked["phase"], walked["swaps"], walked["t"]
    ax[0].plot(phase[:, 0], phase[:, 1], lw=0.5, color="tab:blue", label="Moreau–Jean, all steps")
    ax[0].plot(cycle[:, 0], cycle[:, 1], "--", lw=1.5, color="k", label="gait (event-driven)")
    ax[0].set_xlabel("stance leg angle θ [rad]")
    ax[0].set_ylabel("θ̇ [rad/s]")
    ax[0].set_title("limit cycle (strikes: the jumps back to θ⁺)")
    ax[0].legend(loc="upper left", fontsize=8)
    steps = np.arange(1, swaps.size + 1)
    ax[1].plot(steps, walked["lengths"], ".", color="tab:green")
    ax[1].set_xlabel("step")
    ax[1].set_ylabel("step length [m]", color="tab:green")
    twin = ax[1].twinx()
    twin.plot(steps, walked["periods"], ".", color="tab:red")
    twin.set_ylabel("step period [s]", color="tab:red")
    ax[1].set_title(f"{swaps.size} steps")
    last = t >= (swaps[-3] if swaps.size >= 3 else 0.0)
    for k, name in enumerate(("stance hip", "stance knee", "swing hip", "swing knee")):
        ax[2].plot(t[last], _relabelled(walked["u"], walked["stance"])[last, k], label=name)
    for time in swaps[swaps >= t[last][0]]:
        ax[2].axvline(time, color="0.6", lw=0.8, ls=":")
    ax[2].set_xlabel("t [s]")
    ax[2].set_ylabel("torque [N m]")
    ax[2].set_title("torques, last two steps (dotted: strikes)")
    ax[2].legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _relabelled(u: np.ndarray, stance: np.ndarray) -> np.ndarray:
    """Torques in (stance hip, stance knee, swing hip, swing knee) order, shape (n, 4)."""
    swapped = u[:, [2, 3, 0, 1]]
    return np.where(stance[:, None] == 0, u, swapped)


#: Disturbances of the robustness runs: name, scene overrides, pushes ([[pushes]] tables).
DISTURBANCES = (
    ("controller's model 10 % heavier", {"controller.model.mass_scale": 1.1}, []),
    ("pushed forward 0.3 m/s at 1 s", {}, [{"time": 1.0, "velocity": [0.3, *[0.0] * 6]}]),
    ("pushed backward 0.3 m/s at 1 s", {}, [{"time": 1.0, "velocity": [-0.3, *[0.0] * 6]}]),
    ("pitch rate +0.5 rad/s at 1 s", {}, [{"time": 1.0, "velocity": [0, 0, 0.5, 0, 0, 0, 0]}]),
)


def robustness(duration: float, dt: float) -> list[str]:
    """One line per disturbance: steps taken, lowest hip, last step periods, mean speed."""
    path = builtin_scene("rabbit_walk")
    lines = []
    for name, overrides, pushes in DISTURBANCES:
        table = apply_overrides(tomllib.loads(path.read_text()), overrides)
        table["pushes"] = pushes
        scene = Scene.from_dict(table, base_dir=path.parent)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PhysicsWarning)
            log = simulate(scene, duration=duration, dt=dt, progress=False).log
        t, q = np.asarray(log.t), np.asarray(log.q)
        swaps = t[1:][np.diff(np.asarray(log.stance)) != 0]
        periods = np.diff(np.concatenate(([0.0], swaps)))
        fell = np.min(q[:, 1]) < 0.5  # the hip below 0.5 m [m]
        lines.append(
            f"- {name}: {'FELL' if fell else 'walks'}, {swaps.size} steps in {duration:g} s, "
            f"hip never below {np.min(q[:, 1]):.3f} m, last step periods "
            f"{np.array2string(periods[-3:], precision=3)} s, "
            f"speed {(q[-1, 0] - q[0, 0]) / t[-1]:.3f} m/s"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> dict[str, object]:
    """Run the studies; returns the measured figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=FIGURES, help="folder of the outputs")
    parser.add_argument("--steps", type=int, default=100, help="steps under Moreau–Jean")
    parser.add_argument("--dt", type=float, default=1e-3, help="Moreau–Jean step [s]")
    parser.add_argument(
        "--robustness-duration", type=float, default=6.0, help="runs under disturbances [s]"
    )
    args = parser.parse_args(argv)
    scene = load_scene("rabbit_walk")
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    section, gait = find_biped_gait(law, scene.constraints, scene.q0, scene.v0)
    stride = section.flow.stride(gait.q, gait.v)
    delta2 = (
        momentum(scene.robot, stride.q, stride.v, FEET[1])
        / momentum(scene.robot, stride.q, stride.v_minus, FEET[0])
    ) ** 2

    duration = (args.steps + 1) * SLOWER * gait.period
    log = simulate(scene, duration=duration, dt=args.dt, progress=False).log
    walked = walk(scene, law, log)
    args.out.mkdir(parents=True, exist_ok=True)
    figure(gait_cycle(section, gait), walked, args.out / "biped_walk.png")
    q, t = walked["q"], walked["t"]
    late = t > t[-1] - 2.0
    lines = [
        f"Gait (event-driven, section heel_strike): period {gait.period:.6f} s, "
        f"residual {gait.residual:.1e}, {gait.iterations} Newton iterations",
        f"z* = {np.array2string(gait.z, precision=6)}",
        "|multipliers|: " + ", ".join(f"{abs(m):.3g}" for m in gait.multipliers),
        f"zero dynamics' multiplier delta^2 = {delta2:.8f} "
        f"(leading multiplier {abs(gait.multipliers[0]):.8f})",
        f"Moreau–Jean, dt = {args.dt:g} s, {duration:.2f} s: {walked['swaps'].size} steps "
        f"(asked at least {args.steps}), hip never below {np.min(q[:, 1]):.4f} m",
        f"step periods {np.min(walked['periods']):.4f}–{np.max(walked['periods']):.4f} s, "
        f"lengths {np.min(walked['lengths']):.4f}–{np.max(walked['lengths']):.4f} m, "
        f"speed {(q[-1, 0] - q[0, 0]) / t[-1]:.4f} m/s",
        f"largest |y| over the last 2 s {np.max(np.abs(walked['y'][late])):.2e} rad, "
        f"largest |u| {np.max(np.abs(walked['u'])):.1f} N m, "
        f"largest stance-foot slip per step {1e3 * np.max(walked['slip']):.3f} mm",
        "Disturbed (Moreau–Jean, from the scene's start):",
        *robustness(args.robustness_duration, args.dt),
    ]
    text = "\n".join(lines)
    print(text)
    (args.out / "biped_walk.md").write_text(text + "\n")
    return {"gait": gait, "delta2": delta2, "walked": walked}


if __name__ == "__main__":
    main()
