"""The trajectory record of a run: preallocated arrays, incremental save, load."""

from __future__ import annotations

import os
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ucontrol.exceptions import InvalidParameterError, LogFileError, NotFoundError
from ucontrol.output_files import write_atomically

#: Per-sample arrays of a log, with their shape after the sample axis (see docs/outputs.md).
SAMPLE_FIELDS: dict[str, str] = {
    "t": "()",
    "q": "(nq,)",
    "v": "(nv,)",
    "u": "(nu,)",
    "gap": "(n,)",
    "normal_velocity": "(n,)",
    "impulse": "(n,)",
    "active": "(n,)",
    "energy": "()",
    "solver_iterations": "()",
    "complementarity_residual": "()",
    "solver_time": "()",
    "solver_status": "()",
    "solver_outer_iterations": "()",
}


class Impacts(NamedTuple):
    """The impacts of a run, in the order the integrator found them.

    Attributes:
        t: Impact times in [s], shape (K,): located within the step by event-driven
            integration, the contact onsets of compliant integration, the start t_k of the
            step that closes the constraint with Moreau–Jean (resolution h).
        constraint: The constraint of each impact, by name, shape (K,).
    """

    t: NDArray[np.float64]
    constraint: NDArray[Any]  # strings


#: ``solver_status`` codes: no contact solve in the step, solved within the solver's
#: tolerance, or left above it (the run went on with ``on_unsolved = "warn"``).
NO_SOLVE, SOLVED, UNSOLVED = 0, 1, 2


class Log:
    """Samples of a run, one row per time step, stored in preallocated arrays.

    Row k holds the state at ``t[k]`` (``q``, ``v``, ``gap``, ``normal_velocity``, ``energy``)
    and what acts over the step that starts there: the torque ``u`` (zero-order hold), the
    normal ``impulse`` of each constraint and its membership of the ``active`` set, and the
    contact solve's ``solver_iterations``, ``complementarity_residual`` (natural-map residual,
    of the Coulomb problem with friction), ``solver_time`` in [s], ``solver_status``
    (:data:`NO_SOLVE`, :data:`SOLVED`, :data:`UNSOLVED`) and ``solver_outer_iterations``
    (fixed-point iterations of a friction solve). The last row has no step after it: its
    impulses are zero and its torque is the one last applied.

    Besides the rows, :attr:`impacts` lists the run's impacts with their times (a table of
    its own: a step may hold several impacts, or none).

    Args:
        capacity: Maximum number of rows.
        nq: Configuration size.
        nv: Velocity size.
        nu: Number of actuated coordinates.
        constraint_names: One label per unilateral constraint.
        metadata: Scalars and strings saved with the arrays (scene, integrator, dt, ...).
    """

    def __init__(
        self,
        capacity: int,
        *,
        nq: int,
        nv: int,
        nu: int,
        constraint_names: list[str],
        metadata: dict[str, Any] | None = None,
    ) -> None:
        n = len(constraint_names)
        self.constraint_names = list(constraint_names)
        self.metadata = dict(metadata or {})
        self.size = 0
        self._arrays: dict[str, NDArray[Any]] = {
            "t": np.zeros(capacity),
            "q": np.zeros((capacity, nq)),
            "v": np.zeros((capacity, nv)),
            "u": np.zeros((capacity, nu)),
            "gap": np.zeros((capacity, n)),
            "normal_velocity": np.zeros((capacity, n)),
            "impulse": np.zeros((capacity, n)),
            "active": np.zeros((capacity, n), dtype=bool),
            "energy": np.zeros(capacity),
            "solver_iterations": np.zeros(capacity, dtype=np.int64),
            "complementarity_residual": np.zeros(capacity),
            "solver_time": np.zeros(capacity),
            "solver_status": np.zeros(capacity, dtype=np.int8),
            "solver_outer_iterations": np.zeros(capacity, dtype=np.int64),
        }
        self._extras: dict[str, NDArray[Any]] = {}
        self._impacts: list[tuple[int, float]] = []  # (constraint index, time [s])

    def __len__(self) -> int:
        return self.size

    def __getattr__(self, name: str) -> NDArray[Any]:
        arrays = self.__dict__.get("_arrays", {})
        if name in arrays:
            return arrays[name][: self.size]
        extras = self.__dict__.get("_extras", {})
        if name in extras:
            return extras[name][: self.size]
        raise AttributeError(name)

    @property
    def fields(self) -> list[str]:
        """Names of the per-sample arrays held."""
        return [*self._arrays, *self._extras]

    def constraint_index(self, name: str) -> int:
        """Column of constraint ``name`` in ``gap``, ``impulse``, ``active``, ...

        Raises:
            NotFoundError: No constraint has that name (the message lists them).
        """
        if name not in self.constraint_names:
            raise NotFoundError("constraint", name, self.constraint_names)
        return self.constraint_names.index(name)

    @property
    def impacts(self) -> Impacts:
        """The run's impacts: their times in [s] and constraints' names, each of shape (K,)."""
        pairs = np.array(self._impacts, dtype=float).reshape(-1, 2)
        names = np.array(self.constraint_names, dtype=str)[pairs[:, 0].astype(np.intp)]
        return Impacts(pairs[:, 1].copy(), names)

    def impact_times_of(self, name: str) -> NDArray[np.float64]:
        """Impact times of constraint ``name`` in [s], shape (K_a,), in the order found.

        Raises:
            NotFoundError: No constraint has that name (the message lists them).
        """
        i = self.constraint_index(name)
        return np.array([t for index, t in self._impacts if index == i], dtype=float)

    def record_impacts(self, impacts: Sequence[tuple[int, float]]) -> None:
        """Add a step's impacts, (constraint index, time in [s]) pairs, to :attr:`impacts`."""
        self._impacts += impacts

    def gap_of(self, name: str) -> NDArray[np.float64]:
        """Gap of constraint ``name`` at every sample, in [m] (or [rad]), shape (N,)."""
        return self.gap[:, self.constraint_index(name)]

    def impulse_of(self, name: str) -> NDArray[np.float64]:
        """Normal impulse of constraint ``name`` over each step, in [N s], shape (N,).

        Row k is the impulse over [t_k, t_k+1]; the last row has no step after it and holds 0.
        """
        return self.impulse[:, self.constraint_index(name)]

    def force_of(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean normal force of constraint ``name`` over each step, and the steps' start times.

        The last row, which has no step after it, is left out (its impulse is 0 by
        convention), so the mean of the force is the true mean over the run; impacts appear as
        impulse / h peaks.

        Returns:
            The force in [N] and the times t_k in [s], each of shape (N - 1,).
        """
        impulse = self.impulse_of(name)[:-1]
        return impulse / np.diff(self.t), self.t[:-1]

    def row_at(self, t: float) -> int:
        """The row of the last sample at or before ``t`` [s] (values held until the next).

        Raises:
            InvalidParameterError: ``t`` is before the first sample or after the last.
        """
        times = self.t
        if not len(times) or not times[0] - 1e-12 <= t <= times[-1] + 1e-12:
            span = f"[{times[0]:g}, {times[-1]:g}] s" if len(times) else "an empty log"
            raise InvalidParameterError("t", t, f"a time in {span}")
        return int(np.searchsorted(times, t + 1e-12, side="right") - 1)

    def at(self, field: str, t: float) -> Any:
        """The value of ``field`` (e.g. ``"phase"``, ``"q"``) in the row of time ``t`` [s]."""
        if field not in self.fields:
            raise NotFoundError("log field", field, self.fields)
        return getattr(self, field)[self.row_at(t)]

    def add_field(self, name: str, shape: tuple[int, ...], dtype: Any = float) -> None:
        """Add a per-sample array, e.g. a controller's phase, of shape ``(capacity, *shape)``."""
        capacity = self._arrays["t"].shape[0]
        self._extras[name] = np.zeros((capacity, *shape), dtype=dtype)

    def extra_fields(self, names: Sequence[str]) -> tuple[NDArray[Any], ...]:
        """The whole arrays (every row, shape ``(capacity, *shape)``) of fields ``names``.

        For a recorder that writes many fields at every sample: ``array[len(log)] = value``
        is :meth:`record_extra` without its look-up. The arrays stay those of the log until
        :meth:`add_field` replaces one.
        """
        return tuple(self._extras[name] for name in names)

    def record_extra(self, name: str, value: Any) -> None:
        """Write ``value`` into the current row of a field added by :meth:`add_field`."""
        self._extras[name][self.size] = value

    def record_state(
        self,
        t: float,
        q: NDArray[Any],
        v: NDArray[Any],
        gap: NDArray[Any],
        normal_velocity: NDArray[Any],
        energy: float,
    ) -> None:
        """Write the state part of the current row."""
        arrays, k = self._arrays, self.size
        arrays["t"][k] = t
        arrays["q"][k] = q
        arrays["v"][k] = v
        arrays["gap"][k] = gap
        arrays["normal_velocity"][k] = normal_velocity
        arrays["energy"][k] = energy

    def record_step(
        self,
        u: NDArray[Any],
        impulse: NDArray[Any],
        active: NDArray[Any],
        iterations: int,
        residual: float,
        solve_time: float = 0.0,
        status: int = NO_SOLVE,
        outer_iterations: int = 0,
    ) -> None:
        """Write what acts over the step starting at the current row, then close the row.

        Args:
            u: Torque held over the step, shape (nu,).
            impulse: Normal impulse of each constraint in [N s], shape (n,).
            active: Active-set membership, shape (n,).
            iterations: Contact solver iterations.
            residual: Contact solve residual in [m/s].
            solve_time: Wall time of the contact solve in [s].
            status: :data:`NO_SOLVE`, :data:`SOLVED` or :data:`UNSOLVED`.
            outer_iterations: Fixed-point iterations of a friction solve.
        """
        arrays, k = self._arrays, self.size
        arrays["u"][k] = u
        arrays["impulse"][k] = impulse
        arrays["active"][k] = active
        arrays["complementarity_residual"][k] = residual
        arrays["solver_status"][k] = status
        # Rows are allocated as zeros and written once, in order: zeros need no write.
        if iterations:
            arrays["solver_iterations"][k] = iterations
        if solve_time:
            arrays["solver_time"][k] = solve_time
        if outer_iterations:
            arrays["solver_outer_iterations"][k] = outer_iterations
        self.size = k + 1

    def record_step_without_solve(
        self, u: NDArray[Any], impulse: NDArray[Any], active: NDArray[Any]
    ) -> None:
        """:meth:`record_step` of a step without a contact solve, then close the row.

        Its solver fields keep the zeros the rows are allocated with (:data:`NO_SOLVE`): rows
        are written once, in order.
        """
        arrays, k = self._arrays, self.size
        arrays["u"][k] = u
        arrays["impulse"][k] = impulse
        arrays["active"][k] = active
        self.size = k + 1

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the filled rows to ``path`` (``.npz``) atomically and return the path.

        Raises:
            OutputWriteError: The file could not be written (e.g. a full disk); a previous
                file at ``path`` is kept whole.
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        payload: dict[str, Any] = {name: getattr(self, name) for name in self.fields}
        payload["constraint_names"] = np.array(self.constraint_names, dtype=str)
        pairs = np.array(self._impacts, dtype=float).reshape(-1, 2)
        payload["impact_t"] = pairs[:, 1]
        payload["impact_constraint"] = pairs[:, 0].astype(np.int64)
        for key, value in self.metadata.items():
            payload[f"meta_{key}"] = np.array(value)
        return write_atomically(path, lambda stream: np.savez(stream, **payload))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Log:
        """Read a log written by :meth:`save`.

        Raises:
            LogFileError: The file is missing, truncated, corrupt or not a log.
        """
        try:
            with np.load(path) as archive:
                content = {key: archive[key] for key in archive.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
            raise LogFileError(str(path), str(error) or type(error).__name__) from error
        missing = {"t", "q", "v", "u", "constraint_names"} - set(content)
        if missing:
            raise LogFileError(str(path), f"it has no {sorted(missing)} arrays")
        names = [str(name) for name in content.pop("constraint_names")]
        impact_t = content.pop("impact_t", np.zeros(0))  # logs written before the table: none
        impact_constraint = content.pop("impact_constraint", np.zeros(0, dtype=np.int64))
        if impact_t.shape != impact_constraint.shape or not np.all(
            (impact_constraint >= 0) & (impact_constraint < len(names))
        ):
            raise LogFileError(
                str(path),
                f"its impact table has {impact_t.shape} times and constraints "
                f"{impact_constraint.tolist()} for {len(names)} constraints",
            )
        metadata = {
            key.removeprefix("meta_"): _metadata_value(content.pop(key))
            for key in list(content)
            if key.startswith("meta_")
        }
        size = content["t"].shape[0]
        log = cls(
            size,
            nq=content["q"].shape[1],
            nv=content["v"].shape[1],
            nu=content["u"].shape[1],
            constraint_names=names,
            metadata=metadata,
        )
        for key, value in content.items():
            if key not in log._arrays:
                log._extras[key] = value
            else:
                log._arrays[key] = value
        log.size = size
        log._impacts = [
            (int(i), float(t)) for i, t in zip(impact_constraint, impact_t, strict=True)
        ]
        return log


def _metadata_value(value: NDArray[Any]) -> Any:
    """A saved metadata entry back as a Python scalar, string or list."""
    return value.item() if value.ndim == 0 else value.tolist()
