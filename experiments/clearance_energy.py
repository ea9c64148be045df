r"""Energy balance of the clearance slider-crank under event_driven: friction and impact losses.

Runs ``robots/slider_crank_clearance.toml`` (journal in its bearing: e = ``--restitution``,
μ = ``--friction``; the slider on the floor, μ = ``--floor-friction``) with the event-driven
integrator for ``--duration`` [s], and compares the mechanism's energy change
:math:`E(t) - E(0)` with the integrator's ledger
(:class:`~ucontrol.integrators.event_driven.EnergyLedger`): actuator work (zero: every joint
is passive) plus friction work of the sliding phases minus the kinetic energy lost at the
impacts. With ``--elastic`` the bearing is frictionless and elastic (μ = 0, e = 1), the floor
and gravity are removed, and the energy must stay constant.

Prints one line of figures (docs/clearance.md). Run:
``python experiments/clearance_energy.py`` (about 35 s for the scene's 1 s).
"""

from __future__ import annotations

import argparse
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol.integrators.event_driven import EnergyLedger
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
SCENE = ROBOTS / "slider_crank_clearance.toml"


@dataclass(frozen=True)
class Balance:
    """A run's energy change and its account.

    Attributes:
        change: :math:`E(t) - E(0)` in [J] (kinetic plus gravitational).
        initial: :math:`E(0)` in [J].
        ledger: The integrator's work and losses over the run.
        impacts: Impacts located.
    """

    change: float
    initial: float
    ledger: EnergyLedger
    impacts: int

    @property
    def residual(self) -> float:
        """:math:`E(t) - E(0)` minus the ledger's balance, in [J]."""
        return self.change - self.ledger.balance

    @property
    def dissipated(self) -> float:
        """Energy taken out by friction and impacts, in [J] (>= 0)."""
        return self.ledger.impact_loss - self.ledger.friction_work


def scene_table(
    restitution: float = 0.5,
    friction: float = 0.1,
    floor_friction: float = 0.3,
    elastic: bool = False,
    dt: float = 1e-3,
) -> dict[str, Any]:
    """The shipped scene's table under event_driven with the bearing's e and μ (``dt`` [s])."""
    table = tomllib.loads(SCENE.read_text())
    table["integrator"] = {"name": "event_driven", "dt": dt}
    table["clearance"][0].update(restitution=restitution, friction=friction)
    table["contacts"][0]["friction"] = floor_friction
    if elastic:
        table["clearance"][0].update(restitution=1.0, friction=0.0)
        del table["contacts"], table["surfaces"]
        table["robot"]["gravity"] = [0.0, 0.0, 0.0]
    return table


def energy_balance(table: dict[str, Any], duration: float) -> Balance:
    """Run the scene of ``table`` for ``duration`` [s] and balance its energy."""
    scene = Scene.from_dict(table, base_dir=ROBOTS)
    integrator = scene.build_integrator()  # an EventDriven (the table names it)
    q, v, t = scene.q0, scene.v0, 0.0
    start = integrator.evaluate(q, v, t)
    impacts = 0
    for _ in range(round(duration / integrator.dt)):
        outcome = integrator.step(integrator.evaluate(q, v, t), np.zeros(scene.robot.nv))
        q, v, t = outcome.q, outcome.v, t + integrator.dt
        impacts += len(outcome.impacts)
    end = integrator.evaluate(q, v, t)
    initial = start.kinetic_energy + start.potential_energy
    change = end.kinetic_energy + end.potential_energy - initial
    return Balance(change, initial, integrator.ledger, impacts)  # type: ignore[attr-defined]


def main(argv: Sequence[str] | None = None) -> Balance:
    """Run, print the figures and return them."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0, help="run length [s]")
    parser.add_argument("--dt", type=float, default=1e-3, help="sampling period [s]")
    parser.add_argument("--restitution", type=float, default=0.5, help="bearing's e")
    parser.add_argument("--friction", type=float, default=0.1, help="bearing's μ")
    parser.add_argument("--floor-friction", type=float, default=0.3, help="slider's μ")
    parser.add_argument("--elastic", action="store_true", help="μ = 0, e = 1, no floor or g")
    args = parser.parse_args(argv)
    table = scene_table(args.restitution, args.friction, args.floor_friction, args.elastic, args.dt)
    balance = energy_balance(table, args.duration)
    ledger = balance.ledger
    reference = balance.initial if args.elastic else balance.dissipated
    print(
        f"{args.duration:g} s, {balance.impacts} impacts: E(t) - E(0) = {balance.change:.9g} J, "
        f"friction work {ledger.friction_work:.9g} J, impact losses {ledger.impact_loss:.9g} J, "
        f"actuator work {ledger.actuator_work:.3g} J; residual {balance.residual:.3e} J = "
        f"{abs(balance.residual) / reference:.2e} of the "
        f"{'initial energy' if args.elastic else 'energy dissipated'}"
    )
    return balance


if __name__ == "__main__":
    main()
