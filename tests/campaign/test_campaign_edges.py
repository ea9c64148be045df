"""Campaign edge cases: malformed files and tables, verdicts, criteria, tables and worst cases.

Every bad input raises the typed error of :mod:`ucontrol.exceptions` naming the value; every
computed figure is checked against a value worked out by hand in the test.
"""

from __future__ import annotations

import array
import itertools
import json
import math
import sys
import threading
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ucontrol.campaign import (
    CampaignError,
    CampaignFileError,
    DistributionError,
    ParameterKeyError,
    UnknownMetricError,
    apply_overrides,
    load,
    load_campaign,
    run_campaign,
    wilson_interval,
)
from ucontrol.campaign.criterion import parse_criterion
from ucontrol.campaign.distributions import Distribution, parse_distribution
from ucontrol.campaign.figures import plot_campaign, worst_cases, worst_markdown
from ucontrol.campaign.metrics import VERDICTS, Metric, check_metric, resolve
from ucontrol.campaign.overrides import lookup, parse_assignment, scene_with_overrides, split_key
from ucontrol.campaign.runner import prepare_directory, write_record
from ucontrol.campaign.table import check_formats, finished_runs, read_campaign, write_table
from ucontrol.exceptions import (
    CriterionError,
    InvalidParameterError,
    OptionalDependencyError,
    SceneError,
)

HEAD = """
[campaign]
scene = "ball.toml"
duration = 0.2
"""


# --- campaign files -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[campaign\nscene = 1", "not valid TOML"),
        ("[grid]\n", "a \\[campaign\\] table"),
        ("[campaign]\nduration = 0.2\n", "needs `scene`"),
        (HEAD + "seed = -3\n", "-3"),
        (HEAD + "seed = 1.5\n", "1.5"),
        (HEAD + "runs = 4\n", "`runs` = 4 needs"),
        (HEAD.replace("0.2", "-0.5"), "-0.5"),
        (HEAD + "dt = 'small'\n", "small"),
        (HEAD + "metrics = 'max_penetration'\n", "max_penetration"),
        (HEAD + "metrics = [1, 2]\n", r"\[1, 2\]"),
        ("distributions = 3\n" + HEAD, "distributions"),
        ("grid = 3\n" + HEAD, "grid"),
        ("metrics = 3\n" + HEAD, "metrics"),
    ],
)
def test_malformed_campaign_file_is_named(write_campaign, text, match):
    with pytest.raises(CampaignFileError, match=match):
        load_campaign(write_campaign(text), check=False)


def test_scene_next_to_the_campaign_that_is_not_toml_is_named(write_campaign, tmp_path):
    (tmp_path / "broken.toml").write_text("[robot\n")
    with pytest.raises(CampaignFileError, match=r"broken\.toml"):
        load_campaign(write_campaign(HEAD.replace("ball.toml", "broken.toml")), check=False)


def test_a_key_both_swept_and_drawn_is_named(write_campaign):
    text = (
        HEAD.replace("0.2", "0.2\nruns = 2")
        + '[grid]\n"contacts.0.restitution" = [0.5]\n'
        + '[distributions]\n"contacts.0.restitution" = { type = "uniform", low = 0, high = 1 }\n'
    )
    with pytest.raises(ParameterKeyError) as caught:
        load_campaign(write_campaign(text), check=False)
    assert caught.value.key == "contacts.0.restitution"


def test_a_metric_named_like_a_parameter_and_an_unknown_worst_are_named(write_campaign):
    clash = HEAD + '[grid]\n"n_impacts" = [1]\n[metrics]\n"n_impacts" = "n_impacts"\n'
    with pytest.raises(CampaignFileError, match="'n_impacts' names both"):
        load_campaign(write_campaign(clash), check=False)
    worst = HEAD.replace("0.2", '0.2\nworst = "-final_energy"\nmetrics = ["n_impacts"]')
    with pytest.raises(UnknownMetricError) as caught:
        load_campaign(write_campaign(worst), check=False)
    assert caught.value.metric == "-final_energy" and caught.value.available == ["n_impacts"]


# --- distributions --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("spec", "name", "value"),
    [
        (3.0, "distribution", 3.0),
        ({"type": "normal", "mean": 0.5, "std": 0.1, "low": 1.0, "high": 0.0}, "high", 0.0),
        ({"type": "normal", "mean": 2.0, "std": 0.1, "low": 0.0, "high": 1.0}, "mean", 2.0),
        ({"type": "normal", "std": 0.1}, "mean", None),
        ({"type": "choice", "values": [1, 2], "weights": "1 1"}, "weights", "1 1"),
        ({"type": "uniform", "low": -math.inf, "high": 1.0}, "low", -math.inf),
        ({"type": "uniform", "low": 0.0, "high": True}, "high", True),
    ],
)
def test_distribution_parameters_out_of_range_are_named(spec, name, value):
    with pytest.raises(DistributionError) as caught:
        parse_distribution("robot.q0.0", spec)
    assert caught.value.key == "robot.q0.0" and caught.value.name == name
    assert caught.value.value == value and repr(value) in str(caught.value)


def test_a_truncation_too_narrow_to_draw_from_is_named():
    # P(0 <= X <= 1e-12) for X ~ N(0, 1) is 4e-13: 10 000 draws never land in it
    narrow = parse_distribution(
        "k", {"type": "normal", "mean": 0.0, "std": 1.0, "low": 0.0, "high": 1e-12}
    )
    with pytest.raises(DistributionError) as caught:
        narrow.sample(np.random.default_rng(0))
    assert caught.value.value == (0.0, 1e-12)


def test_representatives_lie_inside_each_support():
    choice = parse_distribution("k", {"type": "choice", "values": ["a", "b"]})
    assert choice.representative() == "a"
    # a normal law's mean clamped into its truncation [low, high]
    assert Distribution("k", "normal", mean=3.0, low=0.0, high=1.0).representative() == 1.0
    assert Distribution("k", "normal", mean=-3.0, low=0.0, high=1.0).representative() == 0.0
    assert Distribution("k", "normal", mean=0.4).representative() == 0.4
    # log-uniform: the geometric mean of its bounds
    log_uniform = parse_distribution("k", {"type": "loguniform", "low": 1e-4, "high": 1e-2})
    assert log_uniform.representative() == pytest.approx(1e-3, rel=1e-14)


# --- dotted keys ----------------------------------------------------------------------------


BASE = {"robot": {"q0": [1.1]}, "contacts": [{"restitution": 0.9}]}


@pytest.mark.parametrize(
    ("key", "match"),
    [
        ("", "non-empty"),
        ("robot..q0", "empty part"),
        ("contacts.first", r"index 'first' is out of range \(length 1\)"),
        ("robot.0", "0 indexes a table"),
        ("robot.q0.0.1", "'robot.q0.0' is a value"),
        ("contacts.x.restitution", "'contacts' is an array"),
    ],
)
def test_override_that_does_not_walk_the_table_is_named(key, match):
    with pytest.raises(ParameterKeyError, match=match) as caught:
        apply_overrides(BASE, {key: 0.5})
    assert caught.value.key == key


def test_lookup_names_the_missing_part_and_what_the_table_holds():
    assert lookup(BASE, "contacts.0.restitution") == 0.9
    with pytest.raises(ParameterKeyError, match="'robot' has no key 'v0'; it holds: q0"):
        lookup(BASE, "robot.v0")
    with pytest.raises(ParameterKeyError, match=r"'robot\.q0\.0' is a value"):
        lookup(BASE, "robot.q0.0.x")
    assert split_key("surfaces.ground.point.2") == ["surfaces", "ground", "point", 2]


def test_a_bare_word_is_a_string_and_the_default_scene_is_built(tmp_path):
    assert parse_assignment("integrator.name = event_driven") == ("integrator.name", "event_driven")
    scene = scene_with_overrides(None, ["duration=0.125"])
    assert scene.duration == 0.125
    bad = tmp_path / "bad.toml"
    bad.write_text("[robot\n")
    with pytest.raises(SceneError, match=r"bad\.toml"):
        scene_with_overrides(bad, [])


# --- criteria -------------------------------------------------------------------------------


def test_criterion_arithmetic_and_constants_evaluate_like_python():
    rng = np.random.default_rng(5)
    criterion = parse_criterion("-a + 2 * b - c / 4 > +a ** 2 and true or not false and d")
    assert criterion.names == ("a", "b", "c", "d")
    for _ in range(100):
        a, b, c = rng.normal(size=3)
        d = bool(rng.integers(2))
        expected = ((-a + 2 * b - c / 4 > +(a**2)) and True) or ((not False) and d)
        assert criterion({"a": a, "b": b, "c": c, "d": d}) == expected


def test_criterion_division_by_zero_and_nan_operands_fail():
    assert not parse_criterion("a / b < 1")({"a": 1.0, "b": 0.0})
    assert parse_criterion("a / b < 1")({"a": 1.0, "b": 2.0})
    # a NaN figure is false in and/or as in a comparison
    assert not parse_criterion("a or b")({"a": math.nan, "b": 0.0})
    assert parse_criterion("a or b")({"a": math.nan, "b": 1.0})


def test_attribute_of_a_call_is_not_a_metric_name():
    with pytest.raises(CriterionError, match=r"'abs\(a\)' is not a metric name") as caught:
        parse_criterion("abs(a).real > 0")
    assert caught.value.value == "abs(a).real > 0"


# --- metrics --------------------------------------------------------------------------------


def _summary(v_tau0, rises, complete):
    ratios = [None, *(b / a for a, b in itertools.pairwise(v_tau0))]
    return {
        "n_impacts": 3,
        "tracking": {"free_error_max": 0.25},
        "weak_stability": {
            "V_tau0": v_tau0,
            "V_tau0_ratio": ratios,
            "cycles": [
                {"complete": c, "transition_rise": r} for c, r in zip(complete, rises, strict=True)
            ],
        },
    }


def test_weak_stability_verdicts_on_hand_made_summaries():
    good = _summary([4.0, 2.0, 1.0], [0.5, None, 0.25], [True, True, True])
    assert VERDICTS["weak_stability.V_tau0_decreasing"](good) is True
    assert VERDICTS["weak_stability.cycles_complete"](good) is True
    assert VERDICTS["weak_stability.weakly_stable"](good) is True
    assert VERDICTS["weak_stability.max_transition_rise"](good) == 0.5
    assert VERDICTS["weak_stability.max_V_tau0_ratio"](good) == 0.5  # 2/4 and 1/2
    rising = _summary([1.0, 3.0], [None, None], [True, False])
    assert VERDICTS["weak_stability.V_tau0_decreasing"](rising) is False
    assert VERDICTS["weak_stability.cycles_complete"](rising) is False
    assert VERDICTS["weak_stability.weakly_stable"](rising) is False
    assert math.isnan(VERDICTS["weak_stability.max_transition_rise"](rising))
    assert VERDICTS["weak_stability.max_V_tau0_ratio"](rising) == 3.0
    assert VERDICTS["weak_stability.cycles_complete"](_summary([], [], [])) is False


def test_metric_values_of_a_finished_run(tmp_path):
    summary = _summary([4.0, 2.0], [0.5, 0.75], [True, True])
    summary["peak"] = np.float64(2.5)
    result = SimpleNamespace(summary=summary)
    assert Metric("s", "weak_stability.max_transition_rise").evaluate(result) == 0.75
    assert Metric("v", "weak_stability.V_tau0.1").evaluate(result) == 2.0
    assert Metric("v", "weak_stability.V_tau0.2").evaluate(result) is None  # beyond the array
    assert Metric("p", "peak").evaluate(result) == 2.5
    assert type(Metric("p", "peak").evaluate(result)) is float
    no_cycles = SimpleNamespace(summary={"n_impacts": 0})
    assert Metric("w", "weak_stability.weakly_stable").evaluate(no_cycles) is None
    (tmp_path / "edge_metrics.py").write_text("def twice(result):\n    return 2 * result.x\n")
    run = SimpleNamespace(x=np.int64(21), summary={})
    assert Metric("t", "edge_metrics:twice").evaluate(run, (str(tmp_path),)) == 42
    with pytest.raises(TypeError, match="'tracking' returned dict"):
        Metric("t", "tracking").evaluate(result)
    assert resolve(summary, "tracking.free_error_max.x") is None


def test_check_metric_accepts_array_entries_and_lists_the_scalar_keys():
    summary = _summary([4.0, 2.0], [0.5, 0.75], [True, True])
    check_metric(Metric("v", "weak_stability.V_tau0.7"), summary, ())  # lengths vary by run
    with pytest.raises(UnknownMetricError) as caught:
        check_metric(Metric("v", "weak_stability.V_tau0.last"), summary, ())
    assert caught.value.metric == "weak_stability.V_tau0.last"
    # nested tables are listed dotted, arrays are not
    assert "tracking.free_error_max" in caught.value.available
    assert "weak_stability.V_tau0" not in caught.value.available


# --- tables and worst cases -----------------------------------------------------------------


def _record(index, e, q0, penetration, status="ok", success=True, error=""):
    return {
        "run_id": f"run-{index:05d}",
        "index": index,
        "parameters": {"contacts.0.restitution": e, "robot.q0.0": q0},
        "metrics": {"max_penetration": penetration, "flag": bool(index % 2)},
        "success": success,
        "status": status,
        "error": error,
        "wall_time_s": 0.01 * index,
        "worker": "host:1",
    }


@pytest.fixture
def campaign_dir(write_campaign, tmp_path):
    """A campaign directory with six hand-written run records (no run is simulated)."""
    text = (
        HEAD.replace("0.2", '0.2\nworst = "max_penetration"')
        + '[grid]\n"contacts.0.restitution" = [0.2, 0.5, 0.8]\n"robot.q0.0" = [0.5, 0.7]\n'
        + '[metrics]\nmax_penetration = "max_penetration"\nflag = "n_impacts"\n'
    )
    campaign = load_campaign(write_campaign(text), check=False)
    directory = prepare_directory(campaign, tmp_path / "out")
    records = [
        _record(0, 0.2, 0.5, 1e-4),
        _record(1, 0.2, 0.7, 5e-4, success=False),
        _record(2, 0.5, 0.5, 2e-4),
        _record(3, 0.5, 0.7, None, status="error", success=False, error="SolverError: x"),
        _record(4, 0.8, 0.5, 9e-4),
        _record(5, 0.8, 0.7, 3e-4),
    ]
    records[3]["metrics"] = {}  # a run that raised has no metrics
    for record in records:
        write_record(directory, record)
    (directory / "runs" / "run-00006.json").write_text("{not json")  # an interrupted write
    return directory


def test_worst_cases_rank_failures_then_the_worst_metric(campaign_dir):
    assert sorted(finished_runs(campaign_dir)) == [f"run-{i:05d}" for i in range(6)]
    worst = worst_cases(campaign_dir, 4)
    # failed run 3 first, then the completed failure 1, then penetrations 9e-4 > 3e-4
    assert list(worst["run_id"]) == ["run-00003", "run-00001", "run-00004", "run-00005"]
    assert worst.loc[2, "rerun"] == (
        "ucontrol run ball --duration 0.2 --dt 0.001 --set contacts.0.restitution=0.8 "
        "--set robot.q0.0=0.5"
    )
    text = worst_markdown(worst).splitlines()
    assert text[0] == "- `run-00003` failed (error): SolverError: x"
    assert text[2] == "- `run-00001` completed, success criterion not met, max_penetration = 0.0005"
    assert text[4] == "- `run-00004` passed, max_penetration = 0.0009"


@pytest.mark.slow
def test_figures_of_a_two_parameter_sweep(campaign_dir, tmp_path):
    import matplotlib.image as mpimg

    paths = plot_campaign(campaign_dir, tmp_path / "figures")
    assert sorted(p.name for p in paths) == sorted(
        [
            "success_contacts_0_restitution.png",
            "success_robot_q0_0.png",
            "success_map.png",
            "metrics.png",
            "worst.csv",
            "worst.md",
        ]
    )
    # two metrics on one row of two panels: 4.2 in per panel at 110 dpi
    assert mpimg.imread(tmp_path / "figures" / "metrics.png").shape[1] == round(2 * 4.2 * 110)


def test_four_metrics_leave_two_empty_panels_hidden(write_campaign, tmp_path):
    text = (
        HEAD
        + '[grid]\n"robot.q0.0" = [0.5]\n[metrics]\n'
        + "".join(f'm{i} = "n_impacts"\n' for i in range(4))
    )
    campaign = load_campaign(write_campaign(text), check=False)
    directory = prepare_directory(campaign, tmp_path / "out")
    for index in range(3):
        record = _record(index, 0.9, 0.5, 0.0)
        record["metrics"] = {f"m{i}": float(index + i) for i in range(4)}
        write_record(directory, record)
    import matplotlib.image as mpimg

    paths = plot_campaign(directory)
    # one swept value only: no success figure; 4 metrics on 2 rows of 3 panels
    assert sorted(p.name for p in paths) == ["metrics.png", "worst.csv", "worst.md"]
    height, width = mpimg.imread(directory / "figures" / "metrics.png").shape[:2]
    assert (height, width) == (round(2 * 3.2 * 110), round(3 * 4.2 * 110))


def test_an_empty_campaign_has_no_worst_case(write_campaign, tmp_path):
    campaign = load_campaign(write_campaign(HEAD), check=False)
    directory = prepare_directory(campaign, tmp_path / "out")
    worst = worst_cases(directory)
    assert worst.empty and "rerun" in worst.columns
    assert worst_markdown(worst) == "(no finished runs)"


def test_rerun_of_a_scene_file_is_relative_to_the_working_directory(
    campaign_dir, tmp_path, monkeypatch
):
    info = read_campaign(campaign_dir)
    info["scene"] = {"path": str(tmp_path / "scenes" / "my_ball.toml")}
    info["scene_path"] = str(tmp_path / "scenes" / "my_ball.toml")
    info["dt"] = 5e-4
    (campaign_dir / "campaign.json").write_text(json.dumps(info))
    monkeypatch.chdir(tmp_path)
    assert (
        worst_cases(campaign_dir, 1)
        .loc[0, "rerun"]
        .startswith("ucontrol run scenes/my_ball.toml --duration 0.2 --dt 0.0005 --set")
    )
    monkeypatch.chdir(campaign_dir)  # the scene lies outside: its path is kept whole
    assert str(tmp_path / "scenes") in worst_cases(campaign_dir, 1).loc[0, "rerun"]


def test_table_formats_and_the_parquet_columns(campaign_dir, monkeypatch):
    with pytest.raises(InvalidParameterError, match="xlsx"):
        check_formats(["csv", "xlsx"])
    paths = write_table(campaign_dir, ("csv", "parquet"))
    import pandas as pd

    frame = pd.read_parquet(paths[1])
    # the failed run has no metrics: the column mixing booleans and None is JSON text
    assert [json.loads(x) for x in frame["flag"]] == [False, True, False, None, False, True]
    assert frame["max_penetration"].isna().tolist() == [False] * 3 + [True] + [False] * 2
    assert load(campaign_dir)["max_penetration"].iloc[1] == 5e-4
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(OptionalDependencyError, match="pyarrow"):
        check_formats(["parquet"])


def test_a_folder_without_a_campaign_is_named(tmp_path):
    with pytest.raises(CampaignError, match=str(tmp_path)):
        read_campaign(tmp_path)


def test_wilson_interval_of_no_runs_is_the_whole_interval():
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_records_hold_numpy_and_other_values_as_json(tmp_path):
    (tmp_path / "runs").mkdir()
    record = {
        "run_id": "run-00000",
        "n": np.int64(7),
        "samples": array.array("d", [0.5, 0.25]),
        "where": Path("/a/b"),
    }
    path = write_record(tmp_path, record)
    assert json.loads(path.read_text()) == {
        "run_id": "run-00000",
        "n": 7,
        "samples": [0.5, 0.25],
        "where": "/a/b",
    }


def test_a_campaign_run_from_a_thread_with_a_progress_bar(write_campaign, tmp_path, capsys):
    """Two free-fall runs on an in-process cluster, started from a worker thread."""
    from distributed import Client

    text = HEAD.replace("0.2", '0.05\nmetrics = ["max_penetration"]') + (
        '[grid]\n"robot.q0.0" = [0.5, 0.7]\n'
    )
    campaign = load_campaign(write_campaign(text), check=False)
    outcome: dict[str, object] = {}
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        thread = threading.Thread(
            target=lambda: outcome.update(
                value=run_campaign(campaign, tmp_path / "out", client=c, progress=True)
            )
        )
        thread.start()
        thread.join()
    result = outcome["value"]
    assert (result.total, result.ran, result.failed, result.interrupted) == (2, 2, 0, False)
    assert "2/2" in capsys.readouterr().err
    # 0.05 s of free fall from gaps of 0.4 m and 0.6 m: no contact, no penetration
    assert list(load(tmp_path / "out")["max_penetration"]) == [0.0, 0.0]
