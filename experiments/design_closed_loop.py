"""Closed loop: the designed cycle vs the hand-made one, both tracked by the Brogliato law.

The task's scene (``--task``: ``two_link``, robots/two_link_one_constraint_task.toml, or
``panda``, robots/panda_table_task.toml, or a task file) runs in Moreau–Jean for ``--cycles``
periods (plus 1 s, to see the last takeoff) with the scene's Brogliato controller, once with
its hand-made circle and once with the cycle designed from the task (same gains, same
transition settings). Prints the design's IPOPT status, the peak joint torque, the first
impact's impulse, impacts and V(tau0) per cycle, and the ratios designed / hand-made.
``--cycle-file`` reuses a cycle written by ``ucontrol design`` (or by ``--save``) instead of
solving the task again.

    python experiments/design_closed_loop.py [--task panda] [--cycles 5] [--dt 1e-3]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from ucontrol.analysis.cycles import cycle_events
from ucontrol.analysis.weak_stability import weak_stability
from ucontrol.control.brogliato_controller import BrogliatoController
from ucontrol.control.controller_table import CYCLE_KEYS
from ucontrol.design import DesignedCycle, DesignTask, design_cycle
from ucontrol.design.design_figures import save_design_figures
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
TASKS = {
    "two_link": ROOT / "robots/two_link_one_constraint_task.toml",
    "panda": ROOT / "robots/panda_table_task.toml",
}


def _figures(log, contact: int, period: float, cycles: int) -> dict[str, float]:  # type: ignore[no-untyped-def]
    u = np.asarray(log.u)
    impulse = np.asarray(log.impulse)[:, contact]
    t = np.asarray(log.t)
    hits = np.flatnonzero(impulse > 0.0)
    first = float(impulse[hits[0]]) if hits.size else 0.0
    per_cycle_peaks = [
        float(np.max(np.abs(u[(t >= k * period) & (t < (k + 1) * period)]), initial=0.0))
        for k in range(cycles)
    ]
    return {
        "peak_torque": float(np.max(np.abs(u))),
        "first_impact_impulse": first,
        "first_impact_time": float(t[hits[0]]) if hits.size else float("nan"),
        "peak_torque_per_cycle": per_cycle_peaks,
    }


def main(argv: list[str] | None = None) -> dict[str, dict]:  # type: ignore[type-arg]
    """Run both cycles; returns their figures and the ratios designed / hand-made."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="two_link", help="two_link, panda or a task file")
    parser.add_argument("--cycle-file", type=Path, default=None, help="a designed cycle (.npz)")
    parser.add_argument("--save", type=Path, default=None, help="write the designed cycle here")
    parser.add_argument(
        "--figures", type=Path, default=None, help="draw the designed cycle into this folder"
    )
    parser.add_argument("--cycles", type=int, default=5)
    parser.add_argument("--dt", type=float, default=1e-3, help="time step in [s]")
    parser.add_argument(
        "--V-floor", type=float, default=1e-9, help="V(tau0) level in [J] taken as converged"
    )
    args = parser.parse_args(argv)
    task = DesignTask.from_toml(TASKS.get(args.task, Path(args.task)))
    # the closed loop runs on the whole scene (the task's model may lock joints)
    assert task.scene.source is not None
    scene = Scene.from_toml(task.scene.source)
    results: dict[str, dict] = {}  # type: ignore[type-arg]
    if args.cycle_file is not None:
        designed = DesignedCycle.load(args.cycle_file)
    else:
        designed, report = design_cycle(
            task,
            progress=lambda k, cost, inf_pr, inf_du: print(
                f"ipopt iteration {k:4d}: objective {cost:.6g}, inf_pr {inf_pr:.2e}, "
                f"inf_du {inf_du:.2e}",
                flush=True,
            ),
        )
        results["design"] = {
            "status": report.status,
            "iterations": report.iterations,
            "inf_pr": report.inf_pr,
            "inf_du": report.inf_du,
            "stationarity": report.stationarity,
            "durations": report.durations,
        }
        print("design:", results["design"])
        if args.save is not None:
            designed.save(args.save)
    print(f"designed cycle: landing at {designed.landing_time:.4g} s, period {designed.period}")
    if args.figures is not None:
        save_design_figures(designed, task.torque_limit, task.scene.robot.joint_names, args.figures)
    hand_made = scene.build_controller()
    assert isinstance(hand_made, BrogliatoController)
    settings = {k: scene.controller[k] for k in CYCLE_KEYS if k in scene.controller}
    cycle = designed.desired_cycle(**settings)
    controller = BrogliatoController(
        scene.robot,
        hand_made.task,
        cycle,
        hand_made.gains,
        posture=scene.controller.get("posture", scene.q0),
    )
    contact = scene.constraints.names.index(designed.contact)
    for name, law, period in (
        ("hand-made", hand_made, hand_made.cycle.period),
        ("designed", controller, cycle.period),
    ):
        run = simulate(
            dataclasses.replace(scene, duration=args.cycles * period + 1.0),
            law,
            dt=args.dt,
            progress=False,
        )
        results[name] = _figures(run.log, contact, period, args.cycles)
        results[name]["n_impacts"] = run.summary.get("n_impacts")
        events = cycle_events(run.log)
        results[name]["complete_cycles"] = sum(bool(cycle.complete) for cycle in events)
        stability = weak_stability(run.log)
        results[name]["V_tau0"] = stability.V_tau0
        results[name]["V_tau0_decreasing"] = stability.V_tau0_decreasing(floor=args.V_floor)
        print(name, results[name])
    for key in ("peak_torque", "first_impact_impulse"):
        ratio = results["designed"][key] / results["hand-made"][key]
        print(f"{key}: designed / hand-made = {ratio:.3f}")
        results.setdefault("ratios", {})[key] = ratio
    return results


if __name__ == "__main__":
    main()
