"""The controllers' fast per-call paths against plain array references.

The measurement of the contact forces and flags, the flexible law's force input and the
impedance law's pseudo-inverse are written on Python scalars or as bare numpy operations for
speed; each is checked here against the array formula it replaces, bitwise (same IEEE
operations in the same order), on random inputs. So are the laws' inputs written by shortcut
(the stacked target in one copy, the reference from the target where nothing is clipped, the
force term reset only after a held contact) against the column-by-column copies, and the log
rows written from cached values against the values they stand for.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ucontrol.control.brogliato_controller import IMPACT_SPEED
from ucontrol.control.controller import ContactState
from ucontrol.control.flexible_brogliato_controller import TAYLOR_CACHE_SIZE
from ucontrol.control.impedance_controller import _pseudo_inverse
from ucontrol.control.phase_machine import DesiredState
from ucontrol.scene import load_scene

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def _controller(name: str):  # type: ignore[no-untyped-def]
    return load_scene(ROBOTS / f"{name}.toml").build_controller()


def _random_contacts(rng: np.random.Generator, names: list[str], dt: float = 1e-3) -> ContactState:
    """Impulses zero, positive or negative and normal velocities around -IMPACT_SPEED."""
    n = len(names)
    impulse = rng.choice([0.0, 1.0, -1e-3], n) * rng.uniform(0.0, 1e-2, n)  # [N s]
    normal_velocity = -IMPACT_SPEED * rng.choice([0.0, 0.5, 1.0, 2.0], n)  # [m/s]
    return ContactState(names, np.zeros(n), normal_velocity, impulse, impulse > 0.0, dt)


@pytest.mark.parametrize("shape", [(3, 9), (2, 2), (3, 7), (6, 4)])
@pytest.mark.parametrize("rank_deficit", [0, 1])
def test_pseudo_inverse_is_numpys(
    rng: np.random.Generator, shape: tuple[int, int], rank_deficit: int
) -> None:
    rank = min(shape) - rank_deficit
    for _ in range(20):
        A = rng.standard_normal((shape[0], rank)) @ rng.standard_normal((rank, shape[1]))
        for rcond in (1e-10, 1e-15, 0.3):
            expected = np.linalg.pinv(A, rcond=rcond)
            assert np.array_equal(_pseudo_inverse(A, rcond), expected)


def test_brogliato_measurement_matches_array_reference(rng: np.random.Generator) -> None:
    """Forces impulse/dt, closed > 0, persistent = closed and settled at the last call."""
    law = _controller("two_link_two_constraints")
    declared = list(law.machine.contacts)
    names = ["stop_a", declared[1], "stop_b", declared[0]]  # the plant's order differs
    index = np.array([names.index(name) for name in declared])
    settled = np.zeros(len(declared), dtype=bool)
    for k in range(200):
        contacts = _random_contacts(rng, names, dt=rng.uniform(1e-4, 2e-3))
        closed = law._measure(1e-3 * k, contacts)
        force = contacts.impulse[index] / contacts.dt  # [N]
        expected_closed = force > 0.0
        assert np.array_equal(law.contact_force, force)
        assert np.array_equal(closed, expected_closed)
        assert np.array_equal(law._persistent, expected_closed & settled)
        settled = expected_closed & (contacts.normal_velocity[index] >= -IMPACT_SPEED)
        assert np.array_equal(law._settled, settled)


def test_flexible_force_input_matches_array_reference(rng: np.random.Generator) -> None:
    """The law's force input: -λ_d + K_f (λ - λ_d) (3, n) and λ (2, n), as arrays."""
    law = _controller("two_link_flexible_two_constraints")
    n = len(law.machine.contacts)
    q = np.array([1.5, -0.9])
    law._state_input[0][...] = q
    base = law.machine.desired(0.0)
    for _ in range(50):
        constrained = rng.random(n) < 0.7
        lambda_d = np.where(constrained, rng.uniform(0.0, 5.0, (3, n)), 0.0)  # [N], [N/s], ...
        desired = DesiredState(
            target=base.target,
            reference=base.reference,
            force=lambda_d[0],
            constrained=constrained,
            force_derivatives=(lambda_d[1], lambda_d[2]),
        )
        law.contact_force[...] = rng.uniform(0.0, 5.0, n)
        law._persistent[...] = rng.random(n) < 0.5
        law._evaluate(0.0, q, desired)
        if not constrained.any():
            assert np.array_equal(law._model_force_input, np.zeros(5 * n))
            continue
        lambda_m = lambda_d.copy()
        measured = constrained & law._persistent
        lambda_m[0, measured] = law.contact_force[measured]
        term = -lambda_d + law.gains.force_gain * (lambda_m - lambda_d)
        expected = np.concatenate([term.ravel(), lambda_m[:2].ravel()])
        assert np.array_equal(law._model_force_input, expected)


@pytest.mark.parametrize(
    "scene",
    [
        "two_link_one_constraint",
        "two_link_flexible_one_constraint",
        "two_link_one_constraint_impedance",
    ],
)
def test_torque_is_not_overwritten_by_the_next_call(scene: str) -> None:
    """The torque returned is held by the loop: no later call may write into it."""
    law = _controller(scene)
    if hasattr(law, "machine"):
        names = list(law.machine.contacts)
    else:
        names = [contact.name for contact in law.contacts]
    n, nq = len(names), (4 if "flexible" in scene else 2)
    q = np.array([0.9, -1.6, 0.9, -1.6][:nq])
    contacts = ContactState(names, np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n, bool), 1e-3)
    first = law(0.0, q, np.zeros(nq), contacts)
    kept = first.copy()
    law(0.5, q + 0.1, np.ones(nq), contacts)
    assert np.array_equal(first, kept)


def _desired_variants(  # type: ignore[no-untyped-def]
    rng: np.random.Generator, law, t: float, shared: dict
):
    """The machine's desired state at ``t`` with random forces and clipping, and its plain twin.

    The twin has separate target arrays (no ``stacked``), reference arrays that are not the
    target's, and a fresh ``constrained`` array: the law's general copies. ``shared`` holds
    the read-only flags reused between calls.
    """
    base = law.machine.desired(t)
    n = len(law.machine.contacts)
    constrained = rng.random(n) < 0.5
    if not constrained.any() and rng.random() < 0.5:
        constrained = law.machine.none_constrained
    elif rng.random() < 0.5:  # read-only flags shared between calls, as the machine's
        constrained = shared.setdefault(tuple(constrained.tolist()), constrained)
        constrained.flags.writeable = False
    force = np.where(constrained, rng.uniform(0.0, 5.0, n), 0.0)  # [N]
    derivatives = tuple(np.where(constrained, rng.uniform(-5.0, 5.0, n), 0.0) for _ in base[4])
    reference = base.reference
    if rng.random() < 0.3:  # a clipped reference: arrays of their own
        reference = (base.reference[0].copy(), base.reference[1].copy())
        reference[0][0] = reference[1][0] = 0.0
    fast = base._replace(
        reference=reference, force=force, constrained=constrained, force_derivatives=derivatives
    )
    plain = fast._replace(
        target=tuple(row.copy() for row in base.target),
        reference=(reference[0].copy(), reference[1].copy()),
        constrained=np.array(constrained),
        stacked=None,
    )
    return fast, plain


def _law_outputs(law) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The rigid law's outputs (tau, V1, V, X) of its last run, copied."""
    return np.concatenate([law._tau_output, law._V1_output, law._V_output, law._X_output])


@pytest.mark.parametrize("no_compile", ["0", "1"])  # compiled, and casadi's VM
@pytest.mark.parametrize("scene", ["two_link_two_constraints", "panda_table"])
def test_rigid_law_inputs_by_shortcut_match_the_plain_copies(
    rng: np.random.Generator, scene: str, no_compile: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stacked target, reference from the target, skipped force reset: same law outputs."""
    monkeypatch.setenv("UCONTROL_NO_COMPILE", no_compile)
    law = _controller(scene)
    names = list(law.machine.contacts)
    n, nq = len(names), law.robot.nq
    contacts = ContactState(names, np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n, bool), 1e-3)
    q = law.robot.neutral() if scene == "panda_table" else np.array([1.5, -0.9])
    law(0.0, q + 0.1 * rng.standard_normal(nq), rng.standard_normal(nq), contacts)
    shared: dict[tuple[bool, ...], np.ndarray] = {}
    for t in rng.uniform(0.0, 12.0, 60):
        law.contact_force[...] = rng.uniform(0.0, 5.0, n)
        law._persistent[...] = rng.random(n) < 0.5
        fast, plain = _desired_variants(rng, law, float(t), shared)
        law._evaluate_law(plain)
        expected = _law_outputs(law)
        law._target_buffer.fill(np.nan)  # nothing left from the plain call
        law._reference_buffer.fill(np.nan)
        law._evaluate_law(fast)
        assert np.array_equal(_law_outputs(law), expected)
        # After a held contact, a free state resets the force term: as the plain path does.
        free = fast._replace(constrained=law.machine.none_constrained)
        law._evaluate_law(free._replace(constrained=np.zeros(n, bool)))
        expected = _law_outputs(law)
        law._evaluate_law(fast)
        law._evaluate_law(free)
        assert np.array_equal(_law_outputs(law), expected)


def test_flexible_law_inputs_by_shortcut_match_the_plain_copies(rng: np.random.Generator) -> None:
    law = _controller("two_link_flexible_two_constraints")
    n = len(law.machine.contacts)
    q = np.array([1.5, -0.9])
    law._state_input[0][...] = q
    shared: dict[tuple[bool, ...], np.ndarray] = {}
    for t in rng.uniform(0.0, 0.5, 60):  # targets Newton reaches from q (no call made)
        law.contact_force[...] = rng.uniform(0.0, 5.0, n)
        law._persistent[...] = rng.random(n) < 0.5
        fast, plain = _desired_variants(rng, law, float(t), shared)
        V1 = law._evaluate(float(t), q, plain)
        expected = (law._law_output.copy(), _flexible_law_inputs(law))
        law._reference_input.fill(np.nan)  # nothing left from the plain call
        assert law._evaluate(float(t), q, fast) == V1
        assert np.array_equal(law._law_output, expected[0])
        assert np.array_equal(_flexible_law_inputs(law), expected[1])


def _flexible_law_inputs(law) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Every input of the flexible law (named), copied and stacked."""
    function = law._law.function
    return np.concatenate([law._law.input_buffer(i).copy() for i in range(function.n_in())])


class _RecordChecker:
    """The scene's controller, each of its log rows checked against the plain values."""

    def __init__(self, law) -> None:  # type: ignore[no-untyped-def]
        self.law, self.rows, self.events = law, 0, 0

    def __call__(self, t, q, v, contacts):  # type: ignore[no-untyped-def]
        return self.law(t, q, v, contacts)

    def prepare_log(self, log) -> None:  # type: ignore[no-untyped-def]
        self.law.prepare_log(log)

    def record(self, log) -> None:  # type: ignore[no-untyped-def]
        law = self.law
        machine, desired = law.machine, law.desired
        expected = {
            "phase": machine.phase.value,
            "contact_phase": np.array(machine.phases),
            "events": machine.events.copy(),
            "V": law.V,
            "V1": law.V1,
            "virtual_depth": machine.depth.copy(),
            "task_position": law.X.copy(),
            "task_desired": desired.reference[0].copy(),
            "task_target": desired.target[0].copy(),
            "lambda_d": desired.force.copy(),
            "contact_force": law.contact_force.copy(),
        }
        if hasattr(law, "flexible"):
            expected["motor_desired"] = law.motor_desired[0]
            expected["link_desired"] = law.link_desired[0]
        law.record(log)
        k = len(log)
        for name, value in expected.items():
            assert np.array_equal(log.extra_fields([name])[0][k], value), name
        assert not machine.events.any()  # logged once
        self.rows += 1
        self.events += int(expected["events"].any())


@pytest.mark.parametrize("scene", ["two_link_two_constraints", "two_link_flexible_one_constraint"])
def test_recorded_fields_are_the_plain_values(scene: str) -> None:
    import ucontrol

    checker = _RecordChecker(_controller(scene))
    ucontrol.simulate(
        load_scene(ROBOTS / f"{scene}.toml"), controller=checker, duration=6.0, progress=False
    )
    assert checker.rows == 6001 and checker.events >= 3  # τ0, first impact, t_f at least


def test_taylor_start_is_the_product_with_the_coefficients_tuple(
    rng: np.random.Generator,
) -> None:
    law = _controller("two_link_flexible_one_constraint")
    for _ in range(400):  # steps seen again (kept coefficients) and new ones (> the cache)
        law._link_rows = rng.standard_normal((5, law.robot.nv)) * 10.0 ** rng.integers(-3, 3)
        dt = float(rng.choice([0.0, 1e-3, 2e-3, rng.uniform(0.0, 0.1)]))  # [s]
        law._taylor_start(dt)
        expected = np.dot((1.0, dt, dt * dt / 2, dt**3 / 6, dt**4 / 24), law._link_rows)
        assert np.array_equal(law._newton_q, expected)
        assert len(law._taylor) <= TAYLOR_CACHE_SIZE


def test_posture_error_by_subtraction_is_pinocchios_difference(
    rng: np.random.Generator,
) -> None:
    import pinocchio as pin

    law = _controller("panda_table")
    assert law._posture_by_subtraction
    model = law.robot.model
    for _ in range(200):
        q = pin.randomConfiguration(model) * rng.uniform(0.5, 2.0)
        assert np.array_equal(q - law.posture, pin.difference(model, law.posture, q))
    assert not _controller("two_link_one_constraint")._posture_by_subtraction  # square task


def test_flexible_force_rates_reused_only_for_the_shared_plateau(
    rng: np.random.Generator,
) -> None:
    """The cached force-term rows of λ_d's derivatives: same input as computing them anew.

    ``law`` keeps its cache from call to call; ``anew`` is reset (its cache emptied) before
    each evaluation. No call is made, so Newton starts from q in both.
    """
    law = _controller("two_link_flexible_two_constraints")
    anew = _controller("two_link_flexible_two_constraints")
    n, q = len(law.machine.contacts), np.array([1.5, -0.9])
    base = law.machine.desired(0.0)
    plateau = tuple(_read_only(rng.uniform(-5.0, 5.0, n)) for _ in range(2))

    def both_inputs(desired, force, persistent):  # type: ignore[no-untyped-def]
        anew.reset()
        for controller in (law, anew):
            controller.contact_force[...], controller._persistent[...] = force, persistent
            controller._state_input[0][...] = q
            controller._evaluate(0.0, q, desired)
        return law._model_force_input.copy(), anew._model_force_input.copy()

    for _ in range(60):
        writable = tuple(rng.uniform(-5.0, 5.0, n) for _ in range(2))
        rates = plateau if rng.random() < 0.6 else writable
        desired = base._replace(
            force=rng.uniform(0.0, 5.0, n),
            constrained=np.ones(n, bool),
            force_derivatives=rates,
        )
        force, persistent = rng.uniform(0.0, 5.0, n), rng.random(n) < 0.5
        cached, computed = both_inputs(desired, force, persistent)
        assert np.array_equal(cached, computed)
        if rates is writable:  # never kept: its values may change
            writable[0][...] = rng.uniform(-5.0, 5.0, n)
            cached, computed = both_inputs(desired, force, persistent)
            assert np.array_equal(cached, computed)


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array
