"""Campaign files: parsing, typed errors before any run, deterministic plans."""

from __future__ import annotations

import itertools
import math
import socket

import numpy as np
import pytest

from ucontrol.campaign import (
    CampaignFileError,
    CriterionError,
    DistributionError,
    EmptyGridError,
    OutputDirectoryError,
    ParameterKeyError,
    SchedulerUnreachableError,
    UnknownMetricError,
    apply_overrides,
    load_campaign,
    wilson_interval,
)
from ucontrol.campaign.criterion import parse_criterion
from ucontrol.campaign.overrides import format_assignment, parse_assignment
from ucontrol.campaign.runner import connect, prepare_directory
from ucontrol.exceptions import UControlError

HEAD = """
[campaign]
scene = "ball.toml"
duration = 0.2
"""


def test_grid_is_the_cartesian_product_in_declaration_order(write_campaign):
    path = write_campaign(
        HEAD
        + """
        [grid]
        "contacts.0.restitution" = [0.2, 0.5, 0.8]
        "robot.q0.0" = [0.5, 0.7]
        "integrator.dt" = [1e-3, 5e-4]
        """
    )
    campaign = load_campaign(path)
    plan = campaign.plan()
    expected = list(itertools.product([0.2, 0.5, 0.8], [0.5, 0.7], [1e-3, 5e-4]))
    assert [tuple(run.parameters.values()) for run in plan] == expected
    assert [run.run_id for run in plan] == [f"run-{i:05d}" for i in range(12)]
    assert campaign.size == 12


def test_same_seed_same_plan_and_draws_follow_their_laws(write_campaign):
    text = (
        HEAD.replace("duration = 0.2", "duration = 0.2\nseed = SEED\nruns = 4000")
        + """
        [distributions]
        "contacts.0.restitution" = { type = "uniform", low = 0.1, high = 0.9 }
        "robot.q0.0" = { type = "normal", mean = 1.0, std = 0.05 }
        "integrator.dt" = { type = "log-uniform", low = 1e-4, high = 1e-2 }
        "contacts.0.radius" = { type = "choice", values = [0.1, 0.2], weights = [3, 1] }
        """
    )
    first = load_campaign(write_campaign(text.replace("SEED", "7"), "a.toml"), check=False).plan()
    again = load_campaign(write_campaign(text.replace("SEED", "7"), "b.toml"), check=False).plan()
    other = load_campaign(write_campaign(text.replace("SEED", "8"), "c.toml"), check=False).plan()
    assert [r.parameters for r in first] == [r.parameters for r in again]
    assert [r.parameters for r in first] != [r.parameters for r in other]
    n = len(first)
    e = np.array([r.parameters["contacts.0.restitution"] for r in first])
    q = np.array([r.parameters["robot.q0.0"] for r in first])
    dt = np.array([r.parameters["integrator.dt"] for r in first])
    radius = np.array([r.parameters["contacts.0.radius"] for r in first])
    assert e.min() >= 0.1 and e.max() <= 0.9
    # sample means within 5 standard errors of the laws' means
    assert abs(e.mean() - 0.5) < 5 * (0.8 / math.sqrt(12)) / math.sqrt(n)
    assert abs(q.mean() - 1.0) < 5 * 0.05 / math.sqrt(n)
    assert abs(q.std() - 0.05) < 5 * 0.05 / math.sqrt(2 * n)
    log_dt = np.log(dt)  # uniform on [ln 1e-4, ln 1e-2]
    width = math.log(1e-2) - math.log(1e-4)
    assert abs(log_dt.mean() - math.log(1e-3)) < 5 * (width / math.sqrt(12)) / math.sqrt(n)
    share = np.mean(radius == 0.1)
    assert abs(share - 0.75) < 5 * math.sqrt(0.75 * 0.25 / n)
    # run k's draws depend on (seed, k) only: a longer campaign keeps the first runs
    longer = load_campaign(
        write_campaign(text.replace("SEED", "7").replace("4000", "4100"), "d.toml"), check=False
    ).plan()
    assert [r.parameters for r in longer[:n]] == [r.parameters for r in first]


def test_overrides_walk_tables_and_arrays_and_leave_the_base_alone():
    base = {"contacts": [{"restitution": 0.9}], "surfaces": {"ground": {"point": [0, 0, 0]}}}
    new = apply_overrides(
        base, {"contacts.0.restitution": 0.3, "surfaces.ground.point.2": 0.01, "sensors.a": 1}
    )
    assert new["contacts"][0]["restitution"] == 0.3
    assert new["surfaces"]["ground"]["point"] == [0, 0, 0.01]
    assert new["sensors"] == {"a": 1}
    assert base["contacts"][0]["restitution"] == 0.9 and "sensors" not in base
    with pytest.raises(ParameterKeyError, match="out of range"):
        apply_overrides(base, {"contacts.1.restitution": 0.3})
    with pytest.raises(ParameterKeyError, match="is a table"):
        apply_overrides(base, {"surfaces.ground": 1.0})


def test_assignment_text_round_trips():
    for key, value in [("a.0.b", 0.93), ("flag", True), ("p", [0.0, 0.005, 0.0]), ("n", "x y")]:
        assert parse_assignment(format_assignment(key, value)) == (key, value)
    with pytest.raises(ParameterKeyError):
        parse_assignment("no-equals-sign")


@pytest.mark.parametrize(
    ("key", "match"),
    [
        ("contacts.0.restitutio", "restitutio"),
        ("contacts.3.restitution", "out of range"),
        ("robot.q0.7", "out of range"),
        ("surfaces.floor.point.2", "floor"),
        ("integrator.stepsize", "stepsize"),
        ("controller.mass_scale", "mass_scale"),  # the ball's zero controller has no such key
    ],
)
def test_unknown_dotted_key_is_named(write_campaign, key, match):
    path = write_campaign(HEAD + f'[grid]\n"{key}" = [0.5]\n')
    with pytest.raises(ParameterKeyError, match=match) as caught:
        load_campaign(path)
    assert caught.value.key == key


def test_value_the_scene_rejects_is_named(write_campaign):
    path = write_campaign(HEAD + '[grid]\n"contacts.0.restitution" = [0.5, 1.5]\n')
    with pytest.raises(ParameterKeyError, match=r"1\.5"):
        load_campaign(path)


@pytest.mark.parametrize(
    ("spec", "name", "value"),
    [
        ('{ type = "uniform", low = 1.0, high = 0.5 }', "high", 0.5),
        ('{ type = "uniform", low = 0.0, high = 0.0 }', "high", 0.0),
        ('{ type = "normal", mean = 0.5, std = 0.0 }', "std", 0.0),
        ('{ type = "normal", mean = 0.5, std = -1 }', "std", -1.0),
        ('{ type = "log_uniform", low = 0.0, high = 1.0 }', "low", 0.0),
        ('{ type = "choice", values = [] }', "values", []),
        ('{ type = "choice", values = [0.1, 0.2], weights = [1] }', "weights", [1]),
        ('{ type = "choice", values = [0.1, 0.2], weights = [1, -1] }', "weights", [1, -1]),
        ('{ type = "beta", a = 1 }', "type", "beta"),
        ('{ type = "uniform", low = 0.0, high = 1.0, mean = 3 }', "keys", ["mean"]),
        ('{ type = "uniform", low = "a", high = 1.0 }', "low", "a"),
    ],
)
def test_distribution_out_of_range_is_named(write_campaign, spec, name, value):
    path = write_campaign(
        HEAD.replace("duration = 0.2", "duration = 0.2\nruns = 3")
        + f'[distributions]\n"contacts.0.restitution" = {spec}\n'
    )
    with pytest.raises(DistributionError) as caught:
        load_campaign(path)
    assert caught.value.key == "contacts.0.restitution"
    assert caught.value.name == name and caught.value.value == value


def test_empty_grid_is_named(write_campaign):
    path = write_campaign(HEAD + '[grid]\n"contacts.0.restitution" = []\n')
    with pytest.raises(EmptyGridError, match=r"contacts\.0\.restitution"):
        load_campaign(path)


@pytest.mark.parametrize(
    ("metrics", "name"),
    [
        ('["max_penetratio"]', "max_penetratio"),
        ('["constraints"]', "constraints"),  # an array, not a number
        ('["weak_stability.cycles_complete"]', "weak_stability.cycles_complete"),  # no cycles
        ('["no_such_module_here:f"]', "no_such_module_here:f"),
        ('["json:no_such_function"]', "json:no_such_function"),
    ],
)
def test_unknown_metric_is_named(write_campaign, metrics, name):
    path = write_campaign(HEAD.replace("duration = 0.2", f"duration = 0.2\nmetrics = {metrics}"))
    with pytest.raises(UnknownMetricError) as caught:
        load_campaign(path)
    assert caught.value.metric == name


def test_criterion_names_are_metrics_too(write_campaign):
    path = write_campaign(
        HEAD.replace("duration = 0.2", 'duration = 0.2\nsuccess = "max_penetratio < 1e-3"')
    )
    with pytest.raises(UnknownMetricError, match="max_penetratio"):
        load_campaign(path)


@pytest.mark.parametrize(
    "expression",
    [
        "__import__('os').system('true')",
        "max_penetration.__class__",
        "open('x')",
        "lambda: 1",
        "[1][0] < 2",
        "'a' == 'a'",
        "max_penetration <",
        "",
    ],
)
def test_criterion_outside_the_allowed_form_is_rejected(expression):
    with pytest.raises(CriterionError):
        parse_criterion(expression)


def test_criterion_evaluates_like_python_on_numbers_and_fails_on_nan():
    rng = np.random.default_rng(3)
    criterion = parse_criterion("a < 1e-3 and not (b > 2 or abs(c) >= 0.5) and 0 <= a")
    for _ in range(200):
        a, b, c = rng.normal(0, 1e-3), rng.uniform(0, 4), rng.normal(0, 0.5)
        expected = a < 1e-3 and not (b > 2 or abs(c) >= 0.5) and 0 <= a
        assert criterion({"a": a, "b": b, "c": c}) == expected
    assert not criterion({"a": float("nan"), "b": 0.0, "c": 0.0})
    assert not criterion({"b": 0.0, "c": 0.0})  # a missing metric never passes
    assert parse_criterion("x.y >= 2").names == ("x.y",)


def test_unknown_campaign_keys_and_scene_are_named(write_campaign):
    with pytest.raises(CampaignFileError, match="'seeds'"):
        load_campaign(write_campaign(HEAD + "seeds = 3\n"))
    with pytest.raises(CampaignFileError, match=r"nothing\.toml"):
        load_campaign(write_campaign(HEAD.replace("ball.toml", "nothing.toml")))
    with pytest.raises(CampaignFileError, match="runs"):
        load_campaign(write_campaign(HEAD + "runs = 0\n"))
    with pytest.raises(CampaignFileError, match="does not exist"):
        load_campaign("/nonexistent/campaign.toml")


def test_shipped_campaign_by_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    campaign = load_campaign("ball_restitution_campaign")
    assert campaign.name == "ball_restitution"
    assert len(campaign.plan()) == 4  # 2 restitutions x 2 runs
    with pytest.raises(CampaignFileError, match=r"nor a shipped campaign: ball_restitution_c"):
        load_campaign("ball_restitution")


def test_unwritable_out_is_named(write_campaign, tmp_path):
    campaign = load_campaign(write_campaign(HEAD))
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(OutputDirectoryError) as caught:
        prepare_directory(campaign, blocker / "out")
    assert caught.value.directory == str(blocker / "out")


def test_unreachable_scheduler_is_named():
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    with pytest.raises(SchedulerUnreachableError) as caught:
        connect(address, timeout=1.0)
    assert caught.value.address == address
    assert isinstance(caught.value, UControlError)


def test_wilson_interval_matches_its_closed_form_and_covers():
    # closed form at k = 0: [0, z^2 / (n + z^2)]
    z = 1.959963984540054
    low, high = wilson_interval(0, 20)
    assert low == 0.0 and high == pytest.approx(z * z / (20 + z * z), rel=1e-12)
    # coverage of the 95 % interval, checked by simulation
    rng = np.random.default_rng(11)
    p, n, trials = 0.8, 40, 4000
    k = rng.binomial(n, p, size=trials)
    covered = np.mean([lo <= p <= hi for lo, hi in (wilson_interval(int(x), n) for x in k)])
    assert 0.92 < covered < 0.98


def test_scene_with_overrides_sets_the_keys(tmp_path):
    from ucontrol.campaign.overrides import scene_with_overrides
    from ucontrol.scene import builtin_scene

    path = builtin_scene("ball.toml")
    scene = scene_with_overrides(path, ["contacts.0.restitution=0.25", "robot.q0=[0.5]"])
    assert scene.contacts[0].restitution == 0.25 and scene.q0.tolist() == [0.5]
    assert scene.source == path.resolve() and scene.name == "ball"
    with pytest.raises(UControlError, match="restitutio"):
        scene_with_overrides(path, ["contacts.0.restitutio=0.25"])
    by_name = scene_with_overrides("ball", ["contacts.0.restitution=0.5"])
    assert by_name.contacts[0].restitution == 0.5 and by_name.source == path.resolve()
    with pytest.raises(UControlError):
        scene_with_overrides("no/such/scene.toml", [])


def test_scene_named_like_the_campaign_file_is_the_built_in_one(write_campaign):
    path = write_campaign(HEAD, "ball.toml")  # the campaign file itself is not a scene
    campaign = load_campaign(path)
    assert campaign.scene_ref == {"builtin": "ball.toml"}


def test_scene_file_next_to_the_campaign_is_preferred(write_campaign, tmp_path):
    from ucontrol.scene import builtin_scene

    text = builtin_scene("ball.toml").read_text().replace('urdf = "ball.urdf"', "urdf = 'URDF'")
    (tmp_path / "my_ball.toml").write_text(
        text.replace("'URDF'", repr(str(builtin_scene("ball.toml").parent / "ball.urdf")))
    )
    campaign = load_campaign(write_campaign(HEAD.replace("ball.toml", "my_ball.toml")))
    assert campaign.scene_ref == {"path": str((tmp_path / "my_ball.toml").resolve())}
    assert campaign.scene_name() == "my_ball"


def test_base_scene_that_cannot_be_built_is_a_campaign_error(write_campaign, tmp_path):
    from ucontrol.campaign import CampaignError
    from ucontrol.scene import builtin_scene

    urdf = str(builtin_scene("ball.toml").parent / "ball.urdf")
    text = builtin_scene("ball.toml").read_text().replace('"ball.urdf"', repr(urdf))
    (tmp_path / "broken.toml").write_text(text + "\nspeed = 3\n")
    path = write_campaign(HEAD.replace("ball.toml", "broken.toml"))
    with pytest.raises(CampaignError, match="speed"):
        load_campaign(path)
