r"""The designed cycle: joint and task trajectories per phase, torques, forces, impulses.

Saved as ``NAME.npz`` (arrays) beside ``NAME.json`` (phase names and kinds, frame, contact,
...), and converted to what the tracking controllers take: a periodic nominal path of the
tracked frame plus the contact phase (:meth:`DesignedCycle.desired_cycle`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ucontrol.control.desired_cycle import ContactPhase, DesiredCycle
from ucontrol.exceptions import SceneError

if TYPE_CHECKING:  # scipy.interpolate loads with it, when a path is asked for
    from ucontrol.control.spline_path import SplinePath

Vector = NDArray[np.float64]
_ARRAYS = ("t", "q", "v", "tau", "force", "position", "velocity")


@dataclass(frozen=True, kw_only=True)
class CyclePhase:
    """One phase of the designed cycle on its multiple-shooting grid (N intervals).

    Attributes:
        name: ``"flight"``, ``"bounce_k"`` or ``"contact"``.
        kind: ``"flight"``, ``"bounce"`` or ``"contact"``.
        t: Node times from the start of the cycle (takeoff) in [s], shape (N + 1,).
        q: Joint positions at the nodes, shape (N + 1, nv).
        v: Joint velocities at the nodes, shape (N + 1, nv) (before the impact at the end).
        tau: Torque held over each interval, shape (N, nv), in [N m].
        force: Normal contact force at the nodes in [N], shape (N + 1,) (0 in flight).
        position: Tracked frame's position in the world in [m], shape (N + 1, 3).
        velocity: Tracked frame's velocity in [m/s], shape (N + 1, 3).
    """

    name: str
    kind: str
    t: Vector
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    tau: NDArray[np.float64]
    force: Vector
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]

    @property
    def duration(self) -> float:
        """Duration in [s]."""
        return float(self.t[-1] - self.t[0])


@dataclass(frozen=True, kw_only=True)
class DesignedCycle:
    """A cycle designed by optimal control, from takeoff to takeoff.

    Attributes:
        phases: The phases in cycle order: flight, bounces, contact.
        impulses: Impulse of each impact in [N s] (one per phase boundary before contact).
        frame: The tracked frame.
        contact: Name of the contact of the constrained phase.
        force: Desired force plateau of the task in [N] (for the tracking controller).
        restitution: Restitution of the contact.
        friction: Coulomb coefficient of the contact.
        substeps: Runge–Kutta steps per control interval in the design.
        scheme: Runge–Kutta scheme of the design (``"rk4"`` or ``"rk8"``).
        scene: Path of the base scene file ("" when built in code).
    """

    phases: tuple[CyclePhase, ...]
    impulses: Vector
    frame: str
    contact: str
    force: float
    restitution: float
    friction: float
    substeps: int
    scheme: str = "rk4"
    scene: str = ""

    @property
    def period(self) -> float:
        """Period in [s]."""
        return float(self.phases[-1].t[-1] - self.phases[0].t[0])

    @property
    def impact_times(self) -> Vector:
        """Time of each impact from the start of the cycle, in [s]."""
        return np.array([phase.t[-1] for phase in self.phases[:-1]])

    @property
    def landing_time(self) -> float:
        """Time of the first landing in [s]."""
        return float(self.phases[0].t[-1])

    def phase(self, name: str) -> CyclePhase:
        """The phase called ``name``."""
        for phase in self.phases:
            if phase.name == name:
                return phase
        raise KeyError(name)

    def nodes(self) -> tuple[Vector, NDArray[np.float64]]:
        """Node times [s] (n,) and positions [m] (n, 3) over one period, each instant once."""
        times = np.concatenate([phase.t[:-1] for phase in self.phases])
        positions = np.vstack([phase.position[:-1] for phase in self.phases])
        return times, positions

    def nominal_path(self) -> SplinePath:
        """The periodic C⁴ path of the tracked frame through the node positions.

        The periodic quintic spline through the node positions at the node times, the path a
        scene's ``designed_cycle`` key gives the controllers
        (:func:`ucontrol.control.desired_cycle.read_designed_cycle`).
        """
        from ucontrol.control.spline_path import SplinePath

        times, positions = self.nodes()
        return SplinePath(waypoints=positions, times=times - times[0], period=self.period)

    def desired_cycle(self, **settings: Any) -> DesiredCycle:
        """The desired cycle of the Brogliato controllers: nominal path and contact phase.

        The contact phase runs from the first landing to the takeoff (the end of the period);
        ``settings`` are :class:`DesiredCycle` fields (``approach_time``, ``depth_min``...).
        """
        phase = ContactPhase(
            contact=self.contact, start=self.landing_time, end=self.period, force=self.force
        )
        return DesiredCycle(path=self.nominal_path(), contact_phases=(phase,), **settings)

    def save(self, path: str | Path) -> Path:
        """Write ``path`` with suffix ``.npz`` (arrays) and ``.json`` (the rest).

        Returns:
            The path of the ``.npz`` file.
        """
        path = Path(path).with_suffix(".npz")
        arrays: dict[str, Any] = {"impulses": np.asarray(self.impulses)}
        for i, phase in enumerate(self.phases):
            for name in _ARRAYS:
                arrays[f"phase{i}_{name}"] = getattr(phase, name)
        np.savez(path, **arrays)
        meta = {
            name.name: getattr(self, name.name)
            for name in fields(self)
            if name.name not in ("phases", "impulses")
        }
        meta["phases"] = [{"name": phase.name, "kind": phase.kind} for phase in self.phases]
        meta["period"] = self.period
        path.with_suffix(".json").write_text(json.dumps(meta, indent=2) + "\n")
        return path

    @classmethod
    def load(cls, path: str | Path) -> DesignedCycle:
        """Read a cycle written by :meth:`save` (give either file or the stem).

        Raises:
            SceneError: A file is missing.
        """
        path = Path(path).with_suffix(".npz")
        meta_path = path.with_suffix(".json")
        if not path.is_file() or not meta_path.is_file():
            raise SceneError(f"designed cycle {str(path)!r} (and its .json) does not exist")
        meta = json.loads(meta_path.read_text())
        with np.load(path) as data:
            phases = tuple(
                CyclePhase(
                    name=spec["name"],
                    kind=spec["kind"],
                    **{name: np.array(data[f"phase{i}_{name}"]) for name in _ARRAYS},
                )
                for i, spec in enumerate(meta.pop("phases"))
            )
            impulses = np.array(data["impulses"])
        meta.pop("period", None)
        return cls(phases=phases, impulses=impulses, **meta)
