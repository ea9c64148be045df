"""Order of Moreau–Jean's midpoint variant between impacts (θ = 1/2), against references.

Two smooth motions, each run at the steps h, h/2 and h/4:

- the four-bar of ``robots/four_bar.toml`` (bilateral point closure, configuration projected
  after every step) against its one-coordinate model in the crank angle (closed-form position
  analysis, Lagrange's equation by scipy: ``test_bilateral._reduced_motion``);
- the two-link drop of ``robots/two_link_drop.toml`` before its first impact (the wall, at 0.131 s),
  against Pinocchio's ABA integrated by scipy's DOP853.

The midpoint variant must converge at order two (measured 1.96–2.00, experiments/midpoint_order.py),
the default step at order one.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import scipy.integrate
from test_bilateral import _four_bar, _reduced_motion

from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate

STEPS = (2e-3, 1e-3, 5e-4)  # [s]
#: Smallest order the midpoint variant must show per halving of h (measured 2.00 on both cases).
SECOND_ORDER = 1.8
#: Range the default step's order must lie in per halving (measured 0.99–1.00).
FIRST_ORDER = (0.8, 1.3)


def _orders(errors: list[float]) -> np.ndarray:
    """Observed order between consecutive halvings of the step."""
    return np.log2(np.array(errors[:-1]) / np.array(errors[1:]))


def _run(scene: Scene, dt: float, midpoint: bool, duration: float) -> tuple[np.ndarray, ...]:
    integrator = dataclasses.replace(scene.integrator, dt=dt, theta=0.5, midpoint=midpoint)
    log = simulate(
        dataclasses.replace(scene, integrator=integrator), duration=duration, progress=False
    ).log
    return np.asarray(log.t), np.asarray(log.q), np.asarray(log.impulse)


def test_midpoint_is_second_order_on_the_four_bar() -> None:
    duration, every = 0.5, 1e-2  # [s]: compared every 10 ms
    times = np.arange(0.0, duration + 0.5 * every, every)
    reference = _reduced_motion(1.0, times)  # crank angle [rad]
    errors: dict[bool, list[float]] = {False: [], True: []}
    for midpoint in (False, True):
        for dt in STEPS:
            _, q, _ = _run(_four_bar(), dt, midpoint, duration)
            crank = q[:: round(every / dt), 0]
            errors[midpoint].append(float(np.max(np.abs(crank - reference))))
    assert np.all(_orders(errors[True]) > SECOND_ORDER), errors
    low, high = FIRST_ORDER
    assert np.all((_orders(errors[False]) > low) & (_orders(errors[False]) < high)), errors
    assert errors[True][-1] < errors[False][-1] / 20.0  # 4.8e-5 against 8.2e-3 rad measured


def _aba_motion(scene: Scene, times: np.ndarray) -> np.ndarray:
    """Configurations at ``times`` of M(q) a = -h(q, v) from the start (DOP853, rtol 1e-13)."""
    model = scene.robot.model
    data = model.createData()
    nq = model.nq

    def rhs(_: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:nq], y[nq:]
        return np.concatenate((v, pin.aba(model, data, q, v, np.zeros(model.nv))))

    start = np.concatenate((scene.q0, scene.v0))
    solution = scipy.integrate.solve_ivp(
        rhs, (0.0, times[-1]), start, method="DOP853", t_eval=times, rtol=1e-13, atol=1e-14
    )
    return solution.y[:nq].T


def test_midpoint_is_second_order_on_the_two_link_drop_before_its_impact() -> None:
    scene = load_scene(builtin_scene("two_link_drop.toml"))  # zero torque, gravity
    duration = 0.12  # [s], the first impact is at 0.131 s
    errors: dict[bool, list[float]] = {False: [], True: []}
    for midpoint in (False, True):
        for dt in STEPS:
            t, q, impulse = _run(scene, dt, midpoint, duration)
            assert not np.any(impulse > 0.0)  # a smooth window
            errors[midpoint].append(float(np.max(np.abs(q - _aba_motion(scene, t)))))
    assert np.all(_orders(errors[True]) > SECOND_ORDER), errors
    low, high = FIRST_ORDER
    assert np.all((_orders(errors[False]) > low) & (_orders(errors[False]) < high)), errors
