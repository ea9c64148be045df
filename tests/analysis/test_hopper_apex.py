"""The hopper's apex map (robots/hopper.toml under Raibert's laws): its gait and multipliers.

The apex map is the event-driven closed loop (:class:`~ucontrol.analysis.hop_flow.HopFlow`)
from one apex to the next; the chart is every coordinate at the apex but x (the map does
not depend on it) and ż (0 on the section): (z, pitch, hip, l, ẋ, pitch rate, hip rate, l̇).
The vertical ones are deadbeat (the thrust law restores the energy whatever the bottom state),
the forward speed and attitude ones are not. :func:`find_gait` with ``section="apex"`` gives the
fixed point and the multipliers; the reference is the closed loop itself: hops from the
fixed point pushed along each eigenvector, whose deviation after one hop is that
eigenvector times the multiplier (the map's linearisation, read off the flow without the
Jacobian find_gait computed).
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from ucontrol.analysis.gait import find_gait
from ucontrol.analysis.hop_flow import HopFlow
from ucontrol.campaign.overrides import apply_overrides
from ucontrol.exceptions import InvalidParameterError, JointNotFoundError, StrideError
from ucontrol.scene import Scene, load_scene
from ucontrol.scene.builtin_scenes import builtin_scene

#: |multiplier - closed loop's| accepted (issue 28: 1e-4).
MULTIPLIER_TOLERANCE = 1e-4
#: Deviation along an eigenvector [section units] for the closed loop's reference.
PUSH = 1e-4


@pytest.fixture(scope="module")
def hopper() -> tuple[HopFlow, np.ndarray, np.ndarray]:
    scene = load_scene("hopper")
    flow = HopFlow(scene.constraints, scene.build_controller())
    return flow, np.asarray(scene.q0, dtype=float), np.asarray(scene.v0, dtype=float)


def _to_state(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate(([0.0], z[:4])), np.concatenate((z[4:5], [0.0], z[5:]))


def _from_state(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.concatenate((q[1:], v[:1], v[2:]))


def _apex_map(flow: HopFlow, z: np.ndarray) -> np.ndarray:
    hop = flow.apex(*_to_state(z))
    return _from_state(hop.q, hop.v)


@pytest.fixture(scope="module")
def gait(hopper):  # type: ignore[no-untyped-def]
    flow, q0, _ = hopper
    return find_gait(flow, _to_state, _from_state, _from_state(q0, np.zeros(5)), section="apex")


def test_the_apex_gait_is_at_the_command(gait) -> None:  # type: ignore[no-untyped-def]
    """The fixed point's apex is the commanded 0.8 m to 1 % (the law's momentum model)."""
    assert gait.residual < 1e-9
    assert abs(gait.z[0] - 0.8) / 0.8 < 0.01
    assert gait.stable
    assert np.max(np.abs(gait.multipliers)) > 0.1  # a map with non-trivial multipliers


def test_multipliers_against_the_closed_loop(hopper, gait) -> None:  # type: ignore[no-untyped-def]
    """Each eigenpair of DP against hops of the closed loop pushed along the eigenvector."""
    flow, _, _ = hopper
    values, vectors = np.linalg.eig(gait.jacobian)
    for value, vector in zip(values, vectors.T, strict=True):
        # a complex pair: push along the real and imaginary parts, DP (a + ib) = λ (a + ib)
        for part, image in (
            (vector.real, (value * vector).real),
            (vector.imag, (value * vector).imag),
        ):
            if np.linalg.norm(part) < 1e-3:
                continue
            ahead = _apex_map(flow, gait.z + PUSH * part) - gait.z
            behind = _apex_map(flow, gait.z - PUSH * part) - gait.z
            measured = (ahead - behind) / (2.0 * PUSH)  # DP applied to the vector
            assert np.max(np.abs(measured - image)) < MULTIPLIER_TOLERANCE


def test_an_unknown_section_is_refused(hopper) -> None:  # type: ignore[no-untyped-def]
    flow, q0, _ = hopper
    with pytest.raises(InvalidParameterError, match="section"):
        find_gait(flow, _to_state, _from_state, _from_state(q0, np.zeros(5)), section="top")


def test_a_flow_without_the_section_is_refused() -> None:
    class Strides:
        def stride(self, q: np.ndarray, v: np.ndarray) -> None: ...

    with pytest.raises(InvalidParameterError, match="apex"):
        find_gait(Strides(), _to_state, _from_state, np.zeros(8), section="apex")


def test_an_apex_never_reached_is_a_stride_error(hopper) -> None:  # type: ignore[no-untyped-def]
    """Started on the ground at rest with the leg at rest length: no hop, no apex."""
    flow, _, _ = hopper
    short = HopFlow(flow.constraints, flow.law, max_duration=0.3)
    with pytest.raises(StrideError, match="never crossed"):
        short.apex(np.array([0.0, 0.8, 0.0, 0.0, 0.5]), np.zeros(5))


def _flow_with_friction(mu: float) -> HopFlow:
    path = builtin_scene("hopper")
    table = apply_overrides(tomllib.loads(path.read_text()), {"contacts.0.friction": mu})
    scene = Scene.from_dict(table, base_dir=path.parent)
    return HopFlow(scene.constraints, scene.build_controller())


def test_a_touchdown_outside_the_cone_is_a_stride_error() -> None:
    """At 1 m/s the touchdown's |P_t| / P_n is 0.49: mu = 0.3 cannot hold it."""
    flow = _flow_with_friction(0.3)
    with pytest.raises(StrideError, match="not a sticking one"):
        flow.apex(np.array([0.0, 0.8, 0.0, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0, 0.0]))


def test_a_slipping_stance_is_a_stride_error() -> None:
    """A pitch rate of 0.5 rad/s: the stance attitude torque pulls the foot out of mu = 0.2."""
    flow = _flow_with_friction(0.2)
    with pytest.raises(StrideError, match="slip"):
        flow.apex(np.array([0.0, 0.8, 0.0, 0.0, 0.5]), np.array([0.0, 0.0, 0.5, 0.0, 0.0]))


def test_a_flow_needs_one_foot_and_a_prismatic_height(hopper) -> None:  # type: ignore[no-untyped-def]
    flow, _, _ = hopper
    walker = load_scene("compass_walker")
    with pytest.raises(InvalidParameterError, match="exactly one point contact"):
        HopFlow(walker.constraints, flow.law)
    with pytest.raises(JointNotFoundError, match="free"):
        HopFlow(flow.constraints, flow.law, height_joint="free")
    with pytest.raises(InvalidParameterError, match="prismatic"):
        HopFlow(flow.constraints, flow.law, height_joint="pitch")
