"""A designed cycle taken directly by the controllers: ``[controller] designed_cycle = FILE``.

The two-link task's cycle (solved once per session) is written with ``DesignedCycle.save`` and
named in a scene file beside it: the rigid and flexible Brogliato controllers and the impedance
controller read it (path relative to the scene), the flexible law and the impedance law track
it in closed loop through one landing, contact phase and takeoff.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from two_link_design import ROBOTS, two_link_design

from ucontrol.analysis.cycles import cycle_events
from ucontrol.control.desired_cycle import read_designed_cycle
from ucontrol.exceptions import InvalidParameterError, SceneError
from ucontrol.scene import Scene
from ucontrol.simulate import simulate

pytestmark = pytest.mark.slow  # long runs: `pytest -m "not slow"` leaves them out

#: Simulated time in [s]: the first landing (7.85 s), the contact phase, the takeoff (10 s).
DURATION = 10.6


def _scene_file(folder: Path, base: str, extra: str = "") -> Path:
    """``base`` with ``designed_cycle = "cycle.npz"`` in place of its path and contact phase."""
    text = (ROBOTS / base).read_text()
    text = text[: text.index("[controller.path]")] + 'designed_cycle = "cycle.npz"\n' + extra
    for urdf in ("two_link.urdf", "two_link_flexible.urdf"):
        text = text.replace(f'urdf = "{urdf}"', f'urdf = "{ROBOTS / urdf}"')
    path = folder / base
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def cycle_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("designed")
    two_link_design()[0].save(folder / "cycle")
    return folder


def _force_error(log, start: float, end: float) -> float:  # type: ignore[no-untyped-def]
    """Largest |λ - λ_d| in [N] over [start, end), λ = P / h; the contact closed throughout."""
    t = np.asarray(log.t)
    window = (t >= start) & (t < end)
    force = np.asarray(log.impulse)[window, 0] / 1e-3  # [N]: the scenes' dt
    assert np.all(force > 0.0), "the contact opened in the contact phase"
    return float(np.max(np.abs(force - np.asarray(log.lambda_d)[window, 0])))


def test_the_file_gives_the_designed_path_and_contact_phase(cycle_dir: Path) -> None:
    cycle = two_link_design()[0]
    path, phase = read_designed_cycle(cycle_dir / "cycle.json")
    desired = cycle.desired_cycle()
    assert phase == desired.contact_phases[0]
    assert phase.start == pytest.approx(cycle.landing_time) and phase.end == cycle.period
    times, positions = cycle.nodes()
    for t, p in zip(times, positions, strict=True):  # through the design's nodes
        np.testing.assert_allclose(path(float(t))[0], p, atol=1e-12)
    for t in np.random.default_rng(3).uniform(0.0, cycle.period, 5):
        for a, b in zip(path.derivatives(t, 4), desired.path.derivatives(t, 4), strict=True):
            np.testing.assert_array_equal(a, b)
    scene = Scene.from_toml(_scene_file(cycle_dir, "two_link_one_constraint.toml"))
    rigid = scene.build_controller()
    assert rigid.cycle.contact_phases == (phase,)  # type: ignore[attr-defined]
    assert rigid.cycle.approach_time == 0.8  # type: ignore[attr-defined] # the scene's setting


def test_flexible_brogliato_tracks_the_designed_cycle(cycle_dir: Path) -> None:
    scene = Scene.from_toml(_scene_file(cycle_dir, "two_link_flexible_one_constraint.toml"))
    log = simulate(scene, duration=DURATION, progress=False).log
    cycles = cycle_events(log)
    assert len(cycles) == 1 and cycles[0].complete
    # measured 0.011 N against the 5 N plateau and its fall, from 0.35 s after the landing
    assert _force_error(log, 8.2, 9.95) <= 0.05
    assert np.asarray(log.gap)[np.asarray(log.t) >= 10.3, 0].min() > 0.0  # taken off


def test_impedance_tracks_the_designed_cycle(cycle_dir: Path) -> None:
    scene = Scene.from_toml(_scene_file(cycle_dir, "two_link_one_constraint_impedance.toml"))
    log = simulate(scene, duration=DURATION, progress=False).log
    t, gap = np.asarray(log.t), np.asarray(log.gap)[:, 0]
    assert gap[t < 7.0].min() > 0.0  # flies until the designed landing
    assert _force_error(log, 8.2, 9.4) <= 0.5  # measured 0.125 N on the 5 N plateau
    assert gap[t >= 10.3].min() > 0.0  # taken off


def test_designed_cycle_beside_a_path_or_missing(cycle_dir: Path) -> None:
    text = (ROBOTS / "two_link_one_constraint.toml").read_text()
    path = cycle_dir / "both.toml"
    text = text.replace('urdf = "two_link.urdf"', f'urdf = "{ROBOTS / "two_link.urdf"}"')
    head, tail = text.split("[controller.path]")
    path.write_text(head + 'designed_cycle = "cycle.npz"\n[controller.path]' + tail)
    with pytest.raises(InvalidParameterError, match="path") as error:
        Scene.from_toml(path).build_controller()
    assert "designed_cycle" in str(error.value)
    missing = _scene_file(cycle_dir, "two_link_one_constraint_impedance.toml")
    missing.write_text(missing.read_text().replace('"cycle.npz"', '"no_cycle.npz"'))
    with pytest.raises(SceneError, match=r"no_cycle\.npz"):
        Scene.from_toml(missing).build_controller()
    broken = cycle_dir / "broken"
    np.savez(broken.with_suffix(".npz"), impulses=np.zeros(1))
    broken.with_suffix(".json").write_text('{"phases": [{"name": "flight"}]}')
    with pytest.raises(SceneError, match="not a designed cycle"):
        read_designed_cycle(broken)
