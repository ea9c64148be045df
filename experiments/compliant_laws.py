r"""Restitution maps e(v⁻) of the compliant contact laws, and the Hunt–Crossley dampings.

Each law of :mod:`ucontrol.integrators.contact_laws`, calibrated on a requested restitution
(``--restitution``, default 0.7), takes one isolated impact of a 1 kg mass at speeds v⁻ from
``--min-speed`` to ``--max-speed`` (integrated by :meth:`ContactLaw.restitution`, no gravity).
The Kuwabara–Kono law meets e at ``--reference-speed``. A second panel gives the restitution that
Hunt–Crossley's law :math:`k\delta^{3/2}(1 + \chi\dot\delta)` reaches against the requested one
with the published dampings χ v⁻ = 3(1 - e)/2 (Hunt and Crossley 1975), 3(1 - e²)/4
(Lankarani and Nikravesh 1990), 8(1 - e)/(5e) (Flores et al. 2011) and the exact one
(:func:`hunt_crossley_damping`): the closed form :func:`hunt_crossley_restitution` gives it at
every speed.

Writes ``compliant_laws.png`` and ``compliant_laws.md`` into ``--out`` (default docs/figures)
and prints the table. Run: ``python experiments/compliant_laws.py`` (about ten seconds).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ucontrol.integrators.contact_laws import (
    ContactLaw,
    hunt_crossley_damping,
    hunt_crossley_restitution,
)
from ucontrol.integrators.methods import CONTACT_MODELS

DOCS_FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
MASS = 1.0  # [kg]
#: Stiffness of every law, [N/m] or [N/m^1.5]: the maps do not depend on it.
STIFFNESS = 1e6
#: Published Hunt–Crossley dampings x = χ v⁻ as functions of the requested e.
DAMPINGS: dict[str, Callable[[float], float]] = {
    "Hunt–Crossley 3(1-e)/2": lambda e: 1.5 * (1.0 - e),
    "Lankarani–Nikravesh 3(1-e²)/4": lambda e: 0.75 * (1.0 - e**2),
    "Flores et al. 8(1-e)/(5e)": lambda e: 1.6 * (1.0 - e) / e,
    "exact (this module)": hunt_crossley_damping,
}


def restitution_maps(
    restitution: float, speeds: np.ndarray, reference_speed: float
) -> dict[str, np.ndarray]:
    """e(v⁻) of every law calibrated on ``restitution``, at ``speeds`` [m/s]."""
    maps = {}
    for model in CONTACT_MODELS:
        law = ContactLaw(model=model, stiffness=STIFFNESS, reference_speed=reference_speed)
        maps[model] = np.array(
            [law.restitution(v, restitution=restitution, mass=MASS) for v in speeds]
        )
    return maps


def reached_restitutions(requested: np.ndarray) -> dict[str, np.ndarray]:
    """Restitution Hunt–Crossley's law reaches with each published damping."""
    return {
        name: np.array([hunt_crossley_restitution(damping(e)) for e in requested])
        for name, damping in DAMPINGS.items()
    }


def table(maps: dict[str, np.ndarray], speeds: np.ndarray, restitution: float) -> str:
    """Markdown table of e(v⁻), one row per law."""
    header = "| law | " + " | ".join(f"v⁻ = {v:.3g} m/s" for v in speeds) + " |"
    rule = "|---|" + "---|" * len(speeds)
    rows = [f"| {model} | " + " | ".join(f"{e:.6f}" for e in maps[model]) + " |" for model in maps]
    return "\n".join([f"Requested e = {restitution:g}.", "", header, rule, *rows]) + "\n"


def plot(
    maps: dict[str, np.ndarray],
    speeds: np.ndarray,
    restitution: float,
    reference_speed: float,
    path: Path,
) -> Path:
    """Left: e(v⁻) of each law; right: e reached by Hunt–Crossley's law against e requested."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(10.0, 4.0), layout="constrained")
    # The three exact laws overlap at e: markers at staggered speeds keep each visible.
    markers = {"linear": "o", "hunt_crossley_exact": "s", "walton_braun": "^"}
    for index, (model, values) in enumerate(maps.items()):
        left.semilogx(
            speeds,
            values,
            marker=markers.get(model),
            markevery=(index % 3, 3),
            markerfacecolor="none",
            label=model,
        )
    left.axvline(reference_speed, color="grey", linewidth=0.8)
    left.set_xlabel("impact speed v⁻ [m/s]")
    left.set_ylabel("restitution e = v⁺ / v⁻")
    left.set_title(f"e(v⁻) calibrated on e = {restitution:g} (grey: reference speed)")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize="small")
    requested = np.linspace(0.05, 0.99, 95)
    for name, reached in reached_restitutions(requested).items():
        right.plot(requested, reached, label=name)
    right.set_xlabel("requested e")
    right.set_ylabel(r"e reached by $k\delta^{3/2}(1 + \chi\dot\delta)$")
    right.set_title(r"Hunt–Crossley dampings $\chi v^-$")
    right.grid(True, alpha=0.3)
    right.legend(fontsize="small")
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--restitution", type=float, default=0.7, help="requested e in [0, 1]")
    parser.add_argument("--min-speed", type=float, default=1e-3, help="lowest v⁻ in [m/s]")
    parser.add_argument("--max-speed", type=float, default=1e2, help="highest v⁻ in [m/s]")
    parser.add_argument("--speeds", type=int, default=26, help="number of impact speeds")
    parser.add_argument(
        "--reference-speed", type=float, default=1.0, help="Kuwabara–Kono calibration, [m/s]"
    )
    parser.add_argument("--out", type=Path, default=DOCS_FIGURES, help="output folder")
    return parser


def main(argv: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Compute the maps, print and write the table, draw the figure; return the maps."""
    parser = _parser()
    args = parser.parse_args(argv)
    if not 0.0 < args.min_speed < args.max_speed or args.speeds < 2:
        parser.error("need 0 < --min-speed < --max-speed and --speeds >= 2")
    speeds = np.geomspace(args.min_speed, args.max_speed, args.speeds)
    maps = restitution_maps(args.restitution, speeds, args.reference_speed)
    every = slice(None, None, max(1, (len(speeds) - 1) // 5))  # six columns at most
    shown = {model: values[every] for model, values in maps.items()}
    markdown = table(shown, speeds[every], args.restitution)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "compliant_laws.md").write_text(markdown)
    plot(maps, speeds, args.restitution, args.reference_speed, args.out / "compliant_laws.png")
    print(markdown)
    return maps


if __name__ == "__main__":
    main()
