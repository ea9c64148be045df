r"""How much the book's q̇_r on the clipped target would change the torque after a first impact.

After the first impact of a cycle (phase TRANSITION, :math:`t_0 \to t_f`) the rigid
Brogliato law builds both :math:`\dot q_r` and :math:`\bar s` on the virtual target
:math:`X_d^*`; the book builds :math:`\dot q_r` (hence :math:`M \ddot q_r + C \dot q_r`) on
the target clipped at the surface (0, at rest) and :math:`\bar s` on :math:`X_d^*`. With
:math:`\bar s` the same, the two torques differ by

.. math::

    \Delta\tau = M \Delta\ddot q_r + C \Delta\dot q_r, \quad
    \Delta\dot q_r = J^{-1} \Delta\dot X_r, \quad
    \Delta\ddot q_r = J^{-1}(\Delta\ddot X_r - \dot J J^{-1} \Delta\dot X_r),

with :math:`\Delta\dot X_r = \Delta\dot X_d + \gamma_2 \Delta X_d`,
:math:`\Delta\ddot X_r = \Delta\ddot X_d + \gamma_2 \Delta\dot X_d` (Δ: clipped minus
virtual; square task). This script evaluates Δτ along the closed loop of the shipped two-link
tracking scenes, at every step of the transition phases, beside the torque applied there, and
then runs both laws (``reference_after_impact = "virtual" | "clipped"``) in closed loop and
compares their transitions: the rise of V over :math:`I_k` and its jumps at the impact steps
(summed over the cycles, :func:`ucontrol.analysis.weak_stability.weak_stability`), the impact
steps, :math:`t_f - t_0` and V at the last :math:`\tau_0`.

Usage::

    python experiments/transition_reference.py --duration 31
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ucontrol.analysis.cycles import cycle_events
from ucontrol.analysis.weak_stability import weak_stability
from ucontrol.control.phase import Phase
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

#: The shipped rigid tracking scenes with a square task.
SCENES = ("two_link_one_constraint", "two_link_two_constraints")


@dataclass
class _Probe:
    """The scene's controller; at each call in a transition, Δτ and τ."""

    law: object
    delta: list[float]
    torque: list[float]

    def __call__(self, t, q, v, contacts):  # type: ignore[no-untyped-def]
        tau = self.law(t, q, v, contacts)  # type: ignore[operator]
        law = self.law
        if law.machine.phase is Phase.TRANSITION:  # type: ignore[attr-defined]
            self.delta.append(float(np.max(np.abs(_delta_torque(law, q, v)))))
            self.torque.append(float(np.max(np.abs(tau))))
        return tau

    def prepare_log(self, log) -> None:  # type: ignore[no-untyped-def]
        self.law.prepare_log(log)  # type: ignore[attr-defined]

    def record(self, log) -> None:  # type: ignore[no-untyped-def]
        self.law.record(log)  # type: ignore[attr-defined]


def _delta_torque(law, q: np.ndarray, v: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Δτ [N m] of the law's last call: its torque with q̇_r on the clipped target, minus it."""
    target, reference = law.desired.target, law.desired.reference
    clipped = reference[0] != target[0]
    if not clipped.any():
        return np.zeros(v.size)
    dX = reference[0] - target[0]  # [m]
    d_dX = reference[1] - target[1]  # [m/s]
    dd_dX = np.where(clipped, -target[2], 0.0)  # [m/s²]: 0 on the clipped rows
    gamma2 = law.gains.gamma2
    d_dX_r, dd_dX_r = d_dX + gamma2 * dX, dd_dX + gamma2 * d_dX
    model, data = law.robot.model, pin.Data(law.robot.model)
    C = pin.computeCoriolisMatrix(model, data, q, v)
    pin.crba(model, data, q)
    M = np.triu(data.M) + np.triu(data.M, 1).T
    pin.computeJointJacobiansTimeVariation(model, data, q, v)
    pin.updateFramePlacements(model, data)
    state = law.task.evaluate(model, data, v)
    d_dq_r = np.linalg.solve(state.J, d_dX_r)  # [rad/s]
    dd_dq_r = np.linalg.solve(state.J, dd_dX_r - state.dJ @ d_dq_r)  # [rad/s²]
    return np.asarray(M @ dd_dq_r + C @ d_dq_r)


def measure(name: str, duration: float) -> tuple[float, float, float, float, int]:
    """Over the transition steps of ``name``: the largest and the median |Δτ| and |τ|.

    Returns:
        Largest |Δτ|, largest |τ|, median |Δτ|, median |τ| (each the largest joint's, in
        [N m]) and the number of steps.
    """
    scene = load_scene(name)
    probe = _Probe(scene.build_controller(), [], [])
    simulate(scene, probe, duration=duration, progress=False)  # type: ignore[arg-type]
    delta, torque = np.array(probe.delta or [0.0]), np.array(probe.torque or [0.0])
    return (
        float(delta.max()),
        float(torque.max()),
        float(np.median(delta)),
        float(np.median(torque)),
        len(probe.delta),
    )


def _variant(name: str, reference: str) -> Scene:
    """Scene ``name`` with ``reference_after_impact = reference``."""
    import tomllib

    source = load_scene(name).source
    assert source is not None
    table = tomllib.loads(source.read_text())
    table.pop("reference", None)
    table["controller"]["reference_after_impact"] = reference
    return Scene.from_dict(table, base_dir=source.parent)


def closed_loop(name: str, reference: str, duration: float) -> dict[str, float]:
    """The transitions of ``name`` run with ``reference_after_impact = reference``.

    Returns:
        ``transition_rise`` and ``impact_jumps`` [J] summed over the cycles, the number of
        ``impact_steps`` (a declared contact's positive impulse in a transition), the mean
        ``t_f - t_0`` [s] over the contacts' cycles and ``V_last_tau0`` [J].
    """
    log = simulate(_variant(name, reference), duration=duration, progress=False).log
    report = weak_stability(log)
    phase = np.asarray(log.contact_phase)
    declared = [log.constraint_names.index(c) for c in log.metadata["controller_contacts"]]
    impulse = np.asarray(log.impulse)[:, declared]
    transiting = phase == int(Phase.TRANSITION)
    settle = [
        t_f - t_0
        for cycle in cycle_events(log)
        for t_0, t_f in zip(cycle.first_impact, cycle.accumulation_end, strict=True)
        if np.isfinite(t_f - t_0)
    ]
    return {
        "transition_rise": sum(c.transition_rise for c in report.cycles),
        "impact_jumps": sum(c.impact_jumps for c in report.cycles),
        "impact_steps": float(np.count_nonzero(transiting & (impulse > 0.0))),
        "settle": float(np.mean(settle)) if settle else float("nan"),
        "V_last_tau0": report.cycles[-1].V_tau0 if report.cycles else float("nan"),
    }


def main(argv: Sequence[str] | None = None) -> list[tuple[str, float, float, float, float, int]]:
    """Print the table of Δτ beside τ over the transitions of each scene."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--duration", type=float, default=11.0, help="simulated time [s]")
    args = parser.parse_args(argv)
    rows = [(name, *measure(name, args.duration)) for name in SCENES]
    print("| scene | transition steps | largest Δτ | largest τ | median Δτ | median τ |")
    print("|:---|---:|---:|---:|---:|---:|")
    for name, delta, torque, median_delta, median_torque, steps in rows:
        cells = f"{delta:.3g} | {torque:.3g} | {median_delta:.3g} | {median_torque:.3g}"
        print(f"| {name} | {steps} | {cells} |")
    print()
    print(
        "| scene | q̇_r on | V rise over I_k | V jumps at impacts | impact steps | t_f - t_0 |",
        end="",
    )
    print(" V(last τ0) |")
    print("|:---|:---|---:|---:|---:|---:|---:|")
    for name in SCENES:
        for reference in ("virtual", "clipped"):
            m = closed_loop(name, reference, args.duration)
            cells = f"{m['transition_rise']:.4g} | {m['impact_jumps']:.4g} | "
            cells += f"{m['impact_steps']:.0f} | {m['settle']:.4g} | {m['V_last_tau0']:.4g}"
            print(f"| {name} | {reference} | {cells} |")
    return rows


if __name__ == "__main__":
    main()
