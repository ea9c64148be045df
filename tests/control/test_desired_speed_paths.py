"""The phase machine's shortcuts give what its general code gives.

The circle's samples as one product of a constant table with (cos φ, sin φ), the early return
of ``update`` before its next due time, the values shared between calls (forces on their
plateau, the reference where nothing is clipped) and the segments' precomputed tables, each
against an independent reference: the analytic derivatives, the path seen only through its
``derivatives``, a machine that runs every check at every call, finite differences. The rigid
law's unrolled quintic blend and desired forces on Python floats are checked bitwise against
the general formulas, the cached phase values, constraint flags and event flag against what
they cache.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from conftest import ROBOTS
from numpy.polynomial import Polynomial

from ucontrol.control import CirclePath, Phase, PhaseMachine
from ucontrol.control.trajectory_segment import (
    BlendToNominal,
    Parabola,
    RestCubic,
    _derivative_table,
    _polynomial_sample,
    smooth_step,
)
from ucontrol.scene import load_scene


def _scene_machine(name: str, order: int = 2, **cycle_changes: Any) -> PhaseMachine:
    controller: Any = load_scene(ROBOTS / f"{name}.toml").build_controller()
    cycle = dataclasses.replace(controller.cycle, **cycle_changes)
    return PhaseMachine(controller.task, cycle, order=order)


class _AlwaysChecking(PhaseMachine):
    """A machine whose ``update`` runs every check at every call (never returns early)."""

    def _schedule(self) -> None:
        super()._schedule()
        self._due = -math.inf


@dataclasses.dataclass(frozen=True)
class _SeenThroughDerivatives:
    """A circle seen only through the nominal path protocol: the machine's general branch."""

    circle: CirclePath

    @property
    def period(self) -> float:
        return self.circle.period

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.circle(t)

    def derivatives(self, t: float, order: int) -> tuple[np.ndarray, ...]:
        return self.circle.derivatives(t, order)


def _closures(rng: np.random.Generator, machine: PhaseMachine, t: float) -> np.ndarray:
    """Random contact closures: bounces while transiting, mostly closed when held."""
    closed = []
    for i, phase in enumerate(machine.phases):
        if phase in (Phase.APPROACH, Phase.TRANSITION):
            closed.append(t > machine.approach_time(i) + 0.5 and rng.random() < 0.8)
        else:
            closed.append(phase is Phase.CONSTRAINED and rng.random() < 0.95)
    return np.array(closed)


def _fields(desired: Any) -> list[np.ndarray]:
    return [*desired.target, *desired.reference, desired.force, *desired.force_derivatives]


def test_circle_table_gives_the_analytic_derivatives(rng: np.random.Generator) -> None:
    for _ in range(20):
        u, w = np.linalg.qr(rng.normal(size=(3, 2)))[0].T
        circle = CirclePath(
            centre=rng.normal(size=3),
            radius=rng.uniform(0.05, 1.0),
            period=rng.uniform(0.5, 20.0),
            axes=np.array([u, w]),
            start_angle=rng.uniform(-3.0, 3.0),
        )
        omega = 2.0 * math.pi / circle.period
        for t in rng.uniform(0.0, 30.0, 5):
            coefficients = circle.plane_coefficients(t, 5)
            angle = circle.start_angle + omega * t
            for k in range(6):
                expected = (
                    circle.radius
                    * omega**k
                    * np.array(
                        [math.cos(angle + k * math.pi / 2), math.sin(angle + k * math.pi / 2)]
                    )
                )
                # Measured: 2.6e-14 relative (the rounding of angle + k π/2 in the reference,
                # |angle| up to 380 rad).
                scale = circle.radius * omega**k
                np.testing.assert_allclose(coefficients[k], expected, atol=2e-13 * scale)


@pytest.mark.parametrize("order", [2, 4])
def test_planar_table_equals_the_path_derivatives_on_a_tilted_circle(
    rng: np.random.Generator, order: int
) -> None:
    # Axes out of the task's plane: the table's entries are not 0 or ±1, so the two branches
    # round differently, by a few ulps of each derivative's scale r ω^k.
    reference_machine = _scene_machine("two_link_one_constraint", order)
    circle = reference_machine.cycle.path
    tilt = 0.3  # [rad] about the y axis: x shrinks by cos(tilt), z appears
    tilted = dataclasses.replace(
        circle, axes=np.array([[math.cos(tilt), 0.0, math.sin(tilt)], [0.0, 1.0, 0.0]])
    )
    table = _scene_machine("two_link_one_constraint", order, path=tilted)
    general = _scene_machine("two_link_one_constraint", order, path=_SeenThroughDerivatives(tilted))
    error, size = np.zeros(order + 1), np.zeros(order + 1)  # per derivative over the run
    for t in np.arange(0.0, 12.0, 2e-3):
        closed = _closures(rng, table, t)
        V1 = float(rng.uniform(0.0, 1e-3))
        for machine in (table, general):
            machine.update(t, closed, V1, machine.desired(t))
        assert table.phases == general.phases
        a, b = table.desired(t), general.desired(t)
        for k in range(order + 1):
            error[k] = max(error[k], float(np.max(np.abs(a.target[k] - b.target[k]))))
            size[k] = max(size[k], float(np.max(np.abs(a.target[k]))))
        np.testing.assert_array_equal(a.force, b.force)
    assert np.all(error <= 1e-14 * size)  # measured: 1.5e-15 (order 2), 1.3e-15 (order 4)


@pytest.mark.slow
@pytest.mark.parametrize("opening", [False, True])  # the takeoff rule watches held contacts
@pytest.mark.parametrize("order", [2, 4])
@pytest.mark.parametrize("scene", ["two_link_one_constraint", "two_link_two_constraints"])
def test_update_returning_early_changes_nothing(
    rng: np.random.Generator, scene: str, order: int, opening: bool
) -> None:
    fast = _scene_machine(scene, order, takeoff_on_opening=opening)
    checking = _AlwaysChecking(fast.task, fast.cycle, order=order)
    t, events = 0.0, 0
    while t < 1.2 * fast.cycle.period:
        closed = _closures(rng, fast, t)
        V1 = float(rng.uniform(0.0, 1e-3))
        first, second = fast.desired(t), checking.desired(t)
        assert all(map(np.array_equal, _fields(first), _fields(second)))
        happened = fast.update(t, closed, V1, first)
        assert checking.update(t, closed, V1, second) == happened
        assert fast.phases == checking.phases and fast.phase == checking.phase
        assert np.array_equal(fast.take_events(), checking.take_events())
        assert np.array_equal(fast.depth, checking.depth)
        events += happened
        t += float(rng.choice([0.0, 5e-4, 1e-3, 3e-3]))  # repeated times too
    assert events >= 4 * len(fast.contacts)  # τ0, first impact, t_f and t_d of each contact


def test_shared_values_are_read_only_and_targets_fresh() -> None:
    machine = _scene_machine("two_link_one_constraint")
    gap = int(machine.coordinates[0])
    phase = machine.cycle.contact_phases[0]
    clipped = False
    for t in np.arange(0.0, 9.9, 1e-3):
        closed = np.array([machine.phases[0] is not Phase.FREE and t > 4.9])
        machine.update(t, closed, 1e-4, machine.desired(t))
        first, second = machine.desired(t), machine.desired(t)
        assert first.target[0] is not second.target[0]  # fresh trajectory per call
        if machine.phases[0] in (Phase.APPROACH, Phase.TRANSITION) and first.target[0][gap] < 0:
            clipped = True
            assert first.reference[0][gap] == first.reference[1][gap] == 0.0
            assert first.reference[0] is not first.target[0]
        else:
            assert first.reference[0] is first.target[0]
        if machine.phases[0] is Phase.CONSTRAINED:
            t_d = machine.takeoff_time(0)
            assert first.force[0] == machine.cycle.desired_force(phase, t, t_d)
            if t < t_d - machine.cycle.force_fall_time - 1e-6:  # on the plateau
                assert first.force is second.force and first.force[0] == phase.force
                with pytest.raises(ValueError, match="read-only"):
                    first.force[0] = 0.0
    assert clipped and machine.phases == [Phase.CONSTRAINED]


def test_polynomial_tables_evaluate_the_derivatives(rng: np.random.Generator) -> None:
    for degree in (0, 3, 9):
        coefficients = rng.normal(size=degree + 1)
        table = _derivative_table(coefficients)
        assert len(table) == degree + 1
        duration = float(rng.uniform(0.2, 3.0))
        for sigma in rng.uniform(0.0, 1.0, 4):
            values = _polynomial_sample(table, sigma, degree + 3, duration)
            expected = [
                Polynomial(coefficients).deriv(k)(sigma) / duration**k for k in range(degree + 3)
            ]
            # Measured: 4.4e-16 relative to max(1, |value|).
            scale = [max(1.0, abs(e)) for e in expected]
            np.testing.assert_allclose(
                np.divide(values, scale), np.divide(expected, scale), atol=5e-15
            )


def test_rest_cubic_jerk_is_the_derivative_of_its_acceleration(rng: np.random.Generator) -> None:
    segment = RestCubic(t0=1.0, p0=0.03, v0=-0.06, p1=-0.01, duration=0.8)
    h = 1e-4
    for t in rng.uniform(1.05, 1.75, 5):
        acceleration = lambda x: segment(x, (0.0,) * 4)[2]  # noqa: E731
        central = (acceleration(t + h) - acceleration(t - h)) / (2 * h)
        # The acceleration is linear: the central difference is exact up to round-off
        # (measured 1.0e-12 relative).
        assert segment(t, (0.0,) * 4)[3] == pytest.approx(central, rel=1e-11)
    assert segment(2.0, (0.0,) * 4) == (-0.01, 0.0, 0.0, 0.0)


def _general_blend(segment: BlendToNominal, t: float, nominal: tuple[float, ...]) -> tuple:
    """Leibniz's rule of BlendToNominal written for any order (the plain reference)."""
    T = segment.duration
    sigma = (t - segment.t0) / T
    if sigma >= 1.0:
        return nominal
    order = len(nominal) - 1
    beta = smooth_step(sigma, order, segment.continuity)
    rates = [beta[0]] + [beta[i] / math.prod([T] * i) for i in range(1, order + 1)]
    base = segment.base(t, nominal)
    error = [n - b for n, b in zip(nominal, base, strict=True)]
    blended = []
    for k in range(order + 1):
        value = base[k]
        for i in range(k + 1):
            value += float(math.comb(k, i)) * rates[i] * error[k - i]
        blended.append(value)
    return tuple(blended)


def test_quintic_blend_is_the_general_leibniz_rule(rng: np.random.Generator) -> None:
    for _ in range(200):
        t0, duration = float(rng.uniform(0.0, 10.0)), float(rng.uniform(0.1, 2.0))
        base = (
            RestCubic(t0, *rng.normal(size=3).tolist(), float(rng.uniform(0.1, 1.0)))
            if rng.random() < 0.5
            else Parabola(t0, float(rng.uniform(0.1, 5.0)))
        )
        segment = BlendToNominal(base, t0, duration)
        nominal = tuple(rng.normal(size=3).tolist())
        for t in (t0 - 0.1, t0, *rng.uniform(t0, t0 + duration, 5), t0 + duration):
            assert segment(t, nominal) == _general_blend(segment, t, nominal)


def test_smooth_step_value_alone_is_the_first_of_its_derivatives(
    rng: np.random.Generator,
) -> None:
    for sigma in (-0.5, 0.0, *rng.uniform(0.0, 1.0, 200), 1.0, 1.5):
        assert smooth_step(sigma, 0) == smooth_step(sigma, 5)[:1]


def _run_machine(
    rng: np.random.Generator, machine: PhaseMachine, duration: float
) -> Iterator[float]:
    """Yield the machine after each update of a run with random closures."""
    for t in np.arange(0.0, duration, 2e-3):
        closed = _closures(rng, machine, float(t))
        machine.update(float(t), closed, float(rng.uniform(0.0, 1e-3)), machine.desired(float(t)))
        yield float(t)


@pytest.mark.parametrize("scene", ["two_link_one_constraint", "two_link_two_constraints"])
def test_rigid_forces_are_the_cycle_desired_forces(rng: np.random.Generator, scene: str) -> None:
    machine = _scene_machine(scene)
    checked = 0
    for t in _run_machine(rng, machine, 11.0):
        if not machine._held:
            continue
        force, derivatives = machine._forces(t)
        expected = np.zeros(len(machine.contacts))
        for i, phase, t_d in machine._held:
            expected[i] = machine.cycle.desired_force_derivatives(phase, t, t_d, 0)[0]
        assert np.array_equal(force, expected) and derivatives == ()
        checked += 1
    assert checked > 100


@pytest.mark.parametrize("order", [2, 4])
def test_cached_phase_values_constraint_flags_and_events(
    rng: np.random.Generator, order: int
) -> None:
    machine = _scene_machine("two_link_two_constraints", order)
    pending_seen = 0
    for t in _run_machine(rng, machine, 12.0):
        assert machine.phase_value == machine.phase.value
        assert machine.phase_values.tolist() == [int(phase) for phase in machine.phases]
        desired = machine.desired(t)
        held = [phase is Phase.CONSTRAINED for phase in machine.phases]
        assert desired.constrained.tolist() == held
        assert (desired.constrained is machine.none_constrained) == (not any(held))
        assert not machine.none_constrained.any()
        assert machine.events_pending == bool(machine.events.any())
        if machine.events_pending and rng.random() < 0.5:
            pending_seen += 1
            machine.take_events()
            assert not machine.events_pending
    assert pending_seen > 0


@pytest.mark.parametrize("order", [2, 4])
@pytest.mark.parametrize("scene", ["two_link_one_constraint", "panda_table"])
def test_stacked_target_and_circle_angle(rng: np.random.Generator, scene: str, order: int) -> None:
    machine = _scene_machine(scene, order)
    free = _scene_machine(scene, order)
    path, table, offset = machine._plane
    m = machine.task.m
    for t in _run_machine(rng, machine, 11.0 if scene.startswith("two_link") else 4.5):
        desired = machine.desired(t)
        stacked = desired.stacked
        assert stacked is not None and stacked.shape == ((order + 1) * m,)
        for k, row in enumerate(desired.target):  # views of the stacked samples
            assert np.shares_memory(row, stacked)
            assert np.array_equal(row, stacked[k * m : (k + 1) * m])
        angle = path.angle(t)  # the nominal samples with the path's own angle
        expected = np.dot(table, np.array([math.cos(angle), math.sin(angle)]))
        expected[:m] += offset
        assert np.array_equal(machine._nominal(t), expected)
        # A machine that stays free samples the nominal path itself: the inlined circle.
        nominal = free.desired(t).stacked
        assert nominal is not None
        assert np.array_equal(nominal.view(np.uint64), expected.view(np.uint64))  # signed zeros


@pytest.mark.parametrize("order", [2, 4])
def test_constant_segment_samples_computed_once(rng: np.random.Generator, order: int) -> None:
    machine = _scene_machine("two_link_two_constraints", order)
    constant_seen = 0
    for t in _run_machine(rng, machine, 12.0):
        desired = machine.desired(t)
        nominal = machine._nominal(t)
        m = machine.task.m
        for j, segment in enumerate(machine._segments):
            column = nominal[j::m]
            expected = segment(t, tuple(column.tolist()))
            assert desired.stacked[j::m].tolist() == list(expected)
            constant_seen += type(segment).__name__ == "Constant"
    assert constant_seen > 100


def test_rest_cubic_rigid_sample_is_the_padded_one(rng: np.random.Generator) -> None:
    for _ in range(100):
        p0, v0, p1 = rng.normal(size=3).tolist()
        segment = RestCubic(t0=1.0, p0=p0, v0=v0, p1=p1, duration=float(rng.uniform(0.1, 1.0)))
        for t in (0.5, *rng.uniform(1.0, 2.2, 5)):
            assert segment(t, (0.0,) * 3) == segment(t, (0.0,) * 5)[:3]


def test_blind_segments_read_only_the_sample_length(rng: np.random.Generator) -> None:
    """The machine hands these segments zeros instead of the nominal sample."""
    from ucontrol.control.phase_machine import _BLIND_SEGMENTS
    from ucontrol.control.trajectory_segment import Constant, RestHermite, SmoothParabola

    for _ in range(50):
        t0, duration = float(rng.uniform(0.0, 5.0)), float(rng.uniform(0.1, 1.0))
        for size in (3, 5):
            segments = [
                RestCubic(t0, *rng.normal(size=3).tolist(), duration),
                RestHermite(t0, tuple(rng.normal(size=size).tolist()), 0.1, duration),
                Parabola(t0, float(rng.uniform(0.1, 2.0))),
                SmoothParabola(t0, float(rng.uniform(0.1, 2.0)), duration, size - 3),
                Constant(float(rng.normal())),
            ]
            assert {type(segment) for segment in segments} == _BLIND_SEGMENTS
            for segment in segments:
                for t in rng.uniform(t0 - 0.5, t0 + 1.5, 4):
                    nominal = tuple(rng.normal(size=size).tolist())
                    assert segment(t, nominal) == segment(t, (0.0,) * size)


def test_rest_cubic_is_the_plain_hermite_cubic(rng: np.random.Generator) -> None:
    for _ in range(100):
        p0, v0, p1 = rng.normal(size=3).tolist()
        T = float(rng.uniform(0.1, 1.0))
        segment = RestCubic(t0=1.0, p0=p0, v0=v0, p1=p1, duration=T)
        for t in (0.5, 1.0, *rng.uniform(1.0, 1.0 + T, 5)):
            sigma = max((t - 1.0) / T, 0.0)
            s2, s3, drop = sigma * sigma, sigma * sigma * sigma, p0 - p1
            expected = (
                (2 * s3 - 3 * s2 + 1) * p0
                + (s3 - 2 * s2 + sigma) * T * v0
                + (3 * s2 - 2 * s3) * p1,
                (6 * s2 - 6 * sigma) * drop / T + (3 * s2 - 4 * sigma + 1) * v0,
                (12 * sigma - 6) * drop / T**2 + (6 * sigma - 4) * v0 / T,
            )
            assert segment(t, (0.0,) * 3) == expected
