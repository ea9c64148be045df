"""The observer hook of simulate: called once per completed row, the last one included."""

from __future__ import annotations

from conftest import ROBOTS

from ucontrol.log import Log
from ucontrol.scene import load_scene
from ucontrol.simulate import simulate


def test_observer_sees_every_row_once_when_it_is_complete() -> None:
    seen: list[tuple[int, float, float]] = []

    def observer(log: Log) -> None:
        seen.append((len(log), float(log.t[-1]), float(log.impulse[-1, 0])))

    log = simulate(load_scene(ROBOTS / "ball.toml"), duration=0.5, observer=observer).log
    assert [size for size, _, _ in seen] == list(range(1, len(log) + 1))
    assert [t for _, t, _ in seen] == log.t.tolist()
    assert [impulse for _, _, impulse in seen] == log.impulse[:, 0].tolist()  # step written
