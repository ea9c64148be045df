"""RABBIT's walking gait under the HZD law (robots/rabbit_walk.toml): found, judged, walked.

The gait is found by Newton on the stride map of the event-driven closed loop (section
"heel_strike"); its multipliers are checked against two independent computations: the
zero dynamics' own multiplier δ² (the ratio of the angular momenta about the new and the old
stance foot across the strike, squared), and finite differences of the closed loop along the
leading eigenvector. The scene then walks under Moreau–Jean.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.analysis.biped_section import BipedSection, find_biped_gait
from ucontrol.analysis.gait import Gait
from ucontrol.control.hzd_controller import HZDController
from ucontrol.exceptions import InvalidParameterError, ShapeError
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

#: Steps walked under Moreau–Jean here (experiments/biped_walk.py walks 100).
STEPS = 5


@pytest.fixture(scope="module")
def scene() -> Scene:
    return load_scene("rabbit_walk")


def _found(scene: Scene) -> tuple[BipedSection, Gait]:
    """The scene's section and gait, found from its start."""
    law = scene.build_controller()
    assert isinstance(law, HZDController)
    return find_biped_gait(law, scene.constraints, scene.q0, scene.v0)


@pytest.fixture(scope="module")
def found(scene: Scene) -> tuple[BipedSection, Gait]:
    return _found(scene)


@pytest.fixture(scope="module")
def section(found: tuple[BipedSection, Gait]) -> BipedSection:
    return found[0]


@pytest.fixture(scope="module")
def gait(found: tuple[BipedSection, Gait]) -> Gait:
    return found[1]


def _momentum(scene: Scene, q: np.ndarray, v: np.ndarray, foot: str) -> float:
    """Angular momentum about the foot, about the y axis [kg m²/s]."""
    model = scene.robot.model
    data = pin.Data(model)
    pin.computeCentroidalMomentum(model, data, q, v)
    com = pin.centerOfMass(model, data, q, v)
    mass = pin.computeTotalMass(model)
    r = com - scene.robot.frame_position(q, foot)
    p = mass * data.vcom[0]
    return float(data.hg.angular[1] + r[2] * p[0] - r[0] * p[2])


def test_the_chart_is_inverted(scene: Scene, section: BipedSection) -> None:
    z = section.from_state(scene.q0, scene.v0)
    q, v = section.to_state(z)
    np.testing.assert_allclose(q, scene.q0, atol=1e-11)
    np.testing.assert_allclose(v, scene.v0, atol=1e-11)


def test_the_gait_is_period_one_and_stable(gait: Gait) -> None:
    assert gait.residual < 1e-8
    assert gait.multipliers.size == 9
    assert gait.stable
    assert gait.period == pytest.approx(0.5759, abs=1e-3)  # the design's 0.5758 s


def test_leading_multiplier_is_that_of_the_zero_dynamics(
    scene: Scene, section: BipedSection, gait: Gait
) -> None:
    """The orbit lies on the zero dynamics: the stride map's leading multiplier is δ².

    δ = L⁺ / L⁻, angular momenta about the new stance foot just after the strike and about the
    old one just before it (L is continuous over the stance: the feet's forces have no moment
    about the stance foot).
    """
    stride = section.flow.stride(gait.q, gait.v)
    assert stride.stance == 1  # the right foot struck
    before = _momentum(scene, stride.q, stride.v_minus, "foot_left")
    after = _momentum(scene, stride.q, stride.v, "foot_right")
    delta2 = (after / before) ** 2
    assert delta2 == pytest.approx(0.6772, abs=1e-4)  # experiments/biped_gait_design.py
    assert abs(gait.multipliers[0]) == pytest.approx(delta2, abs=1e-6)
    assert np.max(np.abs(gait.multipliers[1:])) < 1e-3  # the outputs' transients, damped


def test_leading_multiplier_against_the_closed_loop(section: BipedSection, gait: Gait) -> None:
    """P(z* + εw) - P(z* - εw) = 2ελw along the leading eigenvector w, strides run anew."""
    values, vectors = np.linalg.eig(gait.jacobian)
    k = int(np.argmax(np.abs(values)))
    w = np.real(vectors[:, k])
    eps = 1e-4

    def stride_map(z: np.ndarray) -> np.ndarray:
        q, v = section.to_state(z)
        stride = section.flow.stride(q, v)
        return section.from_state(stride.q, stride.v)

    image = (stride_map(gait.z + eps * w) - stride_map(gait.z - eps * w)) / (2 * eps)
    np.testing.assert_allclose(image, np.real(values[k]) * w, atol=1e-5)


def test_walks_under_moreau_jean(scene: Scene, gait: Gait) -> None:
    """Five steps from the gait's fixed point: steps of the gait's period, upright, no slip."""
    log = simulate(scene, duration=STEPS * 1.03 * gait.period + 0.2, progress=False).log
    t, q = np.asarray(log.t), np.asarray(log.q)
    stance = np.asarray(log.stance)
    swaps = t[1:][np.diff(stance) != 0]
    assert swaps.size == STEPS
    periods = np.diff(np.concatenate(([0.0], swaps)))
    # the zero-order hold and strikes captured within a step: up to 5 % slower (measured 3 %)
    assert np.all((periods > gait.period - 1e-3) & (periods < 1.06 * gait.period))
    assert np.min(q[:, 1]) > 0.75  # the hip stays up [m]
    speed = (q[-1, 0] - q[0, 0]) / t[-1]
    assert speed == pytest.approx(0.6, rel=0.05)
    # the stance foot does not slip: its x barely moves while it is the stance foot
    left = np.array([scene.robot.frame_position(qk, "foot_left")[0] for qk in q])
    on_left = stance == 0
    assert np.ptp(left[on_left & (t < swaps[0] - 0.01)]) < 1e-3


def test_bad_section_input_is_refused(scene: Scene, section: BipedSection) -> None:
    with pytest.raises(ShapeError, match="z"):
        section.to_state(np.zeros(7))
    with pytest.raises(InvalidParameterError, match="planar base"):
        BipedSection(section.law, section.flow, base=("x", "z", "knee_left"))


def test_the_designed_gait_is_a_stable_gait_of_the_event_driven_closed_loop() -> None:
    """robots/rabbit_walk_designed.toml (the casadi OCP's step, L = 0.4 m at 0.6 m/s).

    Its start is the post-impact instant: the trailing foot still touches the ground, a few
    1e-7 m below the new stance foot (the transcription's drift), and leaves upwards.
    """
    gait = _found(load_scene("rabbit_walk_designed"))[1]
    designed_period = 0.4 / 0.6  # [s] the task's step length over its speed
    assert gait.period == pytest.approx(designed_period, rel=5e-3)  # measured 7.8e-4
    assert gait.stable and np.max(np.abs(gait.multipliers)) < 0.7  # measured 0.607
