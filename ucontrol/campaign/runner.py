"""Run a campaign on dask.distributed, one file per finished run, resumable.

:func:`run_task` is the pure task function shipped to the workers: a scene table and its
overrides in, a JSON-ready record out; it never raises (a failing run is a record with status
``"error"`` and the exception's text). :func:`run_campaign` maps it over the runs not yet on
disk (``client.map``), writes each record as it arrives (``as_completed``) to
``DIR/runs/<run_id>.json`` atomically, and writes the campaign table at the end, also when
interrupted (Ctrl-C or SIGTERM). dask and distributed are imported only here.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import sys
import time
import traceback
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from ucontrol._validation import as_positive
from ucontrol.campaign.build_cache import (
    BUILT,
    CONTROLLER,
    INTEGRATOR,
    REUSED,
    WORKER_CACHE,
    BuildCache,
    controller_family,
    controller_key,
    integrator_family,
    integrator_key,
    reusable_controller,
    reusable_integrator,
)
from ucontrol.campaign.criterion import parse_criterion
from ucontrol.campaign.metrics import Metric
from ucontrol.campaign.overrides import apply_overrides
from ucontrol.campaign.spec import Campaign, scene_file
from ucontrol.campaign.table import (
    CAMPAIGN_FILE,
    PLAN_FILE,
    RUNS_DIR,
    finished_runs,
    read_campaign,
    write_table,
)
from ucontrol.exceptions import (
    CampaignMismatchError,
    OutputDirectoryError,
    SchedulerUnreachableError,
)

#: Run statuses: completed, raised an exception, or its worker died twice (KilledWorker).
OK, ERROR, KILLED = "ok", "error", "killed"
#: Signals that stop a campaign like Ctrl-C: the table is written, the cluster closed.
_STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)
#: Seconds allowed to connect to a scheduler given by address.
CONNECT_TIMEOUT_S = 5.0
#: Longest wait in [s] with no Dask worker connected while runs are pending: then the
#: campaign stops as interrupted (the runs left run on resume) instead of waiting forever.
NO_WORKER_TIMEOUT_S = 60.0
#: Period in [s] of the check for finished runs and connected workers.
_POLL_S = 0.1
#: Modules the workers of a local cluster import as soon as they are up, all at once and before
#: the first run (the scene layer, the closed loop, Pinocchio): a run's time is its own. A worker
#: started later (after one died) imports them in its first run. :func:`prepare_worker` then
#: builds the first run's objects and runs its first steps, which imports the rest (its
#: controller, sensors, summary).
WORKER_IMPORTS = ("ucontrol.campaign.prebuilt_scene", "ucontrol.simulate")
#: Dask settings of the local cluster. A run whose worker dies is tried once more on a fresh
#: worker, then recorded as killed; each worker holds only the run it executes (with dask's
#: default saturation, 1.1, a single-threaded worker also holds the next run, and its death
#: counted against both: a run that kills its worker twice took an innocent one with it).
CLUSTER_SETTINGS = {
    "distributed.scheduler.allowed-failures": 1,
    "distributed.scheduler.worker-saturation": 1.0,
}


@dataclass(frozen=True)
class CampaignOutcome:
    """What :func:`run_campaign` did.

    Attributes:
        directory: The output directory.
        total: Runs in the campaign.
        skipped: Runs already on disk, not run again.
        ran: Runs finished in this call (``ok``, ``error`` or ``killed``).
        failed: Of those, runs that did not complete (``error`` or ``killed``).
        interrupted: The campaign stopped before every run ended (Ctrl-C, SIGTERM, SIGHUP,
            runs cancelled by a scheduler that went away); the same call again runs the rest.
        tables: The table files written.
        signum: The signal that stopped it (SIGINT for Ctrl-C), or None.
        reason: Why it stopped early, when no signal did (e.g. no worker left), or None.
    """

    directory: Path
    total: int
    skipped: int
    ran: int
    failed: int
    interrupted: bool
    tables: list[Path]
    signum: int | None = None
    reason: str | None = None


def run_task(task: Mapping[str, Any]) -> dict[str, Any]:
    """Run one campaign run and return its record (never raises).

    Args:
        task: ``run_id``, ``index``, ``scene`` (base table), ``scene_ref``, ``parameters``
            (dotted key -> value), ``metrics`` (list of (name, spec)), ``success``
            (criterion text or None), ``python_path``, and optionally ``reuse`` (default
            True: the integrator and controller come from this process's
            :data:`~ucontrol.campaign.build_cache.WORKER_CACHE` where the run allows).

    Returns:
        ``run_id``, ``index``, ``parameters``, ``metrics``, ``success``, ``status``
        (``"ok"`` or ``"error"``), ``error`` (exception text, empty when ok),
        ``wall_time_s``, ``worker`` (host:pid) and, once the run's objects are made,
        ``build`` (``"integrator"`` and ``"controller"``: ``"built"`` or ``"reused"``).
    """
    start = time.perf_counter()
    record: dict[str, Any] = {
        "run_id": task["run_id"],
        "index": task["index"],
        "parameters": dict(task["parameters"]),
        "metrics": {},
        "success": False,
        "status": OK,
        "error": "",
        "wall_time_s": 0.0,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }
    try:
        path = scene_file(task["scene_ref"])
        table = apply_overrides(task["scene"], task["parameters"])
        if task.get("reuse", True):
            result, record["build"] = simulate_cached(table, path)
        else:
            from ucontrol.scene import Scene
            from ucontrol.simulate import simulate

            scene = Scene.from_dict(table, base_dir=path.parent, default_name=path.stem)
            result = simulate(scene, progress=False)
            record["build"] = {INTEGRATOR: BUILT, CONTROLLER: BUILT}
        python_path = tuple(task.get("python_path", ()))
        metrics = {
            name: Metric(name, spec).evaluate(result, python_path) for name, spec in task["metrics"]
        }
        record["metrics"] = metrics
        success = task.get("success")
        record["success"] = True if success is None else parse_criterion(success)(metrics)
    except Exception as error:  # a failing run is data: record it, never re-raise
        record["status"] = ERROR
        record["error"] = f"{type(error).__name__}: {error}"
        record["traceback"] = traceback.format_exc(limit=8)
    record["wall_time_s"] = time.perf_counter() - start
    return record


def simulate_cached(
    table: dict[str, Any], path: Path, cache: BuildCache = WORKER_CACHE
) -> tuple[Any, dict[str, str]]:
    """Run the scene ``table`` (from file ``path``) with builds of ``cache`` where it has them.

    The integrator and the controller are taken from ``cache`` under the run's keys and
    families (:mod:`~ucontrol.campaign.build_cache`), given the run's numbers where they were
    built for others (its constraints', its controller's believed inertias) and reset, or
    built; they go back to it after the run.

    Returns:
        The :class:`~ucontrol.simulate.SimulationResult` and, per kind, whether the object
        was ``"built"`` or ``"reused"``. Objects go back to the cache only after a run that
        completed (a failed run's are dropped).
    """
    from ucontrol.scene.controller_builders import retarget_controller
    from ucontrol.simulate import simulate

    scene, keys, families = _cached_scene(table, path)
    build = {}
    integrator = cache.checkout(
        INTEGRATOR,
        keys[INTEGRATOR],
        families[INTEGRATOR],
        lambda cached: cached.use_constraints(scene.constraints),
    )
    if integrator is None:
        integrator, build[INTEGRATOR] = scene.build_integrator(), BUILT
    else:
        integrator.reset()  # no step memory, no warm starts: as a fresh build
        build[INTEGRATOR] = REUSED
    controller = cache.checkout(
        CONTROLLER,
        keys[CONTROLLER],
        families[CONTROLLER],
        lambda cached: retarget_controller(cached, scene),
    )
    if controller is None:
        controller, build[CONTROLLER] = scene.build_controller(), BUILT
    else:
        controller.reset()
        build[CONTROLLER] = REUSED
    result = simulate(scene.use_integrator(integrator), controller, progress=False)
    _keep(cache, keys, families, integrator, controller)
    return result, build


def prepare_worker(task: Mapping[str, Any], cache: BuildCache = WORKER_CACHE) -> str:
    """Ready this process for a campaign's runs: imports, libraries and the first run's builds.

    Run on each worker of a local cluster before any run (``Client.run``): it imports
    :data:`WORKER_IMPORTS`, builds the integrator and the controller of ``task`` (a run's
    task, as for :func:`run_task`), which imports their modules and loads their compiled
    libraries, and runs the first steps of that run (its sensors' delay and two more) with its
    summary, which imports and loads what a run's steps and summary do (the sensors' noise
    generators, the analyses of the summary). With ``reuse`` (the default) both objects are
    kept in ``cache`` for the runs of their families, which reset them as after a run (their
    logs are those of fresh builds); without, they are dropped. Nothing is written and nothing
    raises: a task whose builds or first steps fail is left to its run, which records the
    error (its objects are dropped).

    Returns:
        The error of the builds or steps as ``"Type: message"``, or ``""``.
    """
    import importlib

    from ucontrol.simulate import simulate

    for module in WORKER_IMPORTS:
        importlib.import_module(module)
    try:
        path = scene_file(task["scene_ref"])
        table = apply_overrides(task["scene"], task["parameters"])
        scene, keys, families = _cached_scene(table, path)
        integrator, controller = scene.build_integrator(), scene.build_controller()
        delay = 0 if scene.sensors is None else scene.sensors.delay  # [control periods]
        duration = (delay + 2) * integrator.dt  # [s] (every step a control period)
        simulate(scene.use_integrator(integrator), controller, duration, progress=False)
    except Exception as error:  # the run builds again and records it
        return f"{type(error).__name__}: {error}"
    if task.get("reuse", True):
        _keep(cache, keys, families, integrator, controller)
    return ""


def _cached_scene(table: dict[str, Any], path: Path) -> tuple[Any, dict[str, str], dict[str, str]]:
    """The scene of ``table`` (from file ``path``) that takes a built integrator, and its keys.

    Its keys and its families, by kind (:mod:`~ucontrol.campaign.build_cache`).
    """
    from ucontrol.campaign.prebuilt_scene import PrebuiltScene

    built = PrebuiltScene.from_dict(table, base_dir=path.parent, default_name=path.stem)
    scene = cast(PrebuiltScene, built)  # from_dict builds the class it is called on
    where = str(path)
    keys = {INTEGRATOR: integrator_key(where, table), CONTROLLER: controller_key(where, table)}
    families = {
        INTEGRATOR: integrator_family(where, table),
        CONTROLLER: controller_family(where, table),
    }
    return scene, keys, families


def _keep(
    cache: BuildCache,
    keys: Mapping[str, str],
    families: Mapping[str, str],
    integrator: Any,
    controller: Any,
) -> None:
    """Put the objects that can be reset into ``cache`` under their keys and families."""
    if reusable_integrator(integrator):
        cache.checkin(INTEGRATOR, keys[INTEGRATOR], integrator, families[INTEGRATOR])
    if reusable_controller(controller):
        cache.checkin(CONTROLLER, keys[CONTROLLER], controller, families[CONTROLLER])


def run_campaign(
    campaign: Campaign,
    out: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    client: Any = None,
    formats: tuple[str, ...] = ("csv",),
    progress: bool | None = None,
    worker_timeout: float = NO_WORKER_TIMEOUT_S,
    reuse: bool = True,
) -> CampaignOutcome:
    """Run the runs of ``campaign`` not yet in ``out`` and write the campaign table.

    Args:
        campaign: A checked campaign (:func:`ucontrol.campaign.load_campaign`).
        out: Output directory: ``campaign.json``, ``plan.csv``, ``runs/<run_id>.json``,
            ``campaign.csv`` (and ``campaign.parquet``).
        scheduler: Address of a running Dask scheduler (``tcp://host:8786``); None starts a
            ``LocalCluster`` of ``workers`` single-threaded processes.
        workers: Worker processes of the local cluster; default the number of cores.
        client: An existing ``distributed.Client`` to use instead (not closed here).
        formats: Table formats, ``"csv"`` and/or ``"parquet"``.
        progress: Show a progress bar; default only when stderr is a terminal.
        worker_timeout: Longest wait in [s] with no worker connected while runs are pending;
            then the campaign stops as interrupted, with the reason.
        reuse: Let each worker reuse the integrator and controller of its earlier runs where
            the overrides leave them as built (:mod:`ucontrol.campaign.build_cache`); False
            builds both for every run. The records are the same either way.

    Raises:
        OutputDirectoryError: ``out`` cannot be created or written.
        CampaignMismatchError: ``out`` holds another campaign.
        SchedulerUnreachableError: No scheduler answered at ``scheduler``.
    """
    from ucontrol.campaign.table import check_formats

    check_formats(formats)
    worker_timeout = as_positive("worker_timeout", worker_timeout)
    directory = prepare_directory(campaign, out)
    plan = campaign.plan()
    done = finished_runs(directory)
    pending = [run for run in plan if run.run_id not in done]
    skipped = len(plan) - len(pending)
    ran = failed = 0
    interrupted, signum, reason = False, None, None
    if pending:
        with _signals():  # installed first: a SIGTERM while the cluster starts is handled too
            try:
                tasks = _tasks(campaign, pending, reuse)
                with _client(client, scheduler, workers, tasks) as dask_client:
                    bar = _progress_bar(len(plan), skipped, progress)
                    try:
                        records = _results(dask_client, campaign, pending, tasks, worker_timeout)
                        for record in records:
                            if isinstance(record, str):  # no worker left: stop
                                reason = record
                                break
                            write_record(directory, record)
                            ran += 1
                            failed += record["status"] != OK
                            if bar is not None:
                                bar.update(1)
                                bar.set_postfix(failed=failed, refresh=False)
                    finally:
                        if bar is not None:
                            bar.close()
            except KeyboardInterrupt as interrupt:  # Ctrl-C, SIGTERM, SIGHUP: cluster closed
                interrupted = True
                signum = int(getattr(interrupt, "signum", signal.SIGINT))
        interrupted = interrupted or ran < len(pending)  # e.g. runs cancelled with a scheduler
    tables = write_table(directory, formats)
    return CampaignOutcome(
        directory, len(plan), skipped, ran, failed, interrupted, tables, signum, reason
    )


def prepare_directory(campaign: Campaign, out: str | Path) -> Path:
    """Create ``out`` with its ``runs`` folder and record the campaign there.

    Raises:
        OutputDirectoryError: It cannot be created or written.
        CampaignMismatchError: It already records another campaign.
        CampaignFileError: Its ``campaign.json`` is not a JSON object (delete it to start
            again).
    """
    directory = Path(out)
    fingerprint = campaign.fingerprint()
    try:
        (directory / RUNS_DIR).mkdir(parents=True, exist_ok=True)
        probe = directory / f".write-probe-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError as error:
        raise OutputDirectoryError(str(directory), error.strerror or str(error)) from error
    if (directory / CAMPAIGN_FILE).is_file():
        found = str(read_campaign(directory).get("fingerprint", ""))
        if found != fingerprint:
            raise CampaignMismatchError(str(directory), found, fingerprint)
        return directory
    plan = campaign.plan()
    record = {
        "name": campaign.name,
        "fingerprint": fingerprint,
        "source": None if campaign.source is None else str(campaign.source),
        "scene": campaign.scene_ref,
        "scene_path": str(scene_file(campaign.scene_ref)),
        "duration": campaign.scene_table.get("duration"),
        "dt": campaign.scene_table.get("integrator", {}).get("dt"),
        "seed": campaign.seed,
        "runs": len(plan),
        "parameters": campaign.parameter_names,
        "grid": campaign.grid,
        "metrics": {m.name: m.spec for m in campaign.metrics},
        "success": None if campaign.criterion is None else campaign.criterion.expression,
        "worst": campaign.worst,
    }
    _write_json(directory / CAMPAIGN_FILE, record)
    _write_plan(directory / PLAN_FILE, campaign.parameter_names, plan)
    return directory


def write_record(directory: Path, record: Mapping[str, Any]) -> Path:
    """Write one run's record to ``runs/<run_id>.json`` atomically (temp file + rename)."""
    return _write_json(directory / RUNS_DIR / f"{record['run_id']}.json", record)


def connect(address: str, timeout: float = CONNECT_TIMEOUT_S) -> Any:
    """A ``distributed.Client`` connected to ``address``.

    Raises:
        SchedulerUnreachableError: Nothing answered within ``timeout`` seconds.
    """
    from distributed import Client

    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError, ValueError, TypeError) as error:
        raise SchedulerUnreachableError(address, str(error) or type(error).__name__) from error


def _tasks(campaign: Campaign, pending: list[Any], reuse: bool) -> list[dict[str, Any]]:
    """The task of each pending run (:func:`run_task`'s argument)."""
    return [
        {
            "run_id": run.run_id,
            "index": run.index,
            "scene": campaign.scene_table,
            "scene_ref": campaign.scene_ref,
            "parameters": run.parameters,
            "metrics": [(m.name, m.spec) for m in campaign.metrics],
            "success": None if campaign.criterion is None else campaign.criterion.expression,
            "python_path": list(campaign.python_path),
            "reuse": reuse,
        }
        for run in pending
    ]


def _results(
    client: Any,
    campaign: Campaign,
    pending: list[Any],
    tasks: list[dict[str, Any]],
    worker_timeout: float,
) -> Iterator[dict[str, Any] | str]:
    """Submit the pending runs (their ``tasks``) and yield each record as its run ends.

    When no worker has been connected for ``worker_timeout`` seconds, the reason is yielded
    (a text) instead, and the runs left are cancelled.
    """
    tag = campaign.fingerprint()[:10]
    keys = [f"ucontrol-run-{tag}-{run.run_id}" for run in pending]
    futures = client.map(run_task, tasks, key=keys, pure=False)
    by_key = {future.key: (task, future) for task, future in zip(tasks, futures, strict=True)}
    try:
        for future in _as_completed(client, futures, worker_timeout):
            if isinstance(future, str):
                yield future
                return
            task, _ = by_key[future.key]
            if future.status == "cancelled":  # lost with the scheduler: run again on resume
                continue
            if future.status == "finished":
                yield future.result()
            else:  # the task never returned: its worker died (KilledWorker) or it was lost
                error = future.exception()
                yield {
                    "run_id": task["run_id"],
                    "index": task["index"],
                    "parameters": task["parameters"],
                    "metrics": {},
                    "success": False,
                    "status": KILLED if type(error).__name__ == "KilledWorker" else ERROR,
                    "error": f"{type(error).__name__}: {error}",
                    "wall_time_s": float("nan"),
                    "worker": "",
                }
            future.release()
    finally:
        client.cancel([f for _, f in by_key.values() if not f.done()])


def _as_completed(client: Any, futures: list[Any], worker_timeout: float) -> Iterator[Any]:
    """The futures as they complete; a text instead once no worker came for too long."""
    from distributed import as_completed

    completed = as_completed(futures)
    last_worker = time.monotonic()
    while not completed.is_empty():
        if completed.has_ready():
            for future in completed.next_batch(block=False):
                if future.status in ("pending", "lost"):  # its result died with a worker
                    completed.add(future)
                else:
                    yield future
            continue
        now = time.monotonic()
        if client.scheduler_info(n_workers=1)["workers"]:
            last_worker = now
        elif now - last_worker > worker_timeout:
            yield (
                f"no Dask worker connected for {worker_timeout:g} s with "
                f"{completed.count()} run(s) pending"
            )
            return
        time.sleep(_POLL_S)


@contextmanager
def _client(
    client: Any, scheduler: str | None, workers: int | None, tasks: list[dict[str, Any]]
) -> Iterator[Any]:
    """The given client, a client of ``scheduler``, or a new LocalCluster's.

    A new LocalCluster has at most one worker per task, each readied for the first task by
    :func:`prepare_worker` before any run.
    """
    if client is not None:
        yield client
        return
    if scheduler is not None:
        remote = connect(scheduler)
        try:
            yield remote
        finally:
            remote.close()
        return
    import dask
    from distributed import Client, LocalCluster

    n = max(1, min(workers or os.cpu_count() or 1, len(tasks)))
    with dask.config.set(CLUSTER_SETTINGS):
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=40,  # logging.ERROR: a killed worker's traceback is recorded instead
        )
    local = Client(cluster)
    try:
        local.run(prepare_worker, tasks[0])
        yield local
    finally:
        local.close()
        cluster.close()


class _Signalled(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised like Ctrl-C so that the table is written."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextmanager
def _signals() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`_Signalled` in the main thread while a campaign runs."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: Any) -> None:
        raise _Signalled(signum)

    previous = {signum: signal.signal(signum, interrupt) for signum in _STOP_SIGNALS}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _progress_bar(total: int, initial: int, progress: bool | None) -> Any:
    if progress is False or (progress is None and not sys.stderr.isatty()):
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="run", desc="campaign")


def _write_json(path: Path, content: Mapping[str, Any]) -> Path:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(content, indent=1, default=_jsonable) + "\n")
    os.replace(tmp, path)
    return path


def _write_plan(path: Path, names: list[str], plan: list[Any]) -> None:
    import csv
    import io

    buffer = io.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(["run_id", "index", *names])
    for run in plan:
        writer.writerow([run.run_id, run.index, *(json.dumps(run.parameters[n]) for n in names)])
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(buffer.getvalue())
    os.replace(tmp, path)


def _jsonable(value: Any) -> Any:
    if hasattr(value, "item"):
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)
