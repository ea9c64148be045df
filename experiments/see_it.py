r"""See a run: the one-constraint tracking case in meshcat and in figures.

Runs ``robots/two_link_one_constraint.toml`` (the two-link arm landing on the ground, sliding
with a desired contact force and taking off), writes its log into ``--out``, the figures of
``ucontrol plot`` into ``--out``/figures and its standalone HTML replay ``--out``/replay.html.
Into ``--figures`` it copies ``tracking.png`` as ``see_it_tracking.png`` and, when Debian's
chromium is installed, writes ``see_it_meshcat.png``: the replay at ``--shot-time`` seconds,
rendered offline by headless Chromium (the images of docs/visualisation.md).

Run: ``python experiments/see_it.py`` (~15 s).
"""

from __future__ import annotations

import argparse
import shutil
from collections.abc import Sequence
from pathlib import Path

from ucontrol.scene import load_scene
from ucontrol.simulate import simulate
from ucontrol.viz.browser_screenshot import find_chromium, screenshot
from ucontrol.viz.replay import write_html
from ucontrol.viz.run_figures import run_figures

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "robots" / "two_link_one_constraint.toml"


def main(argv: Sequence[str] | None = None) -> dict[str, Path]:
    """Run the case and write its figures, replay and screenshot; return their paths."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=12.0, help="simulated time in [s]")
    parser.add_argument(
        "--shot-time", type=float, default=7.0, help="time of the screenshot in the replay [s]"
    )
    parser.add_argument("--out", type=Path, default=ROOT / "runs" / "see_it", help="run folder")
    parser.add_argument(
        "--figures", type=Path, default=ROOT / "docs" / "figures", help="folder of the images"
    )
    args = parser.parse_args(argv)

    scene = load_scene(SCENE)
    log = simulate(scene, duration=args.duration, out=args.out).log
    paths = {path.stem: path for path in run_figures(log, args.out / "figures", scene=scene)}
    paths["replay"] = write_html(args.out / "replay.html", scene, log)
    args.figures.mkdir(parents=True, exist_ok=True)
    paths["see_it_tracking"] = Path(
        shutil.copy(paths["tracking"], args.figures / "see_it_tracking.png")
    )
    if find_chromium() is not None:
        paths["see_it_meshcat"] = screenshot(
            paths["replay"].resolve().as_uri(),
            args.figures / "see_it_meshcat.png",
            virtual_time_ms=round(1e3 * args.shot_time),
            offline=True,
        )
    for name, path in paths.items():
        print(f"{name}: {path}")
    return paths


if __name__ == "__main__":
    main()
