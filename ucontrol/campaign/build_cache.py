"""A worker's integrators and controllers, built once and reused by the runs that allow it.

A campaign run builds its scene's integrator (compiled free step, constraint rows) and its
controller (casadi law, phase machine) before its first step; for a short run that is a good
part of its time. The runs of one worker that share the part of the scene table an object is
built from reuse it: :class:`BuildCache` keeps the objects that a run returned, keyed by the
scene file and that part of the table (:func:`integrator_key`, :func:`controller_key`), and
hands them out again after a reset to the state of a fresh build:

- the integrator (Moreau–Jean only: the others have no ``reset``): its step memory renewed
  (``reset()``) and fresh contact solvers with the scene's settings (their warm starts belong
  to one run);
- the controller: ``reset()`` (phase machine, events, measurements); controllers without a
  ``reset`` are built for every run.

Sensors, actuators and their noise generators are made by the closed loop for every run (seeded
per run as before). An override of the controller's table rebuilds the controller alone; an
override of the plant (restitution, a surface, the integrator's settings) rebuilds the
integrator and, since the controller reads the scene's contacts and robot, the controller.

Thread safety: an object is taken out of the cache while its run uses it (:meth:`checkout`) and
put back when the run ends (:meth:`checkin`), so two runs of one worker in two threads never
share one; the cache holds at most ``capacity`` objects of each kind (least recently used out).
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict
from collections.abc import Iterable, Mapping
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


def integrator_key(scene_path: str, table: Mapping[str, Any]) -> str:
    """What a scene's integrator is built from: its file and the tables the builder reads."""
    return _key(scene_path, table, _NOT_READ_BY_INTEGRATOR)


def controller_key(scene_path: str, table: Mapping[str, Any]) -> str:
    """What a scene's controller is built from: its file and the tables the builder reads."""
    return _key(scene_path, table, _NOT_READ_BY_CONTROLLER)


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
    """Built integrators and controllers of one worker, by key, at most ``capacity`` of each.

    Args:
        capacity: Objects of each kind kept.

    Raises:
        InvalidParameterError: ``capacity`` is not a positive whole number.
    """

    def __init__(self, capacity: int = DEFAULT_CAPACITY) -> None:
        self.capacity = as_int("capacity", capacity, low=1)
        self._lock = threading.Lock()
        self._objects: dict[str, OrderedDict[str, list[Any]]] = {
            INTEGRATOR: OrderedDict(),
            CONTROLLER: OrderedDict(),
        }
        self._built = dict.fromkeys(self._objects, 0)
        self._reused = dict.fromkeys(self._objects, 0)
        self._evicted = dict.fromkeys(self._objects, 0)

    def checkout(self, kind: str, key: str) -> Any | None:
        """Take a cached object of ``kind`` under ``key`` out of the cache, or None.

        None counts as a build (the caller builds it). The object returned is the caller's
        alone until :meth:`checkin`; the caller resets it.
        """
        with self._lock:
            free = self._objects[kind].get(key)
            if not free:
                self._built[kind] += 1
                return None
            self._reused[kind] += 1
            found = free.pop()
            if not free:
                del self._objects[kind][key]
            return found

    def checkin(self, kind: str, key: str, built: Any) -> None:
        """Put ``built`` back under ``key`` after its run, dropping the least recently used."""
        with self._lock:
            objects = self._objects[kind]
            objects.setdefault(key, []).append(built)
            objects.move_to_end(key)
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
