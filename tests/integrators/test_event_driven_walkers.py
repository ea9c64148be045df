r"""McGeer's rimless wheel under event_driven: the stance foot sticks, the heel strike is plastic.

The run is the integrator's own (sustained friction holds the stance foot, Newton's law with
Coulomb friction at the two-contact strike), against closed forms written here from angular
momentum and energy (docs/legged.md): the strike keeps the angular momentum about the new
foot, :math:`\omega^+ = \eta\,\omega^-` with :math:`\eta = (\cos 2\alpha + \rho^2)/(1 + \rho^2)`,
so a strike loses :math:`\tfrac12 I (1 - \eta^2)\,\omega^{-2}` (I the inertia about a foot), and
the stance gains :math:`\omega^{-2} = \omega^{+2} + \beta`,
:math:`\beta = 4 g \sin\alpha \sin\gamma / (l (1 + \rho^2))`; the gait's speed is
:math:`\omega^{*2} = \eta^2 \beta / (1 - \eta^2)`.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from ucontrol.integrators.event_driven import EventDriven
from ucontrol.scene import Scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
N_SPOKES, LENGTH, RHO, GRAVITY, SLOPE = 8, 1.0, 0.5, 9.81, 0.1  # [-], [m], [-], [m/s²], [rad]
ALPHA = math.pi / N_SPOKES
ETA = (math.cos(2 * ALPHA) + RHO**2) / (1 + RHO**2)
BETA = 4 * GRAVITY * math.sin(ALPHA) * math.sin(SLOPE) / (LENGTH * (1 + RHO**2))  # [rad²/s²]
OMEGA_STAR = math.sqrt(ETA**2 * BETA / (1 - ETA**2))  # [rad/s]
INERTIA = LENGTH**2 * (1 + RHO**2)  # about a foot, hub mass 1 kg [kg m²]


def _strikes(omega: float, duration: float) -> tuple[list[float], list[float], EventDriven]:
    """Strike times [s] and each strike's kinetic-energy loss [J], from post-strike speed omega."""
    scene = Scene.from_toml(ROBOTS / "rimless_wheel.toml")
    scene = dataclasses.replace(
        scene,
        v0=omega * np.array([LENGTH * math.cos(ALPHA), LENGTH * math.sin(ALPHA), 1.0]),
        integrator=dataclasses.replace(scene.integrator, name="event_driven", dt=0.01),
    )
    integrator = scene.build_integrator()
    assert isinstance(integrator, EventDriven)
    q, v, t = scene.q0, scene.v0, 0.0
    times, losses = [], []
    for _ in range(round(duration / integrator.dt)):
        before = integrator.ledger.impact_loss
        outcome = integrator.step(integrator.evaluate(q, v, t), np.zeros(3))
        q, v, t = outcome.q, outcome.v, t + integrator.dt
        if outcome.impacts:
            assert len(outcome.impacts) == 1  # one foot strikes, the other leaves
            times.append(outcome.impacts[0][1])
            losses.append(integrator.ledger.impact_loss - before)
    return times, losses, integrator


def _post_strike_speed(loss: float) -> float:
    """ω⁺ from a strike's loss ½ I (1 - η²) ω⁻², in [rad/s]."""
    return ETA * math.sqrt(2 * loss / (INERTIA * (1 - ETA**2)))


def _step_period(omega_plus: float) -> float:
    """Time from strike to strike [s]: the energy integral over the stance angle, by quadrature."""
    k = 2 * GRAVITY / (LENGTH * (1 + RHO**2))  # [1/s²]

    def dt_dphi(phi: float) -> float:
        return 1.0 / math.sqrt(omega_plus**2 + k * (math.cos(ALPHA - SLOPE) - math.cos(phi)))

    return quad(dt_dphi, SLOPE - ALPHA, SLOPE + ALPHA, epsabs=1e-14, epsrel=1e-13)[0]


def test_the_gait_is_steady_under_event_driven() -> None:
    """Started on the gait: every strike returns ω* at the period T*.

    Measured: ω⁺ to 1.2e-15 relative, the strike times to 2.4e-15 s.
    """
    times, losses, integrator = _strikes(OMEGA_STAR, 1.4)
    assert len(losses) == 2
    for loss in losses:
        assert abs(_post_strike_speed(loss) - OMEGA_STAR) <= 1e-9 * OMEGA_STAR
    period = _step_period(OMEGA_STAR)  # 0.66173 s
    np.testing.assert_allclose(times, [period, 2 * period], rtol=0.0, atol=1e-9)
    assert abs(integrator.ledger.friction_work) <= 1e-12  # the stance foot sticks


@pytest.mark.slow
def test_strides_follow_the_stride_map_towards_the_gait() -> None:
    """From 1 rad/s: ω⁺ follows ω⁺ ← η (ω⁺² + β)^½ stride after stride (measured 9e-16)."""
    _, losses, _ = _strikes(1.0, 3.0)
    assert len(losses) == 3
    omega = 1.0
    for loss in losses:
        omega = ETA * math.sqrt(omega**2 + BETA)
        assert abs(_post_strike_speed(loss) - omega) <= 1e-9 * omega
    assert abs(omega - OMEGA_STAR) < abs(1.0 - OMEGA_STAR)
