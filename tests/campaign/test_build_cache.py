"""Campaign workers reuse integrators and controllers: fresh builds' logs, rebuilt on need."""

from __future__ import annotations

import threading
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ucontrol.campaign.build_cache import (
    CONTROLLER,
    INTEGRATOR,
    BuildCache,
    controller_family,
    controller_key,
    integrator_family,
    integrator_key,
)
from ucontrol.campaign.overrides import apply_overrides
from ucontrol.campaign.runner import prepare_worker, run_task, simulate_cached
from ucontrol.exceptions import InvalidParameterError
from ucontrol.log import Log
from ucontrol.scene import Scene, builtin_scene
from ucontrol.simulate import simulate

#: Sensors on every run (noise drawn from the run's seed), so that their reset is tested too.
NOISE = {"sensors.position_noise": 1e-4, "sensors.delay": 1}


def _table(name: str, duration: float) -> tuple[dict[str, Any], Path]:
    path = builtin_scene(name)
    table = tomllib.loads(path.read_text())
    table["duration"] = duration
    return table, path


def _fresh(table: dict[str, Any], path: Path) -> Log:
    scene = Scene.from_dict(table, base_dir=path.parent, default_name=path.stem)
    return simulate(scene, progress=False).log


def _assert_same_log(reused: Log, fresh: Log) -> None:
    assert reused.fields == fresh.fields
    assert len(reused) == len(fresh)
    for name in set(fresh.fields) - {"solver_time"}:  # (a timing: never equal)
        a, b = getattr(reused, name), getattr(fresh, name)
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
    assert np.array_equal(reused.impacts.t, fresh.impacts.t)
    assert list(reused.impacts.constraint) == list(fresh.impacts.constraint)


# Each case: overrides of the run, then how its integrator and controller are expected to come.
TWO_LINK_RUNS = [
    ({**NOISE, "sensors.seed": 1}, "built", "built"),
    ({**NOISE, "sensors.seed": 2}, "reused", "reused"),  # sensors only: nothing rebuilt
    ({**NOISE, "sensors.seed": 2, "controller.gamma1": 9.0}, "reused", "built"),
    ({**NOISE, "sensors.seed": 3, "contacts.0.restitution": 0.3}, "reused", "reused"),
    ({**NOISE, "sensors.seed": 1, "actuators.torque_limit": "urdf"}, "reused", "reused"),
    ({"controller.gamma1": 9.0}, "reused", "reused"),  # back to earlier builds
]


@pytest.mark.parametrize(
    ("scene", "duration", "runs"),
    [
        ("two_link_one_constraint", 6.0, TWO_LINK_RUNS),
        (
            "two_link_one_constraint_impedance",
            6.0,
            [
                ({**NOISE, "sensors.seed": 1}, "built", "built"),
                ({**NOISE, "sensors.seed": 2}, "reused", "reused"),
                ({"controller.stiffness": 300.0}, "reused", "built"),
            ],
        ),
        (
            "panda_landing_rs",
            3.0,
            [
                ({}, "built", "built"),
                ({"duration": 2.5}, "reused", "reused"),
            ],
        ),
        (  # four feet held on the ground: the active-set start and its QP's warm starts
            "quadruped_stand",
            1.0,
            [
                ({}, "built", "built"),
                ({"duration": 0.8}, "reused", "built"),  # (a joint PD: built again)
                ({}, "reused", "built"),
            ],
        ),
        (
            "panda_table",
            4.0,
            [
                ({"controller.mass_scale": 1.1}, "built", "built"),
                ({"controller.mass_scale": 1.1, "duration": 3.5}, "reused", "reused"),
                ({"controller.mass_scale": 0.9}, "reused", "reused"),  # its inertias given
                # a surface the controller believes too: its controller built, the other kept
                ({"surfaces.table.point.2": 0.198}, "reused", "built"),
                # after a run whose controller shared the plant's data (its own model), one
                # whose controller does not: the integrator's evaluations as a fresh one's
                ({"controller.mass_scale": 1.1}, "reused", "reused"),
            ],
        ),
    ],
)
def test_reused_builds_give_the_logs_of_fresh_ones(
    scene: str, duration: float, runs: list[tuple[dict[str, Any], str, str]]
) -> None:
    base, path = _table(scene, duration)
    cache = BuildCache()
    impacts = 0
    for overrides, integrator, controller in runs:
        table = apply_overrides(base, overrides)
        result, build = simulate_cached(table, path, cache)
        assert build == {INTEGRATOR: integrator, CONTROLLER: controller}, overrides
        _assert_same_log(result.log, _fresh(table, path))
        impacts += len(result.log.impacts.t)
    assert impacts > 0  # the runs go through the contact phases the resets must forget
    stats = cache.stats()
    assert stats.reused[INTEGRATOR] == sum(run[1] == "reused" for run in runs)
    assert stats.built[CONTROLLER] == sum(run[2] == "built" for run in runs)


#: (scene, duration, draws): runs on one cache, the first as the scene is, then each draw of
#: the numbers of its constraints (restitutions, friction coefficients, planes, stop bounds).
NUMBER_DRAWS = [
    ("two_link_one_constraint", 6.0, [
        {"contacts.0.restitution": 0.35, "surfaces.ground.point.1": -3e-3, "stops.1.upper": -0.01},
        {"contacts.0.restitution": 0.9},
    ]),
    ("panda_table", 2.0, [{"contacts.0.restitution": 0.9, "surfaces.table.point.2": 0.197}]),
    ("panda_table_friction", 2.5, [
        {"contacts.0.friction": 0.15, "surfaces.table.normal": [0.02, 0.0, 1.0]},
    ]),
    ("solo_landing", 0.6, [{"contacts.2.friction": 0.4, "surfaces.ground.point.2": -2e-3}]),
    ("compass_walker", 2.0, [{"contacts.0.friction": 5.0, "contacts.1.friction": 5.0}]),
]  # fmt: skip


@pytest.mark.parametrize(("scene", "duration", "draws"), NUMBER_DRAWS)
def test_an_integrator_takes_drawn_numbers_with_the_logs_of_a_fresh_build(
    scene: str, duration: float, draws: list[dict[str, Any]]
) -> None:
    base, path = _table(scene, duration)
    cache = BuildCache()
    result, build = simulate_cached(base, path, cache)
    assert build[INTEGRATOR] == "built"
    for overrides in draws:
        table = apply_overrides(base, overrides)
        result, build = simulate_cached(table, path, cache)
        assert build[INTEGRATOR] == "reused", overrides  # no rebuild for numbers
        _assert_same_log(result.log, _fresh(table, path))
        assert len(result.log.impacts.t) > 0, overrides
    assert cache.stats().built[INTEGRATOR] == 1


def test_run_task_records_how_it_got_its_objects() -> None:
    table, path = _table("two_link_one_constraint", 0.5)
    task = {
        "run_id": "r0",
        "index": 0,
        "scene": table,
        "scene_ref": {"path": str(path)},
        "parameters": {"controller.gamma2": 6.5},
        "metrics": [("max_penetration", "max_penetration")],
        "success": None,
    }
    first, second = run_task(task), run_task(task)
    fresh = run_task({**task, "reuse": False})
    assert first["status"] == second["status"] == fresh["status"] == "ok"
    assert second["build"] == {INTEGRATOR: "reused", CONTROLLER: "reused"}
    assert fresh["build"] == {INTEGRATOR: "built", CONTROLLER: "built"}
    assert first["metrics"] == second["metrics"] == fresh["metrics"]


def _task(table: dict[str, Any], path: Path, parameters: dict[str, Any]) -> dict[str, Any]:
    return {
        "run_id": "r0",
        "index": 0,
        "scene": table,
        "scene_ref": {"path": str(path)},
        "parameters": parameters,
        "metrics": [("max_penetration", "max_penetration")],
        "success": None,
    }


def test_a_prepared_worker_reuses_its_builds_with_the_logs_of_fresh_ones() -> None:
    base, path = _table("two_link_one_constraint", 6.0)
    first = {**NOISE, "sensors.seed": 1}
    cache = BuildCache()
    assert prepare_worker(_task(base, path, first), cache) == ""
    for overrides, build in [
        ({**NOISE, "sensors.seed": 2}, "reused"),  # the prepared objects, never run before
        ({**NOISE, "sensors.seed": 3, "contacts.0.restitution": 0.2}, "reused"),
    ]:
        table = apply_overrides(base, overrides)
        result, how = simulate_cached(table, path, cache)
        assert how == {INTEGRATOR: build, CONTROLLER: build}, overrides
        _assert_same_log(result.log, _fresh(table, path))
        assert len(result.log.impacts.t) > 0
    unkept = BuildCache()  # without reuse the builds are made (libraries loaded) and dropped
    assert prepare_worker({**_task(base, path, first), "reuse": False}, unkept) == ""
    _, how = simulate_cached(apply_overrides(base, first), path, unkept)
    assert how == {INTEGRATOR: "built", CONTROLLER: "built"}


def test_a_worker_prepared_for_a_failing_run_leaves_the_error_to_the_run() -> None:
    table, path = _table("two_link_one_constraint", 0.5)
    task = _task(table, path, {"controller.no_such_gain": 1.0})
    cache = BuildCache()
    said = prepare_worker(task, cache)  # never raises
    assert said.split(":")[0].endswith("Error") and "no_such_gain" in said
    assert cache.stats().built == {INTEGRATOR: 0, CONTROLLER: 0}
    record = run_task(task)
    assert record["status"] == "error" and "no_such_gain" in record["error"]


def test_keys_follow_what_each_builder_reads() -> None:
    table, path = _table("two_link_one_constraint", 1.0)
    where = str(path)
    for key in (integrator_key, controller_key):
        assert key(where, table) == key(where, apply_overrides(table, {"sensors.seed": 4}))
        assert key(where, table) == key(where, {**table, "duration": 2.0})
        assert key(where, table) != key("other.toml", table)
        assert key(where, table) != key(
            where, apply_overrides(table, {"contacts.0.restitution": 0.1})
        )
    gains = apply_overrides(table, {"controller.gamma1": 1.0})
    assert integrator_key(where, table) == integrator_key(where, gains)
    assert controller_key(where, table) != controller_key(where, gains)
    step = apply_overrides(table, {"integrator.theta": 0.6})
    assert integrator_key(where, table) != integrator_key(where, step)
    assert controller_key(where, table) == controller_key(where, step)


def test_families_leave_out_the_numbers_the_objects_take() -> None:
    table, path = _table("two_link_one_constraint", 1.0)
    where = str(path)
    numbers = {
        "contacts.0.restitution": 0.2,
        "surfaces.ground.point.1": -1e-3,
        "stops.0.lower": 0.1,
    }
    inertias = {"controller.model.mass_scale": 1.1, "controller.mass_scale": 0.9}
    drawn, believed = apply_overrides(table, numbers), apply_overrides(table, inertias)
    assert integrator_key(where, drawn) != integrator_key(where, table)
    assert integrator_family(where, drawn) == integrator_family(where, table)
    assert controller_family(where, drawn) == controller_family(where, table)
    assert controller_key(where, believed) != controller_key(where, table)
    assert controller_family(where, believed) == controller_family(where, table)
    assert integrator_family(where, believed) == integrator_family(where, table)
    assert table == _table("two_link_one_constraint", 1.0)[0]  # (not changed in place)
    for other in ({"contacts.0.radius": 0.01}, {"robot.q0": [0.8, -1.5]}, {"controller.gamma1": 1}):
        changed = apply_overrides(table, other)
        assert controller_family(where, changed) != controller_family(where, table), other
    step = apply_overrides(table, {"integrator.theta": 0.6})
    assert integrator_family(where, step) != integrator_family(where, table)


def test_an_object_of_the_family_is_adapted_or_put_back_unchanged() -> None:
    cache = BuildCache(capacity=3)
    cache.checkin(INTEGRATOR, "a1", "A1", "a")
    cache.checkin(INTEGRATOR, "a2", "A2", "a")
    tried: list[str] = []

    def refuse(built: str) -> bool:
        tried.append(built)
        return False

    assert cache.checkout(INTEGRATOR, "a3", "a", refuse) is None  # both tried, both back
    assert tried == ["A2", "A1"]  # the most recently used first
    assert cache.checkout(INTEGRATOR, "a1", "a", refuse) == "A1"  # its own key: as it is
    assert tried == ["A2", "A1"]
    assert cache.checkout(INTEGRATOR, "a3", "a", lambda built: True) == "A2"
    assert cache.checkout(INTEGRATOR, "a3", "a", lambda built: True) is None  # both lent
    cache.checkin(INTEGRATOR, "a3", "A2", "a")  # now the object of a3
    assert cache.checkout(INTEGRATOR, "a3", "a", refuse) == "A2"
    stats = cache.stats()
    assert stats.reused[INTEGRATOR] == 3 and stats.built[INTEGRATOR] == 2


def test_cache_is_bounded_and_lends_an_object_to_one_run_at_a_time() -> None:
    cache = BuildCache(capacity=2)
    for n in range(3):
        assert cache.checkout(INTEGRATOR, f"k{n}") is None
        cache.checkin(INTEGRATOR, f"k{n}", f"object {n}")
    assert cache.stats().evicted == {INTEGRATOR: 1, CONTROLLER: 0}
    assert cache.checkout(INTEGRATOR, "k0") is None  # the oldest went out
    taken: list[Any] = []
    threads = [
        threading.Thread(target=lambda: taken.append(cache.checkout(INTEGRATOR, "k2")))
        for _ in range(4)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(taken, key=str) == [None, None, None, "object 2"]
    stats = cache.stats()
    assert stats.reused[INTEGRATOR] == 1 and stats.built[INTEGRATOR] == 3 + 1 + 3
    cache.clear()
    assert cache.stats().built == {INTEGRATOR: 0, CONTROLLER: 0}


@pytest.mark.parametrize("capacity", [0, -1, 1.5])
def test_capacity_must_be_a_positive_whole_number(capacity: Any) -> None:
    with pytest.raises(InvalidParameterError, match="capacity"):
        BuildCache(capacity=capacity)
