"""Poisson's and the energetic law as event_driven's impact laws (frictionless contacts)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import brentq

from ucontrol.exceptions import InvalidParameterError, ShapeError, SimulationError
from ucontrol.integrators.event_driven import EventDriven
from ucontrol.integrators.frictional_impact import frictional_impact_velocity
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate

_SCENES = {name: load_scene(builtin_scene(name)) for name in ("ball", "newton_cradle")}


def _scene(scene: str, **integrator: Any) -> Scene:
    """A shipped scene with its ``[integrator]`` settings changed (checked again)."""
    base = _SCENES[scene]
    return dataclasses.replace(base, integrator=dataclasses.replace(base.integrator, **integrator))


@pytest.mark.parametrize("law", ["poisson", "energetic"])
def test_single_contact_laws_are_newtons_without_friction(law: str) -> None:
    """A bouncing ball: Poisson's and Stronge's coefficients give Newton's rebounds."""
    newton = simulate(_scene("ball", name="event_driven"), duration=1.5).log
    other = simulate(_scene("ball", name="event_driven", impact_law=law), duration=1.5).log
    assert int((newton.impulse[:, 0] > 0).sum()) >= 2
    np.testing.assert_allclose(other.impulse, newton.impulse, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(other.v, newton.v, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(other.q, newton.q, rtol=0.0, atol=1e-12)


def test_energetic_law_passes_simultaneous_impacts_to_lzb() -> None:
    """Newton's cradle (touching balls): the energetic law is LZB's at simultaneous impacts."""
    lzb = simulate(_scene("newton_cradle", impact_law="lzb"), duration=0.05).log
    energetic = simulate(_scene("newton_cradle", impact_law="energetic"), duration=0.05).log
    np.testing.assert_allclose(energetic.v, lzb.v, rtol=0.0, atol=1e-12)


def test_poisson_refuses_simultaneous_impacts() -> None:
    with pytest.raises(SimulationError) as caught:
        simulate(_scene("newton_cradle", impact_law="poisson"), duration=0.05)
    cause = caught.value.__cause__
    assert isinstance(cause, InvalidParameterError)
    assert "poisson" in str(cause) and "single contact" in str(cause)


@pytest.mark.parametrize("integrator", ["moreau_jean", "compliant"])
@pytest.mark.parametrize("law", ["poisson", "energetic"])
def test_other_integrators_refuse_the_laws(integrator: str, law: str) -> None:
    with pytest.raises(InvalidParameterError, match=rf"impact_law.*'{law}'"):
        _scene("ball", name=integrator, impact_law=law).build_integrator()


def test_unknown_restitution_law_is_refused() -> None:
    scene = _scene("ball", name="event_driven")
    with pytest.raises(InvalidParameterError, match=r"restitution_law.*'routh'"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, restitution_law="routh")


def test_per_constraint_laws() -> None:
    """One law per constraint: all energetic is the scalar law; mixed laws refuse together."""
    scalar = simulate(_scene("newton_cradle", impact_law="energetic"), duration=0.05).log
    listed = simulate(
        _scene("newton_cradle", impact_law=["energetic", "energetic"]), duration=0.05
    ).log
    np.testing.assert_allclose(listed.v, scalar.v, rtol=0.0, atol=0.0)
    newton = simulate(_scene("newton_cradle"), duration=0.05).log
    listed = simulate(_scene("newton_cradle", impact_law=["newton", "newton"]), duration=0.05).log
    np.testing.assert_allclose(listed.v, newton.v, rtol=0.0, atol=0.0)
    with pytest.raises(SimulationError) as caught:
        simulate(_scene("newton_cradle", impact_law=["energetic", "newton"]), duration=0.05)
    assert "mixed laws" in str(caught.value.__cause__)


@pytest.mark.parametrize(
    ("laws", "error", "match"),
    [
        (["energetic"], ShapeError, r"impact_law"),
        (["energetic", "lzb"], InvalidParameterError, r"impact_law.*'lzb'"),
    ],
)
def test_per_constraint_law_lists_are_checked(laws: list[str], error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        _scene("newton_cradle", impact_law=laws).build_integrator()


def test_restitution_law_list_length_is_checked() -> None:
    scene = _scene("ball", name="event_driven")
    with pytest.raises(ShapeError, match="restitution_law"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, restitution_law=["energetic"] * 5)


def _rough_rod(
    pitch: float,
    v0: list[float],
    restitution: float = 0.6,
    g: float = 0.0,
    mu: float = 0.4,
    planar: bool = True,
    **integrator: Any,
) -> Scene:
    """Painlevé's rod (1 m, 1 kg, x-z plane) striking a rough floor (friction ``mu``).

    Its lower end starts 0.09 m above the floor; gravity ``g`` in [m/s²].
    """
    table = {
        "name": "rough_rod",
        "robot": {
            "urdf": "rod.urdf",
            "q0": [0.0, 0.5 * math.sin(pitch) + 0.09, pitch],
            "v0": v0,
            "gravity": [0.0, 0.0, -g],
            **({"planar_axis": [0.0, 1.0, 0.0]} if planar else {}),
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [
            {"frame": end, "surface": "ground", "friction": mu, "restitution": restitution}
            for end in ("rod_end", "rod_other_end")
        ],
        "integrator": {"name": "event_driven", "dt": 0.02, **integrator},
    }
    return Scene.from_dict(table, base_dir=builtin_scene().parent)


@pytest.mark.parametrize("law", ["poisson", "energetic"])
@pytest.mark.parametrize(
    ("v0", "mu", "transition"),
    [
        ([1.0, -1.0, 0.0], 0.4, None),
        ([-1.5, -1.0, 2.0], 0.4, None),
        ([-0.3, -1.0, 0.0], 0.4, "reversal"),
        ([0.5, -1.0, 0.0], 1.0, "stick"),
    ],
)
def test_rod_strikes_a_rough_floor_in_event_driven(
    law: str, v0: list[float], mu: float, transition: str | None
) -> None:
    """One frictional impact in flight: v+ against the impact map at the located impact.

    Without gravity the flight is uniform: the end rod_end (lower, at pitch p it is
    0.5 (cos p, -sin p) from the centre) touches the floor where z + vz t - 0.5 sin(p + w t)
    vanishes; the velocity after it is the map's at that configuration.
    """
    scene = _rough_rod(0.6, v0, mu=mu, impact_law=law)
    log = simulate(scene, duration=0.2).log
    q0, v = np.array([0.0, 0.5 * math.sin(0.6) + 0.09, 0.6]), np.array(v0)
    t_hit = brentq(lambda t: q0[1] + v[1] * t - 0.5 * math.sin(q0[2] + v[2] * t), 0.0, 0.2)
    p = q0[2] + v[2] * t_hit
    M = np.diag([1.0, 1.0, 1.0 / 12.0])
    H = np.array([[0.0, 1.0, -0.5 * math.cos(p)], [1.0, 0.0, -0.5 * math.sin(p)], [0.0, 0.0, 0.0]])
    v_plus, result = frictional_impact_velocity(M, H, v, friction=mu, restitution=0.6, law=law)
    assert log.impulse[:, 0].sum() == pytest.approx(result.impulse[0], rel=1e-8)
    assert not log.impulse[:, 1].any()
    assert np.abs(log.v[log.t < t_hit] - v).max() <= 1e-12
    assert np.abs(log.v[log.t > t_hit] - v_plus).max() <= 1e-8
    assert result.kinetic_change < 0.0
    assert transition is None or transition in result.names()


@pytest.mark.parametrize("law", ["newton", "energetic"])
def test_plastic_landing_then_sliding_closes_the_energy_balance(law: str) -> None:
    """The rod lands plastically on one end, falls flat, slides and stops (sustained friction).

    Its energy change is the friction work of the sliding phases minus the impacts' losses
    (:class:`~ucontrol.integrators.event_driven.EnergyLedger`): measured to 1.2e-13 J of 4.15 J.
    """
    plastic = _rough_rod(0.6, [0.0, -1.0, 0.0], restitution=0.0, g=9.81, impact_law=law)
    integrator = plastic.build_integrator()
    assert isinstance(integrator, EventDriven)
    q, v, t = plastic.q0, plastic.v0, 0.0
    start = integrator.evaluate(q, v, t)
    for _ in range(50):  # 1 s
        outcome = integrator.step(integrator.evaluate(q, v, t), np.zeros(3))
        q, v, t = outcome.q, outcome.v, t + integrator.dt
    end = integrator.evaluate(q, v, t)
    change = end.kinetic_energy + end.potential_energy - start.kinetic_energy
    change -= start.potential_energy
    ledger = integrator.ledger
    assert ledger.friction_work < -0.01 and ledger.impact_loss > 1.0
    assert abs(change - ledger.balance) <= 1e-9 * abs(change)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)  # at rest, flat: it stuck
    assert abs(q[1]) <= 1e-12 and abs(q[2]) <= 1e-12


def test_rod_refusals_in_event_driven() -> None:
    """Poisson's law and 3D friction at both ends striking together."""
    flat = _rough_rod(0.0, [0.0, -1.0, 0.0], impact_law="poisson")
    with pytest.raises(SimulationError) as caught:
        simulate(flat, duration=0.2)
    assert "'energetic' at simultaneous impacts with friction" in str(caught.value.__cause__)
    spatial = _rough_rod(0.0, [0.0, -1.0, 0.0], planar=False, impact_law="energetic")
    with pytest.raises(SimulationError) as caught:
        simulate(spatial, duration=0.2)
    assert "3D friction (two tangents per contact)" in str(caught.value.__cause__)


@pytest.mark.parametrize(("vx", "mu"), [(1.0, 0.3), (1.0, 1.0), (-0.5, 0.1)])
@pytest.mark.parametrize("exponent", [1.0, 1.5])
def test_flat_rod_lands_on_both_ends_by_lzb_with_friction(
    vx: float, mu: float, exponent: float
) -> None:
    """Both ends strike together: the energetic law goes to LZB with (planar) friction.

    By symmetry the impulses are equal and the rod does not turn: the centre rebounds at
    e |v_z| and its sliding drops by μ (1 + e) |v_z| or stops (then it sticks).
    """
    scene = _rough_rod(0.0, [vx, -1.0, 0.0], mu=mu, impact_law="energetic", lzb_exponent=exponent)
    log = simulate(scene, duration=0.2).log
    slide = math.copysign(max(0.0, abs(vx) - mu * 1.6), vx)
    np.testing.assert_allclose(log.v[-1], [slide, 0.6, 0.0], rtol=0.0, atol=1e-8)
    assert log.impulse[:, 0].sum() == pytest.approx(0.8, rel=1e-8)  # half of (1 + e) m |v_z|


@pytest.mark.parametrize("mu", [0.05, 0.2])
def test_spinning_ball_strikes_a_rough_floor_in_3d(mu: float) -> None:
    """A free ball (1 kg, r = 0.1 m, I = 2 m r²/5) with spin hits a rough floor, no gravity.

    Closed form: W_nt = 0, so P_n = (1 + e) m |v_z| under every law and the slip keeps its
    direction; the slip velocity u_t = v_xy + r (-ω_y, ω_x) drops at the rate W_tt μ P_n,
    W_tt = 1/m + r²/I = 3.5 /kg, and the ball either slips throughout (μ = 0.05) or rolls
    (μ = 0.2, u_t⁺ = 0).
    """
    v0 = np.array([0.5, -0.2, -1.0, 3.0, 1.0, 2.0])  # world = local at the start [m/s, rad/s]
    table = {
        "name": "rough_ball",
        "robot": {
            "urdf": "free_ball.urdf",
            "floating_base": True,
            "q0": [0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0],
            "v0": v0.tolist(),
            "gravity": [0.0, 0.0, 0.0],
        },
        "surfaces": {"ground": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}},
        "contacts": [
            {
                "frame": "ball",
                "surface": "ground",
                "radius": 0.1,
                "restitution": 0.9,
                "friction": mu,
            }
        ],
        "integrator": {"name": "event_driven", "dt": 0.01, "impact_law": "energetic"},
    }
    log = simulate(Scene.from_dict(table, base_dir=builtin_scene().parent), duration=0.4).log
    r, I = 0.1, 0.004
    P_n = 1.9 * 1.0
    slip = np.array([v0[0] - r * v0[4], v0[1] + r * v0[3]])
    speed = float(np.linalg.norm(slip))
    P_t = -slip / 3.5 if 3.5 * mu * P_n >= speed else -mu * P_n * slip / speed
    v_world = v0[:3] + np.array([P_t[0], P_t[1], P_n])
    w_world = v0[3:] + np.array([r * P_t[1], -r * P_t[0], 0.0]) / I
    q, v = log.q[-1], log.v[-1]
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    assert np.abs(R @ v[:3] - v_world).max() <= 1e-8
    assert np.abs(R @ v[3:] - w_world).max() <= 1e-8
    if 3.5 * mu * P_n >= speed:  # rolling: the contact point leaves at rest tangentially
        rolling = v_world[:2] + r * np.array([-w_world[1], w_world[0]])
        assert np.abs(rolling).max() <= 1e-8


@pytest.mark.parametrize("e_t", [-0.5, 0.0, 0.8])
def test_rod_with_brach_tangential_restitution(e_t: float) -> None:
    """Newton's law with Brach's e_t in event_driven: u_n⁺ = -e u_n⁻, u_t⁺ = -e_t u_t⁻."""
    scene = _rough_rod(
        0.6, [1.0, -1.0, 0.0], mu=5.0, impact_law="newton", tangential_restitution=e_t
    )
    log = simulate(scene, duration=0.2).log
    p = 0.6  # no rotation before the impact
    H = np.array([[0.0, 1.0, -0.5 * math.cos(p)], [1.0, 0.0, -0.5 * math.sin(p)]])
    u_minus, u_plus = H @ np.array([1.0, -1.0, 0.0]), H @ log.v[-1]
    assert u_plus[0] == pytest.approx(-0.6 * u_minus[0], abs=1e-10)
    assert u_plus[1] == pytest.approx(-e_t * u_minus[1], abs=1e-10)


def test_tangential_restitution_setting_is_checked() -> None:
    with pytest.raises(InvalidParameterError, match=r"tangential_restitution.*1\.5"):
        _rough_rod(0.6, [1.0, -1.0, 0.0], impact_law="newton", tangential_restitution=1.5)
    scene = _scene("ball", name="event_driven")
    with pytest.raises(InvalidParameterError, match=r"tangential_restitution"):
        EventDriven(scene.robot, scene.constraints, dt=1e-3, tangential_restitution=-2.0)
