"""A walking gait of RABBIT designed by optimal control, fitted, written as a scene and tracked.

Solves the gait task (``robots/rabbit_gait_task.toml``: one step of the planar biped with the
stance foot pinned, the plastic heel strike, the legs relabelled, periodic; casadi Opti and
IPOPT, :mod:`ucontrol.design.gait_transcription`), fits the Bézier virtual constraints with
the impact's endpoint relations, writes ``robots/rabbit_walk_designed.toml`` (the HZD
controller, released at the designed step's start), runs it in closed loop (Moreau–Jean) and
compares each step of the run with the designed one: step length and period. Draws the
designed step, q_a(θ) with its fit, the torques and the closed loop's steps.

Run: ``python experiments/biped_gait_ocp.py`` (about a minute; ``--intervals 12 --steps 4``
for a short check). Prints the solver's figures, the residuals and the closed loop's steps.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from ucontrol.design.gait_figures import save_gait_figure
from ucontrol.design.gait_task import GaitTask
from ucontrol.design.gait_transcription import design_gait
from ucontrol.design.hzd_fit import fit_bezier, write_hzd_scene
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]


def closed_loop_steps(scene_path: Path, duration: float) -> dict[str, list[float]]:
    """Run the scene; the heel strikes' times, step lengths [m] and periods [s], in order.

    A heel strike is a touchdown of the foot that was in the air (the other foot's last
    touchdown before it); the step length is the distance along x between the two feet then.
    """
    scene = load_scene(scene_path)
    log = simulate(scene, duration=duration).log
    feet = ("foot_left", "foot_right")
    names = {foot: next(n for n in log.constraint_names if n.startswith(foot)) for foot in feet}
    strikes = sorted((float(t), foot) for foot in feet for t in log.impact_times_of(names[foot]))
    robot = scene.robot
    times, lengths, last = [], [], "foot_left"
    for t, foot in strikes:
        if foot == last:  # the stance foot's own chatter, not a step
            continue
        q = log.at("q", t)
        lengths.append(float(robot.frame_position(q, foot)[0] - robot.frame_position(q, last)[0]))
        times.append(t)
        last = foot
    periods = np.diff(np.concatenate(([0.0], times))).tolist()
    return {"times": times, "lengths": lengths, "periods": periods}


def main(argv: list[str] | None = None) -> dict[str, object]:
    """Design, fit, write the scene, run it, draw; returns the figures printed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", type=Path, default=ROOT / "robots" / "rabbit_gait_task.toml")
    parser.add_argument("--intervals", type=int, default=None, help="grid (default: task's)")
    parser.add_argument("--scene", type=Path, default=ROOT / "robots" / "rabbit_walk_designed.toml")
    parser.add_argument("--steps", type=int, default=10, help="closed-loop steps to run")
    parser.add_argument(
        "--figure", type=Path, default=ROOT / "docs" / "figures" / "legged" / "biped_gait_ocp.png"
    )
    parser.add_argument("--no-figure", dest="draw", action="store_false")
    args = parser.parse_args(argv)
    task = GaitTask.from_toml(args.task)
    if args.intervals is not None:
        task = dataclasses.replace(task, intervals=args.intervals)
    gait = design_gait(task)
    fit = fit_bezier(gait, task.degree)
    duration = round(args.steps * gait.step_time + 0.5 * gait.step_time, 3)
    write_hzd_scene(args.scene, task, gait, fit, duration=duration)
    steps = closed_loop_steps(args.scene, duration) if args.steps > 0 else {}
    result: dict[str, object] = {
        "design": gait.summary(task.friction),
        "fit": {
            "degree": fit.degree,
            "rms_error_rad": fit.rms_error,
            "max_error_rad": fit.max_error,
            "theta_plus": fit.theta_plus,
            "theta_minus": fit.theta_minus,
        },
        "closed_loop": steps,
    }
    if steps.get("lengths"):
        lengths, periods = np.array(steps["lengths"]), np.array(steps["periods"])
        result["closed_loop_vs_design"] = {
            "steps": len(lengths),
            "max_step_length_error": float(np.max(np.abs(lengths / gait.step_length - 1))),
            "max_period_error": float(np.max(np.abs(periods / gait.step_time - 1))),
            "last_step_length_error": float(lengths[-1] / gait.step_length - 1),
            "last_period_error": float(periods[-1] / gait.step_time - 1),
        }
    print(json.dumps(result, indent=2))
    if args.draw:
        save_gait_figure(gait, fit, args.figure, steps=steps)
    return result


if __name__ == "__main__":
    main()
