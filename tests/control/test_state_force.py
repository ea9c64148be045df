"""The desired contact force designed from the state (``force_profile = "state"``, book §8.1.4).

The law chooses λ_d so that the contact force it produces in the constrained phase is the time
profile λ_t > 0. Checked here against an independent computation of that force (the
constrained dynamics M a + h = τ + J_cᵀ λ, J_c a + J̇_c v = 0 solved with numpy on Pinocchio's
terms), and in closed loop: the contact force stays positive on every step of every
constrained phase of the shipped tracking scenes.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pinocchio as pin
import pytest

from ucontrol.control.controller import ContactState
from ucontrol.control.desired_cycle import DesiredCycle
from ucontrol.control.phase import Phase
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene, load_scene
from ucontrol.simulate import simulate

#: Largest error of the law's contact force against the constrained dynamics, in [N].
#: Measured: 7.1e-15 (two-link), 3.9e-13 (Panda).
FORCE_TOLERANCE = 1e-9


def _scene(name: str, **controller: object) -> Scene:
    """A shipped scene with keys of its ``[controller]`` table replaced."""
    source = load_scene(name).source
    assert source is not None
    table = tomllib.loads(source.read_text())
    table.pop("reference", None)
    table["controller"].update(controller)
    return Scene.from_dict(table, base_dir=source.parent)


def _constrained_force(controller, q, v, tau):  # type: ignore[no-untyped-def]
    """Contact forces [N] of the held rows under ``tau``, from Pinocchio's terms and numpy."""
    model, data = controller.robot.model, pin.Data(controller.robot.model)
    pin.computeAllTerms(model, data, q, v)
    pin.computeJointJacobiansTimeVariation(model, data, q, v)
    pin.updateFramePlacements(model, data)
    state = controller.task.evaluate(model, data, v)
    rows = controller.machine.coordinates
    J_c, drift = state.J[rows], (state.dJ @ v)[rows]
    M = data.M.copy()
    M[np.tril_indices_from(M, -1)] = M.T[np.tril_indices_from(M, -1)]
    n = len(rows)
    kkt = np.block([[M, -J_c.T], [J_c, np.zeros((n, n))]])
    solution = np.linalg.solve(kkt, np.concatenate([tau - data.nle, -drift]))
    return solution[M.shape[0] :]


@pytest.mark.parametrize("name", ["two_link_one_constraint", "panda_table"])
@pytest.mark.parametrize("measured", [False, True])
def test_the_law_produces_the_time_profile_as_contact_force(
    name: str, measured: bool, rng: np.random.Generator
) -> None:
    controller = _scene(name, force_profile="state").build_controller()
    contacts = list(controller.machine.contacts)
    n, lambda_t = len(contacts), 7.0  # [N]
    open_contacts = ContactState(
        contacts, np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n, bool), 1e-3
    )
    q0 = load_scene(name).q0
    largest = 0.0
    for k in range(20):
        q = q0 + 0.05 * rng.standard_normal(q0.size)
        v = 0.3 * rng.standard_normal(controller.robot.nv)
        controller(1e-3 * k, q, v, open_contacts)  # writes the state's inputs
        held = controller.machine.desired(1e-3 * k)._replace(
            force=np.full(n, lambda_t), constrained=np.ones(n, bool)
        )
        if measured:  # held at the last call, with a valid measurement equal to λ_t
            controller.desired = held
            controller._persistent[...] = True
            controller.contact_force[...] = lambda_t
        controller._evaluate_law(held)
        tau = controller._tau_output.copy()
        force = _constrained_force(controller, q, v, tau)
        largest = max(largest, float(np.max(np.abs(force - lambda_t))))
        applied = controller._lambda_d_output[controller.machine.coordinates]
        assert not np.allclose(applied, lambda_t)  # the state's correction is not nil
    assert largest <= FORCE_TOLERANCE


#: The shipped tracking scenes, each run over one cycle with the state-based λ_d: the rigid
#: ones with ``force_profile = "state"`` set (they ship the time profile), the flexible ones as
#: their ``_state`` variants ship (the state profile and a 2 mm virtual target).
STATE_FORCE_RUNS = {
    "two_link_one_constraint": 11.0,
    "two_link_two_constraints": 11.0,
    "panda_table": 8.5,
    "two_link_flexible_one_constraint_state": 10.5,
    "two_link_flexible_two_constraints_state": 10.5,
}


@pytest.mark.parametrize(("name", "duration"), STATE_FORCE_RUNS.items())
def test_the_contact_force_is_positive_on_every_constrained_step(
    name: str, duration: float
) -> None:
    """λ > 0 on every sample the phase machine spends in CONSTRAINED, on every tracking scene.

    λ is the plant's impulse of the step that ends at the sample divided by its length (the
    measurement the machine decides on at that sample). The takeoff rule is on with the
    state profile: each constrained phase ends in a takeoff once λ_d falls, at t_d or at the
    measured opening before it; only in the rigid two-constraint corner, where the wall's
    impacts (e = 0.7) kick the held ground contact open while λ_d is on its plateau, does a
    contact go back to its transition and settle again.
    """
    scene = _scene(name, force_profile="state")
    controller = scene.build_controller()
    assert controller.cycle.ends_on_opening
    log = simulate(scene, controller, duration=duration, progress=False).log
    phase = np.asarray(log.contact_phase)
    for i, contact in enumerate(controller.machine.contacts):
        # Row k + 1 of the log: the step [t_k, t_k+1] ends there (impulse_of's row k).
        force = log.impulse_of(contact)[:-1] / np.diff(log.t)  # [N]
        held = phase[1:, i] == int(Phase.CONSTRAINED)
        assert held.sum() > 1000, (name, contact)  # a whole constrained phase at least
        assert np.all(force[held] > 0.0), (name, contact, log.t[1:][held & (force <= 0.0)])
        # Each constrained phase ends in the takeoff, within the fall of λ_d.
        ends = np.flatnonzero(held[:-1] & ~held[1:])  # the last held row of each phase
        after = phase[1:, i][ends + 1]
        takeoff = log.t[1:][ends[after == int(Phase.TAKEOFF)] + 1]  # [s]
        cycle = controller.cycle
        end, period = cycle.contact_phases[i].end, cycle.period  # [s]
        t_d = end + period * np.round((takeoff - end) / period)  # of each takeoff's cycle
        assert takeoff.size >= 1 and np.all(takeoff <= t_d + 1e-9), (name, contact)
        assert np.all(takeoff > t_d - cycle.force_fall_time), (name, contact)
        if name != "two_link_two_constraints":
            assert np.all(after == int(Phase.TAKEOFF)), (name, contact)  # never lost


def test_force_profile_and_depth_min_are_checked() -> None:
    cycle = load_scene("two_link_one_constraint").build_controller().cycle
    with pytest.raises(InvalidParameterError, match="force_profile"):
        DesiredCycle(path=cycle.path, contact_phases=cycle.contact_phases, force_profile="x")
    with pytest.raises(InvalidParameterError, match="depth_min"):
        DesiredCycle(path=cycle.path, contact_phases=cycle.contact_phases, depth_min=-1e-3)
    exact = DesiredCycle(path=cycle.path, contact_phases=cycle.contact_phases, depth_min=0.0)
    assert exact.depth(0.0) == 0.0  # the book's d = α V1^p, unclipped below
    assert exact.depth(1e-6) == pytest.approx(exact.depth_gain * 1e-3)  # p = 1/2


@pytest.mark.parametrize(
    "name", ["two_link_flexible_one_constraint", "two_link_flexible_two_constraints"]
)
@pytest.mark.parametrize("measured", [False, True])
def test_the_flexible_law_asks_its_springs_for_the_time_profile_as_contact_force(
    name: str, measured: bool, rng: np.random.Generator
) -> None:
    """With the motors on their reference (e = 0) the links get U_R: the force is λ_t.

    q2 = q2d + (q1 - q1d) makes the springs' torque K(q2 - q1) = K(q2d - q1d) = U_R; the
    constrained link dynamics under it (numpy on Pinocchio's terms) give the contact forces.
    """
    controller = _scene(name, force_profile="state").build_controller()
    flexible, robot = controller.flexible, controller.robot
    contacts = list(controller.machine.contacts)
    n, nv, lambda_t = len(contacts), robot.nv, 7.0  # [N]
    open_contacts = ContactState(
        contacts, np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n, bool), 1e-3
    )
    scene = load_scene(name)
    q0 = np.concatenate([scene.q0, scene.motor_q0])
    motors = flexible.v_index
    largest = 0.0
    for k in range(10):
        q = q0 + 0.05 * rng.standard_normal(q0.size)
        v = 0.3 * rng.standard_normal(q0.size)
        controller(1e-3 * k, q, v, open_contacts)  # writes the state's inputs
        base = controller.machine.desired(1e-3 * k)
        held = base._replace(
            force=np.full(n, lambda_t),
            constrained=np.ones(n, bool),
            force_derivatives=tuple(np.full(n, 3.0 * (j + 1)) for j in range(2)),
        )
        if measured:  # held at the last call, with a valid measurement equal to λ_t
            controller.desired = held
            controller._persistent[...] = True
            controller.contact_force[...] = lambda_t
        controller._evaluate(1e-3 * k, q[:nv], held)
        out = controller._law_output
        q1, q1d = q[:nv], controller._reference_input[:nv]
        q2d = out[2 * nv + 2 : 2 * nv + 2 + flexible.nf]
        link_torque = flexible.stiffness * (q2d + (q1 - q1d)[motors] - q1[motors])  # U_R
        torque = np.zeros(nv)
        torque[motors] = link_torque
        force = _constrained_force(controller, q1, v[:nv], torque)
        largest = max(largest, float(np.max(np.abs(force - lambda_t))))
        applied = out[2 * nv + 2 + 3 * flexible.nf :]
        assert not np.allclose(applied, lambda_t)  # the state's correction is not nil
    assert largest <= FORCE_TOLERANCE


def test_transition_reference_experiment_runs(capsys: pytest.CaptureFixture[str]) -> None:
    """The torque term of the book's q̇_r is measured over the first transitions."""
    from conftest import load_experiment

    rows = load_experiment("transition_reference").main(["--duration", "5.5"])
    assert [row[0] for row in rows] == ["two_link_one_constraint", "two_link_two_constraints"]
    for _, largest_delta, largest_torque, _, _, steps in rows:
        assert steps > 10 and 0.0 < largest_delta < np.inf and largest_torque > 0.0
    assert "| scene | transition steps |" in capsys.readouterr().out


def test_the_books_reference_changes_the_torque_by_its_known_term(
    rng: np.random.Generator,
) -> None:
    """``reference_after_impact = "clipped"``: τ changes by M Δq̈_r + C Δq̇_r (Pinocchio)."""
    from conftest import load_experiment

    delta_torque = load_experiment("transition_reference")._delta_torque
    virtual = _scene("two_link_one_constraint").build_controller()
    clipped = _scene("two_link_one_constraint", reference_after_impact="clipped")
    clipped = clipped.build_controller()
    n = len(virtual.machine.contacts)
    contacts = ContactState(
        list(virtual.machine.contacts),
        np.ones(n),
        np.zeros(n),
        np.zeros(n),
        np.zeros(n, bool),
        1e-3,
    )
    q0, largest = load_scene("two_link_one_constraint").q0, 0.0
    for k in range(20):
        q, v = q0 + 0.05 * rng.standard_normal(2), 0.3 * rng.standard_normal(2)
        torques = []
        for law in (virtual, clipped):
            law(1e-3 * k, q, v, contacts)  # writes the state's inputs
            base = law.machine.desired(1e-3 * k)
            target = (base.target[0] - [0.02, 0.0], base.target[1] + [0.1, 0.0], base.target[2])
            reference = (target[0].copy(), target[1].copy())
            reference[0][0] = reference[1][0] = 0.0  # the gap clipped at the surface, at rest
            law.desired = base._replace(target=target, reference=reference, stacked=None)
            law._evaluate_law(law.desired)
            torques.append(law._tau_output.copy())
        expected = delta_torque(clipped, q, v)
        assert np.max(np.abs(expected)) > 1e-3  # not a comparison of zeros
        largest = max(largest, float(np.max(np.abs(torques[1] - torques[0] - expected))))
    assert largest <= 1e-10  # measured: 3.1e-15 N m


def test_reference_after_impact_is_checked() -> None:
    cycle = load_scene("two_link_one_constraint").build_controller().cycle
    with pytest.raises(InvalidParameterError, match="reference_after_impact"):
        DesiredCycle(
            path=cycle.path, contact_phases=cycle.contact_phases, reference_after_impact="x"
        )
    with pytest.raises(InvalidParameterError, match="reference_after_impact"):
        scene = _scene("two_link_flexible_one_constraint", reference_after_impact="clipped")
        scene.build_controller()
