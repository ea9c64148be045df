"""A table of bad inputs through the scene format, the API and the command line.

Each must end in a typed error (a :class:`~ucontrol.exceptions.UControlError`) whose message
names the offending value: never a raw Python exception, never a silent run.
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ucontrol.cli import main
from ucontrol.exceptions import UControlError
from ucontrol.log import Log
from ucontrol.scene import Scene, builtin_scene, load_scene
from ucontrol.simulate import simulate
from ucontrol.testing import (
    assert_cycles_complete,
    assert_force_tracks,
    assert_lyapunov_decreases,
    assert_no_energy_gain,
    assert_penetration_below,
)

ROBOTS = builtin_scene().parent
BALL = tomllib.loads((ROBOTS / "ball.toml").read_text())
ARM = tomllib.loads((ROBOTS / "two_link_drop.toml").read_text())
NAN = float("nan")


def _set(table: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    """A deep copy of ``table`` with the dotted ``key`` set (list items by index)."""
    table = copy.deepcopy(table)
    *parents, last = key.split(".")
    node: Any = table
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return table


#: (base table, dotted key, bad value, text the message must hold; default repr(value)).
SCENE_CASES: list[tuple[str, str, Any, str | None]] = [
    ("ball", "duration", "3", None),
    ("ball", "duration", -1.0, None),
    ("ball", "duration", 0.0, None),
    ("ball", "duration", True, None),
    ("ball", "duration", [1.0], None),
    ("ball", "duration", NAN, "nan"),
    ("ball", "robot.floating_base", "false", None),
    ("ball", "robot.floating_base", 1, None),
    ("ball", "robot.gravity", [0.0, 0.0], "(3,)"),
    ("ball", "robot.gravity", "down", None),
    ("ball", "robot.gravity", [0.0, 0.0, NAN], "nan"),
    ("ball", "robot.q0", [1e300], "1e+300"),
    ("ball", "robot.q0", [200.0], "200.0"),
    ("ball", "robot.q0", ["1"], None),
    ("ball", "robot.q0", [1.0, 2.0], "(1,)"),
    ("ball", "robot.v0", ["a"], None),
    ("ball", "robot.v0", [1.0, 2.0], "(1,)"),
    ("ball", "robot.v0", [-1e300], "`v0[0]` must be at most 1e+06 in magnitude, got -1e+300"),
    ("ball", "robot.gravity", [0.0, 0.0, -1e300], "`gravity[2]` must be at most 1e+06"),
    ("ball", "robot.urdf", "missing.urdf", "missing.urdf"),
    ("ball", "robot.urdf", 42, "42"),
    ("ball", "robot.planar_axis", [0.0, 1.0], "(3,)"),
    ("ball", "robot.mass", 2.0, "'mass'"),
    ("ball", "surfaces.ground.normal", [0.0, 0.0, 0.0], "[0.0, 0.0, 0.0]"),
    ("ball", "surfaces.ground.normal", "up", None),
    ("ball", "surfaces.ground.point", [0.0, 0.0], "(3,)"),
    ("ball", "surfaces.ground.type", "sphere", None),
    ("ball", "surfaces.ground.colour", "red", "'colour'"),
    ("ball", "contacts.0.restitution", "0.5", None),
    ("ball", "contacts.0.restitution", 1.5, None),
    ("ball", "contacts.0.restitution", -0.1, None),
    ("ball", "contacts.0.restitution", True, None),
    ("ball", "contacts.0.radius", -1.0, None),
    ("ball", "contacts.0.radius", "0.1", None),
    ("ball", "contacts.0.friction", -0.3, None),
    ("ball", "contacts.0.friction", "0.3", None),
    ("ball", "contacts.0.frame", "hand", None),
    ("ball", "contacts.0.surface", "table", None),
    ("ball", "contacts.0.stiffness", 1e6, "'stiffness'"),
    ("ball", "integrator.dt", "0.001", None),
    ("ball", "integrator.dt", -1.0, None),
    ("ball", "integrator.dt", 0.0, None),
    ("ball", "integrator.dt", True, None),
    ("ball", "integrator.theta", 0.4, None),
    ("ball", "integrator.theta", 1.5, None),
    ("ball", "integrator.theta", "0.5", None),
    ("ball", "integrator.max_iter", 0.5, None),
    ("ball", "integrator.max_iter", 0, None),
    ("ball", "integrator.max_iter", "10", None),
    ("ball", "integrator.max_iter", -3, None),
    ("ball", "integrator.friction_max_iter", 2.5, None),
    ("ball", "integrator.contact_tolerance", 1e300, None),
    ("ball", "integrator.contact_tolerance", 0.0, None),
    ("ball", "integrator.contact_tolerance", -1e-9, None),
    ("ball", "integrator.friction_tolerance", 1.0, None),
    ("ball", "integrator.name", "rk4", None),
    ("ball", "integrator.midpoint", "false", None),
    ("ball", "integrator.midpoint", 1, None),
    ("ball", "integrator.persistence_tolerance", -1.0, None),
    ("ball", "integrator.persistence_speed", -1.0, None),
    ("ball", "integrator.penetration_tolerance", 0.0, None),
    ("ball", "integrator.penetration_tolerance", -1.0, None),
    ("ball", "integrator.on_unsolved", "ignore", None),
    ("ball", "integrator.contact_solver", "gurobi", None),
    ("ball", "integrator.method", "Euler", None),
    ("ball", "integrator.zeno_velocity", -1.0, None),
    ("ball", "integrator.stiffness", "1e6", None),
    ("ball", "integrator.contact_model", "hertz", None),
    ("ball", "integrator.restitution_threshold", "0", None),
    ("ball", "integrator.substeps", 4, "'substeps'"),
    ("ball", "controller.type", "mpc", None),
    ("ball", "controller.gain", 3.0, "'gain'"),
    ("ball", "reference.type", "pendulum", None),
    ("ball", "reference.contact", "ball/table", None),
    ("ball", "name2", "x", "'name2'"),
    ("ball", "sensors.delay", 1.5, None),
    ("ball", "sensors.position_noise", -0.1, None),
    ("ball", "sensors.velocity", "kalman", None),
    ("ball", "sensors.seed", -1, None),
    ("ball", "sensors.force_noise", [1.0, 2.0], None),
    ("ball", "actuators.torque_limit", "max", None),
    ("ball", "actuators.rate_limit", -5.0, None),
    ("ball", "actuators.rate_limit", 0.0, None),
    ("ball", "actuators.rate_limit", [2.0, 0.0], None),
    ("arm", "sensors.position_noise", [0.1, 0.1, 0.1], "`position_noise` must have shape (2,)"),
    ("arm", "sensors.quantisation", [1e-3], "`quantisation` must have shape (2,), got (1,)"),
    ("arm", "actuators.torque_limit", [1.0, 2.0, 3.0], "`torque_limit` must have shape (2,)"),
    ("arm", "actuators.rate_limit", [1.0], "`rate_limit` must have shape (2,), got (1,)"),
    ("arm", "controller", {"type": "joint_pd", "kp": 1.0, "kd": 1.0, "q_ref": "up"}, "'up'"),
    ("arm", "controller", {"type": "joint_pd", "kp": "10", "kd": 1.0}, "'10'"),
    ("arm", "controller", {"type": "joint_pd", "kp": 1, "kd": 1, "gravity_compensation": 0}, "0"),
    (
        "arm",
        "controller",
        {"type": "joint_pd", "kp": 10.0, "kd": 1.0, "gravity_compensation": "false"},
        "'false'",
    ),
    ("arm", "stops.0.lower", "0", None),
    ("arm", "stops.0.joint", "wrist", None),
    ("arm", "stops.0.restitution", 2.0, None),
    ("arm", "robot.q0", [4.0, -1.6], "4.0"),
    ("arm", "robot.q0", [0.9], "(2,)"),
    ("arm", "contacts.1.surface", "ground", "end_effector/ground"),
]


@pytest.mark.parametrize(("base", "key", "value", "text"), SCENE_CASES)
def test_bad_scene_values(base: str, key: str, value: Any, text: str | None) -> None:
    table = _set(BALL if base == "ball" else ARM, key, value)
    with pytest.raises(UControlError) as caught:  # the controller's values: when it is built
        Scene.from_dict(table, base_dir=ROBOTS).build_controller()
    message = str(caught.value)
    assert (text if text is not None else repr(value)) in message, message


def _urdf_with(tmp_path: Path, inertial: str) -> Path:
    text = (ROBOTS / "ball.urdf").read_text()
    start, end = text.index("<mass"), text.index("</inertial>")
    (tmp_path / "bad.urdf").write_text(text[:start] + inertial + text[end:])
    scene = tmp_path / "scene.toml"
    scene.write_text((ROBOTS / "ball.toml").read_text().replace("ball.urdf", "bad.urdf"))
    return scene


@pytest.mark.parametrize(
    ("inertial", "text"),
    [
        ('<mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>', "-1.0"),
        ('<mass value="1"/><inertia ixx="-1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>', "-1.0"),
        ('<mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5"/>', "5.0"),
        ('<mass value="0"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>', "0.0"),
        ('<mass value="1"/><inertia ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"/>', "-1.0"),
        ('<mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>', "height"),
    ],
)
def test_physically_impossible_urdf_inertia_names_the_link(
    tmp_path: Path, inertial: str, text: str
) -> None:
    with pytest.raises(UControlError) as caught:
        load_scene(_urdf_with(tmp_path, inertial))
    assert text in str(caught.value) and (
        "'ball'" in str(caught.value) or "height" in str(caught.value)
    )


def test_a_robot_without_degree_of_freedom_refuses_constraints(tmp_path: Path, capsys: Any) -> None:
    urdf = (ROBOTS / "ball.urdf").read_text().replace('type="prismatic"', 'type="fixed"')
    (tmp_path / "ball.urdf").write_text(urdf)  # nq = nv = 0: the ball is welded in place
    text = (ROBOTS / "ball.toml").read_text()
    path = tmp_path / "fixed.toml"
    path.write_text(text.replace("q0 = [1.1]", "q0 = []").replace("v0 = [0.0]", "v0 = []"))
    message = "`constraints of robot 'ball'` must be none: the robot has no degree of freedom"
    with pytest.raises(UControlError, match=message):
        load_scene(path)
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err
    scene = tomllib.loads(path.read_text())
    del scene["contacts"], scene["reference"]  # without constraints it runs (and stays put)
    log = simulate(Scene.from_dict(scene, base_dir=tmp_path), duration=0.01).log
    assert log.q.shape == (11, 0) and len(log.constraint_names) == 0


#: OBJ texts of meshes that span no volume (coal's qhull ended the process on them, rc 139).
FLAT_MESHES = {
    "square": "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n",
    "triangle": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "sliver": "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1e-12\nf 1 2 3\nf 1 3 4\n",
}


@pytest.mark.parametrize("shape", sorted(FLAT_MESHES))
def test_a_mesh_without_volume_is_refused(tmp_path: Path, capsys: Any, shape: str) -> None:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "wedge.obj").write_text(FLAT_MESHES[shape])
    (tmp_path / "ball.urdf").write_text((ROBOTS / "free_ball_collision.urdf").read_text())
    scene = (ROBOTS / "ball_mesh_wedge.toml").read_text().replace("free_ball_collision", "ball")
    (tmp_path / "scene.toml").write_text(scene)
    assert main(["run", str(tmp_path / "scene.toml"), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "wedge.obj" in error, error
    assert "`mesh` must be a mesh with a volume" in error and "vertices lie in one plane" in error
    # the same mesh as the link's <collision> element, the wedge a real one
    (tmp_path / "meshes" / "flat.obj").write_text(FLAT_MESHES[shape])
    (tmp_path / "meshes" / "wedge.obj").write_text((ROBOTS / "meshes" / "wedge.obj").read_text())
    load_scene(tmp_path / "scene.toml")
    urdf = (tmp_path / "ball.urdf").read_text()
    sphere = '<collision>\n      <geometry><sphere radius="0.1"/>'
    assert sphere in urdf
    mesh = '<collision>\n      <geometry><mesh filename="meshes/flat.obj"/>'
    (tmp_path / "ball.urdf").write_text(urdf.replace(sphere, mesh))
    with pytest.raises(UControlError, match=r"vertices lie in one plane.*flat\.obj"):
        load_scene(tmp_path / "scene.toml")


def _ball() -> Scene:
    return load_scene("ball")


#: A run without steps: the assertions' arguments are checked before the log is read.
_EMPTY = Log(0, nq=1, nv=1, nu=0, constraint_names=[])


API_CASES: list[tuple[str, Callable[[], Any], str]] = [
    ("load_scene(42)", lambda: load_scene(42), "42"),  # type: ignore[arg-type]
    ("load_scene(unknown)", lambda: load_scene("no_such_scene"), "no_such_scene"),
    ("simulate(path)", lambda: simulate("x.toml"), "'x.toml'"),  # type: ignore[arg-type]
    ("simulate(scene, 5)", lambda: simulate(_ball(), 5), "5"),  # type: ignore[arg-type]
    ("out=3.5", lambda: simulate(_ball(), out=3.5), "3.5"),  # type: ignore[arg-type]
    ("duration=1e300", lambda: simulate(_ball(), duration=1e300), "1e+300"),
    ("dt=1e-300", lambda: simulate(_ball(), dt=1e-300), "steps"),
    ("duration='1'", lambda: simulate(_ball(), duration="1"), "'1'"),  # type: ignore[arg-type]
    ("progress='yes'", lambda: simulate(_ball(), progress="yes"), "'yes'"),  # type: ignore[arg-type]
    ("observer=3", lambda: simulate(_ball(), observer=3), "3"),  # type: ignore[arg-type]
    ("control_period=-1", lambda: simulate(_ball(), control_period=-1.0), "-1.0"),
    ("dt=0", lambda: simulate(_ball(), dt=0.0), "0.0"),
    (
        "output of wrong size",
        lambda: simulate(_ball(), lambda *a: [1.0, 2.0], duration=0.01),
        "(1,)",
    ),
    ("output NaN", lambda: simulate(_ball(), lambda *a: [NAN], duration=0.01), "nan"),
    ("output text", lambda: simulate(_ball(), lambda *a: "go", duration=0.01), "'go'"),
    (
        "delay of 60 periods in a run of 50",
        lambda: simulate(
            Scene.from_dict(_set(BALL, "sensors.delay", 60), base_dir=ROBOTS), duration=0.05
        ),
        "`delay` must be fewer control periods than the run holds (50), got 60",
    ),
    ("penetration limit NaN", lambda: assert_penetration_below(_EMPTY, NAN), "`limit`"),
    ("penetration limit < 0", lambda: assert_penetration_below(_EMPTY, -1e-3), "-0.001"),
    ("energy tolerance NaN", lambda: assert_no_energy_gain(_EMPTY, tolerance=NAN), "nan"),
    ("energy tolerance < 0", lambda: assert_no_energy_gain(_EMPTY, tolerance=-1.0), "-1.0"),
    ("force within '5%'", lambda: assert_force_tracks(_EMPTY, within="5%"), "'5%'"),  # type: ignore[arg-type]
    ("lyapunov floor -inf", lambda: assert_lyapunov_decreases(_EMPTY, floor=-math.inf), "-inf"),
    ("min_cycles 1.5", lambda: assert_cycles_complete(_EMPTY, min_cycles=1.5), "1.5"),  # type: ignore[arg-type]
]


@pytest.mark.parametrize(("label", "call", "text"), API_CASES, ids=[c[0] for c in API_CASES])
def test_bad_api_calls(label: str, call: Callable[[], Any], text: str) -> None:
    with pytest.raises(UControlError) as caught:
        call()
    assert text in str(caught.value), str(caught.value)


def test_files_that_are_not_what_they_claim(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file at all")
    truncated = tmp_path / "truncated.npz"
    good = tmp_path / "good"
    simulate(_ball(), duration=0.05, out=good)
    truncated.write_bytes((good / "log.npz").read_bytes()[:200])
    for path in (garbage, truncated, tmp_path / "missing.npz"):
        with pytest.raises(UControlError, match=str(path.name)):
            Log.load(path)
    scene = tmp_path / "latin1.toml"
    scene.write_bytes("name = 'b\xe9ll'\n".encode("latin-1"))
    with pytest.raises(UControlError, match=r"not UTF-8"):
        load_scene(scene)


def test_a_key_given_twice_is_named(tmp_path: Path, capsys: Any) -> None:
    scene = tmp_path / "twice.toml"
    text = (ROBOTS / "ball.toml").read_text()
    scene.write_text(f"duration = 2.5\n{text}")
    line = 1 + text.splitlines().index("duration = 3.0") + 1  # where `duration` comes again
    with pytest.raises(UControlError, match=rf"line {line}.*the key 'duration' is given twice"):
        load_scene(scene)
    assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "'duration' is given twice" in error


@pytest.mark.parametrize("record", ['{"name": "sweep", "finger', "[1, 2]", "\udcff"])
def test_a_corrupt_campaign_record_is_named(tmp_path: Path, capsys: Any, record: str) -> None:
    campaign = tmp_path / "sweep.toml"
    campaign.write_text('[campaign]\nscene = "ball.toml"\nruns = 1\n')
    out = tmp_path / "out"
    out.mkdir()
    (out / "campaign.json").write_bytes(record.encode("utf-8", "surrogateescape"))
    status = main(["sweep", str(campaign), "--out", str(out), "--no-progress"])
    error = capsys.readouterr().err.strip()
    assert status == 2 and len(error.splitlines()) == 1, error
    assert error.startswith("ucontrol: error: campaign file ") and "campaign.json" in error


@pytest.mark.timeout(60)  # the plan of either was built in memory: no end in sight
@pytest.mark.parametrize(
    ("body", "text"),
    [
        (
            'runs = 1000000000000\n[distributions]\n"robot.q0.0" = { type = "uniform", '
            "low = 0.2, high = 0.5 }\n",
            "1000000000000 runs (1 grid cell(s) x `runs` = 1000000000000), more than the 100000",
        ),
        (
            "[grid]\n"
            + "".join(f'"contacts.0.restitution{i}" = {[0.5] * 200}\n' for i in range(5)),
            "320000000000 runs (320000000000 grid cell(s) x `runs` = 1)",
        ),
    ],
    ids=["runs", "grid"],
)
def test_a_huge_campaign_is_refused_before_it_is_planned(
    tmp_path: Path, capsys: Any, body: str, text: str
) -> None:
    campaign = tmp_path / "huge.toml"
    campaign.write_text(f'[campaign]\nscene = "ball.toml"\n{body}')
    assert main(["sweep", str(campaign), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and text in error and "huge.toml" in error, error
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("arguments", "text"),
    [
        (["run", "ball", "--out", "{file}"], "{file}"),
        (["run", "ball", "--out", "/dev/null"], "/dev/null"),
        (["run", "ball", "--out", "{file}/below"], "{file}/below"),
        (["run", "ball", "--dt", "-1", "--out", "{dir}/a"], "-1"),
        (["run", "ball", "--duration", "0", "--out", "{dir}/a"], "0"),
        (["run", "no_such_scene"], "no_such_scene"),
        (["plot", "{garbage}"], "log.npz"),
        (["plot", "{dir}/empty"], "empty"),
        (["plot", "{run}", "--out", "{file}"], "{file}"),
        (["view", "{run}", "--html", "{dir}"], "{dir}"),
        (["bench", "ball", "--out", "{dir}"], "{dir}"),
        (["convergence", "ball", "--out", "{file}"], "{file}"),
        (["design", "{robots}/two_link_one_constraint_task.toml", "--out", "{file}"], "{file}"),
    ],
)
def test_bad_command_lines_end_in_one_line_and_status_2(
    tmp_path: Path, capsys: Any, arguments: list[str], text: str
) -> None:
    file = tmp_path / "a_file.txt"
    file.write_text("x")
    (tmp_path / "empty").mkdir()
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    (garbage / "log.npz").write_bytes(b"garbage")
    run = tmp_path / "run"
    simulate(_ball(), duration=0.05, out=run)
    names = {"file": file, "dir": tmp_path, "garbage": garbage, "run": run, "robots": ROBOTS}
    capsys.readouterr()
    status = main([argument.format(**names) for argument in arguments])
    error = capsys.readouterr().err.strip()
    assert status == 2 and error.startswith("ucontrol: error: ") and len(error.splitlines()) == 1
    assert text.format(**names) in error


def test_the_table_has_at_least_a_hundred_cases() -> None:
    cases = len(SCENE_CASES) + 6 + len(API_CASES) + 4 + 13 + 1 + 3 + 1 + 3 + 2
    assert cases >= 100


def test_silent_physics_is_made_loud() -> None:
    from ucontrol.exceptions import PenetrationWarning, PlasticRedoWarning, SimulationError

    with pytest.warns(PenetrationWarning, match=r"'ball/ground' penetrated by 4\.39"):
        summary = simulate(_ball(), dt=1.0, duration=3.0).summary  # one step lands 3.9 m deep
    assert summary["n_penetrations_beyond_tolerance"] > 0
    elastic = Scene.from_dict(
        _set(_set(BALL, "contacts.0.restitution", 1.0), "integrator.theta", 1.0),
        base_dir=ROBOTS,
    )
    with pytest.warns(PlasticRedoWarning, match=r"every restitution of the scene is 1"):
        simulate(elastic, duration=1.0)
    with pytest.raises(SimulationError, match=r"non-finite.*t = "):  # a force of 1e300 N
        simulate(_ball(), lambda *a: [1e300], duration=0.1)
    assert summary["max_penetration"] == pytest.approx(4.396, abs=1e-3)


def test_closed_chains_that_fail_are_made_loud(tmp_path: Path) -> None:
    from ucontrol.exceptions import (
        BilateralResidualWarning,
        EnergyGainWarning,
        SolverIterationCapWarning,
    )

    four_bar = load_scene("four_bar")  # no actuator, no contact: only the steps add energy
    with pytest.warns(EnergyGainWarning, match=r"rose by 15\.\d+ J .* without any impact"):
        with pytest.warns(BilateralResidualWarning, match=r"'coupler_end=rocker_end\[0\]'"):
            result = simulate(four_bar, dt=0.1)
    energy, summary = result.log.energy, result.summary
    rise = np.max(energy - np.minimum.accumulate(energy))  # [J] from its lowest point before
    assert summary["energy_gain_without_impacts"] == pytest.approx(rise, rel=1e-12)
    assert summary["energy_gain_bound"] == pytest.approx(1e-2 * (1.0 + np.abs(energy).max()))
    residual = max(np.abs(four_bar.constraints.bilateral.residuals(q)).max() for q in result.log.q)
    assert summary["max_bilateral_residual"] == residual > 1e-6
    # the two-link arm stretched, its end pinned 1 m from the shoulder: a singular closure
    urdf = (ROBOTS / "two_link.urdf").read_text().replace('upper="-0.0001"', 'upper="3.14"')
    pin = '<link name="pin"/><joint name="pin_joint" type="fixed"><parent link="base"/>'
    pin += '<child link="pin"/><origin xyz="1 0 0"/></joint></robot>'
    (tmp_path / "arm.urdf").write_text(urdf.replace("</robot>", pin))
    table = _set(_set(ARM, "robot.urdf", str(tmp_path / "arm.urdf")), "robot.q0", [0.0, 0.0])
    del table["contacts"], table["stops"], table["surfaces"], table["controller"]
    table["bilateral"] = [{"type": "point", "frame": "end_effector", "other_frame": "pin"}]
    pinned = Scene.from_dict(table, base_dir=ROBOTS)
    with pytest.warns(SolverIterationCapWarning, match=r"cap \(5000\) in 49 of 50 solves"):
        log = simulate(pinned, duration=0.05).log
    assert int(np.sum(log.solver_iterations == 5000)) == 49
