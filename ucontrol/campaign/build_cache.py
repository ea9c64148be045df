"""A worker's integrators and controllers, built once and reused by the runs that allow it.

A campaign run builds its scene's integrator (compiled free step, constraint rows) and its
controller (casadi law, phase machine) before its first step; for a short run that is a good
part of its time. The runs of one worker reuse what an earlier run built where only what the
object takes as numbers differs. :class:`BuildCache` keeps the objects that a run returned,
each under its *family*, the scene file and the part of the table its builder reads without
those numbers (:func:`integrator_family`, :func:`controller_family`), and under its *key*, the
same part with them (:func:`integrator_key`, :func:`controller_key`). A run takes an object of
its family: one built for its own key as it is, another after giving it the run's numbers
(the ``adapt`` of :meth:`BuildCache.checkout`), then resets it to the state of a fresh build:

- the integrator (Moreau–Jean only: the others have no ``reset``): the run's constraints when
  they differ in numbers only (:data:`CONSTRAINT_NUMBERS`: restitutions, friction
  coefficients, plane points and normals, stop bounds;
  :meth:`~ucontrol.integrators.MoreauJean.use_constraints`), then its step memory renewed and
  its contact solvers' warm starts dropped (``reset()``);
- the controller: the run's believed inertias (:data:`INERTIA_NUMBERS`;
  :func:`~ucontrol.scene.controller_builders.retarget_controller`: a rigid Brogliato law, whose
  inertias are an input of its compiled code), then ``reset()`` (phase machine, events,
  measurements); controllers without a ``reset`` are built for every run.

An object that cannot take the run's numbers (another kind of contact, a rebound where its
build had none, another controller) goes back unchanged and the run builds its own. Sensors,
actuators and their noise generators are made by the closed loop for every run (seeded per run
as before). Any other override of the controller's table rebuilds the controller alone; any
other override of the plant (the robot, a surface's type, the integrator's settings) rebuilds
the integrator and, since the controller reads the scene's contacts and robot, the controller.

Thread safety: an object is taken out of the cache while its run uses it (:meth:`checkout`) and
put back when the run ends (:meth:`checkin`), so two runs of one worker in two threads never
share one; the cache holds at most ``capacity`` objects of each kind (least recently used out).
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from ucontrol._validation import as_int

#: Top-level scene tables that no integrator builder reads.
_NOT_READ_BY_INTEGRATOR = ("controller", "sensors", "actuators", "duration", "reference")
#: Top-level scene tables that no controller builder reads.
_NOT_READ_BY_CONTROLLER = ("integrator", "sensors", "actuators", "duration", "reference")
#: Objects of each kind a worker keeps by default.
DEFAULT_CAPACITY = 4
#: The kinds of objects cached.
INTEGRATOR, CONTROLLER = "integrator", "controller"
#: How a run got each object (the record's ``build`` entry).
BUILT, REUSED = "built", "reused"


#: Numbers of the constraints a Moreau–Jean integrator takes without a rebuild: per scene
#: table, the keys of its entries (:meth:`~ucontrol.integrators.MoreauJean.use_constraints`).
CONSTRAINT_NUMBERS = {
    "contacts": ("restitution", "friction"),
    "surfaces": ("point", "normal"),
    "stops": ("lower", "upper", "restitution"),
}
#: The controller's believed inertias (table paths), which a rigid Brogliato controller takes
#: without a rebuild (:func:`~ucontrol.scene.controller_builders.retarget_controller`).
INERTIA_NUMBERS = (
    ("controller", "model", "mass_scale"),
    ("controller", "model", "com_offset"),
    ("controller", "mass_scale"),
)


def integrator_key(scene_path: str, table: Mapping[str, Any]) -> str:
    """What a scene's integrator is built from: its file and the tables the builder reads."""
    return _key(scene_path, table, _NOT_READ_BY_INTEGRATOR)


def controller_key(scene_path: str, table: Mapping[str, Any]) -> str:
    """What a scene's controller is built from: its file and the tables the builder reads."""
    return _key(scene_path, table, _NOT_READ_BY_CONTROLLER)


def integrator_family(scene_path: str, table: Mapping[str, Any]) -> str:
    """:func:`integrator_key` without the numbers of :data:`CONSTRAINT_NUMBERS`."""
    return integrator_key(scene_path, _without_numbers(table, ()))


def controller_family(scene_path: str, table: Mapping[str, Any]) -> str:
    """:func:`controller_key` without :data:`CONSTRAINT_NUMBERS` and :data:`INERTIA_NUMBERS`."""
    return controller_key(scene_path, _without_numbers(table, INERTIA_NUMBERS))


def _without_numbers(table: Mapping[str, Any], paths: Iterable[tuple[str, ...]]) -> dict[str, Any]:
    """A copy of ``table`` without the :data:`CONSTRAINT_NUMBERS` and the entries at ``paths``."""
    copy = dict(table)
    for name, keys in CONSTRAINT_NUMBERS.items():
        entries = copy.get(name)
        if isinstance(entries, Mapping):  # (surfaces: by name)
            copy[name] = {k: _without(entry, keys) for k, entry in entries.items()}
        elif isinstance(entries, list):
            copy[name] = [_without(entry, keys) for entry in entries]
    for path in paths:
        _drop(copy, path)
    return copy


def _without(entry: Any, keys: Iterable[str]) -> Any:
    """``entry`` without ``keys`` if it is a table, else as it is."""
    if not isinstance(entry, Mapping):
        return entry
    return {key: value for key, value in entry.items() if key not in keys}


def _drop(table: dict[str, Any], path: tuple[str, ...]) -> None:
    """Remove ``table``'s entry at ``path``, copying the tables on the way (``table`` is one)."""
    head, *rest = path
    if head not in table:
        return
    if not rest:
        del table[head]
    elif isinstance(table[head], Mapping):
        table[head] = dict(table[head])
        _drop(table[head], tuple(rest))
        if not table[head]:  # (a table left empty reads as none)
            del table[head]


def _key(scene_path: str, table: Mapping[str, Any], ignored: Iterable[str]) -> str:
    read = {name: value for name, value in table.items() if name not in ignored}
    return json.dumps([scene_path, read], sort_keys=True, default=repr)  # floats exact (repr)


@dataclass
class CacheStats:
    """Counts of a :class:`BuildCache`, per kind (``"integrator"``, ``"controller"``).

    Attributes:
        built: Objects built because none was cached under the run's key.
        reused: Objects handed out again.
        evicted: Objects dropped to keep within the capacity.
    """

    built: dict[str, int]
    reused: dict[str, int]
    evicted: dict[str, int]


class BuildCache:
    """Built integrators and controllers of one worker, by family, at most ``capacity`` of each.

    Args:
        capacity: Objects of each kind kept.

    Raises:
        InvalidParameterError: ``capacity`` is not a positive whole number.
    """

    def __init__(self, capacity: int = DEFAULT_CAPACITY) -> None:
        self.capacity = as_int("capacity", capacity, low=1)
        self._lock = threading.Lock()
        # Per kind and family, the free objects with the key each was last used for.
        self._objects: dict[str, OrderedDict[str, list[tuple[str, Any]]]] = {
            INTEGRATOR: OrderedDict(),
            CONTROLLER: OrderedDict(),
        }
        self._built = dict.fromkeys(self._objects, 0)
        self._reused = dict.fromkeys(self._objects, 0)
        self._evicted = dict.fromkeys(self._objects, 0)

    def checkout(
        self,
        kind: str,
        key: str,
        family: str | None = None,
        adapt: Callable[[Any], bool] | None = None,
    ) -> Any | None:
        """Take a cached object of ``kind`` for ``key`` out of the cache, or None.

        An object last used for ``key`` is returned as it is. Otherwise, with ``adapt``, the
        objects of ``family`` (default: ``key``), most recently used first, are given to
        ``adapt``, which gives one the run's numbers and says whether it took them: the first
        that does is returned (from then on the object of ``key``), the others go back
        unchanged. None counts as a build (the caller builds it). The object returned is the
        caller's alone until :meth:`checkin`; the caller resets it.
        """
        family = key if family is None else family
        refused: list[tuple[str, Any]] = []
        found = None
        while found is None:
            with self._lock:
                free = self._objects[kind].get(family, [])
                at = next((i for i, (used, _) in enumerate(free) if used == key), None)
                if at is None and (not free or adapt is None):
                    break
                used, candidate = free.pop(len(free) - 1 if at is None else at)
                if not free:
                    del self._objects[kind][family]
            if at is not None or (adapt is not None and adapt(candidate)):  # (unlocked)
                found = candidate
            else:
                refused.append((used, candidate))
        for used, candidate in reversed(refused):  # unchanged, for their own keys
            self._put(kind, family, used, candidate)
        with self._lock:
            counts = self._built if found is None else self._reused
            counts[kind] += 1
        return found

    def checkin(self, kind: str, key: str, built: Any, family: str | None = None) -> None:
        """Put ``built``, last used for ``key``, back under ``family`` (default: ``key``).

        The least recently used objects of ``kind`` beyond the capacity are dropped.
        """
        self._put(kind, key if family is None else family, key, built)

    def _put(self, kind: str, family: str, key: str, built: Any) -> None:
        with self._lock:
            objects = self._objects[kind]
            objects.setdefault(family, []).append((key, built))
            objects.move_to_end(family)
            while sum(len(free) for free in objects.values()) > self.capacity:
                oldest = next(iter(objects))
                objects[oldest].pop(0)
                if not objects[oldest]:
                    del objects[oldest]
                self._evicted[kind] += 1

    def stats(self) -> CacheStats:
        """The counts so far (copies)."""
        with self._lock:
            return CacheStats(dict(self._built), dict(self._reused), dict(self._evicted))

    def clear(self) -> None:
        """Drop every cached object and the counts."""
        with self._lock:
            for objects in self._objects.values():
                objects.clear()
            for counts in (self._built, self._reused, self._evicted):
                for kind in counts:
                    counts[kind] = 0


#: The cache of this process (a Dask worker's, or the caller's with an in-process loop).
WORKER_CACHE = BuildCache()


def reusable_integrator(integrator: Any) -> bool:
    """Whether ``integrator`` can be reset to a fresh build's state (Moreau–Jean)."""
    return getattr(integrator, "name", None) == "moreau_jean" and callable(
        getattr(integrator, "reset", None)
    )


def reusable_controller(controller: Any) -> bool:
    """Whether ``controller`` can be reset to a fresh build's state (it has ``reset()``)."""
    return callable(getattr(controller, "reset", None))
