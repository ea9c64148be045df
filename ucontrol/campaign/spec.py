"""Campaign files: parse, check every part before any run, and plan the runs.

The format is documented in ``docs/campaigns.md``. :func:`load_campaign` reads the file, checks
each table (typed errors from :mod:`ucontrol.exceptions` naming the value), builds the base
scene with every swept key set, runs it for two steps to learn the ``summary.json`` keys the
metrics may name, and returns a :class:`Campaign` whose :meth:`Campaign.plan` lists the runs.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ucontrol._validation import toml_error_message
from ucontrol.campaign.criterion import Criterion, parse_criterion
from ucontrol.campaign.distributions import Distribution, parse_distribution
from ucontrol.campaign.metrics import VERDICTS, Metric, check_metric
from ucontrol.campaign.overrides import apply_overrides, child, lookup, split_key
from ucontrol.exceptions import (
    CampaignError,
    CampaignFileError,
    EmptyGridError,
    NotFoundError,
    ParameterKeyError,
    UControlError,
    UnknownMetricError,
)

_TOP_KEYS = {"campaign", "grid", "distributions", "metrics"}
_CAMPAIGN_KEYS = {"name", "scene", "duration", "dt", "seed", "runs", "metrics", "success", "worst"}
#: Most runs a campaign may hold: its plan (parameters and seed per run) is built in memory
#: and every run writes one file, so a larger one is refused before it is planned.
MAX_RUNS = 100_000
#: Metrics collected when a campaign names none.
DEFAULT_METRICS = ("max_penetration", "n_impacts", "energy_increase_at_impacts")


@dataclass(frozen=True)
class PlannedRun:
    """One run of a campaign.

    Attributes:
        run_id: ``run-<index>``, zero-padded: the same for the same campaign file.
        index: Position in the plan, from 0.
        parameters: Dotted scene key -> value for this run.
    """

    run_id: str
    index: int
    parameters: dict[str, Any]


@dataclass(frozen=True)
class Campaign:
    """A checked campaign.

    Raises:
        CampaignFileError: It holds more than :data:`MAX_RUNS` runs.

    Attributes:
        name: Label (default the campaign file's stem).
        scene_table: The base scene's TOML table, with the campaign's duration and dt applied.
        scene_ref: Where the scene comes from: ``{"builtin": name}`` for a scene shipped with
            ucontrol (workers resolve it in their own installation) or ``{"path": file}``.
        seed: Seed of the Monte Carlo draws.
        runs: Monte Carlo runs per grid cell (1 without distributions).
        grid: Dotted key -> values; the runs cover their cartesian product.
        distributions: Monte Carlo parameters, drawn for every run.
        metrics: The columns to collect.
        criterion: The success criterion, or None (then a run succeeds when it completes).
        worst: Metric ranking the worst cases (largest first; prefix ``-`` for smallest
            first), or None: failures first, then the first metric.
        python_path: Folders searched first for user metric functions (the campaign file's).
        source: The campaign file, or None for a campaign built in code.
    """

    name: str
    scene_table: dict[str, Any]
    scene_ref: dict[str, str]
    seed: int = 0
    runs: int = 1
    grid: dict[str, list[Any]] = field(default_factory=dict)
    distributions: tuple[Distribution, ...] = ()
    metrics: tuple[Metric, ...] = ()
    criterion: Criterion | None = None
    worst: str | None = None
    python_path: tuple[str, ...] = ()
    source: Path | None = None

    def __post_init__(self) -> None:
        if self.size > MAX_RUNS:
            cells = math.prod(len(values) for values in self.grid.values())
            raise CampaignFileError(
                str(self.source or self.name),
                f"{self.size} runs ({cells} grid cell(s) x `runs` = {self.runs}), more than "
                f"the {MAX_RUNS} a campaign may hold: split it into several campaigns",
            )

    @property
    def parameter_names(self) -> list[str]:
        """The swept dotted keys: grid first, then distributions, in declaration order."""
        return [*self.grid, *(d.key for d in self.distributions)]

    @property
    def size(self) -> int:
        """Number of runs: grid cells times Monte Carlo runs."""
        return math.prod(len(values) for values in self.grid.values()) * self.runs

    def plan(self) -> list[PlannedRun]:
        """Every run with its parameters; the same seed gives the same plan."""
        cells = list(itertools.product(*self.grid.values())) or [()]
        width = max(5, len(str(self.size - 1)))
        planned = []
        for index in range(self.size):
            cell = cells[index // self.runs]
            parameters = dict(zip(self.grid, cell, strict=True))
            rng = np.random.default_rng([self.seed, index])
            for distribution in self.distributions:
                parameters[distribution.key] = distribution.sample(rng)
            planned.append(PlannedRun(f"run-{index:0{width}d}", index, parameters))
        return planned

    def fingerprint(self) -> str:
        """SHA-256 of the scene, the plan, the metrics and the criterion."""
        content = {
            "scene": self.scene_table,
            "scene_ref": self.scene_ref,
            "plan": [(run.run_id, run.parameters) for run in self.plan()],
            "metrics": [(m.name, m.spec) for m in self.metrics],
            "success": None if self.criterion is None else self.criterion.expression,
        }
        text = json.dumps(content, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def scene_base_dir(self) -> Path:
        """The folder the scene's relative paths (URDF) are taken from."""
        return scene_file(self.scene_ref).parent

    def scene_name(self) -> str:
        """The scene's default name (its file stem)."""
        return scene_file(self.scene_ref).stem


def scene_file(scene_ref: Mapping[str, str]) -> Path:
    """The scene file of a campaign, resolved on this machine."""
    if "builtin" in scene_ref:
        from ucontrol.scene import builtin_scene

        return builtin_scene(scene_ref["builtin"])
    return Path(scene_ref["path"])


def load_campaign(path: str | Path, *, check: bool = True) -> Campaign:
    """Read and check a campaign file.

    Args:
        path: The campaign TOML file, or the name of a campaign shipped with ucontrol
            (``"ball_restitution_campaign"``) that is no file of the working directory.
        check: Build the scene with each swept key and run it for two steps to check keys
            and metrics (the default); False only parses.

    Raises:
        CampaignFileError: Missing file, invalid TOML, unknown keys, bad seed/runs, unknown
            scene.
        ParameterKeyError: A dotted key does not address the scene, or the scene rejects it.
        DistributionError: A distribution's parameters are out of range.
        EmptyGridError: A grid parameter has no values.
        UnknownMetricError: A metric (or a name in the criterion) does not exist.
        CriterionError: The success criterion is not of the allowed form.
    """
    path = _campaign_file(Path(path))
    text = path.read_text()
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        reason = toml_error_message(error, text)
        raise CampaignFileError(str(path), f"not valid TOML: {reason}") from error
    campaign = parse_campaign(table, path)
    if check:
        check_campaign(campaign)
    return campaign


def _campaign_file(path: Path) -> Path:
    """The campaign file at ``path``, or the shipped campaign of that name.

    Raises:
        CampaignFileError: Neither exists (the message lists the shipped campaigns).
    """
    if path.is_file():
        return path
    if path.parent == Path(".") and path.suffix in ("", ".toml"):
        from ucontrol.scene.builtin_scenes import builtin_campaigns

        shipped = builtin_campaigns()
        if path.stem in shipped:
            return shipped[path.stem]
        raise CampaignFileError(
            str(path), f"the file does not exist, nor a shipped campaign: {', '.join(shipped)}"
        )
    raise CampaignFileError(str(path), "the file does not exist")


def parse_campaign(table: Mapping[str, Any], path: Path) -> Campaign:
    """A :class:`Campaign` from a parsed campaign table; no scene is built.

    :func:`check_campaign` then checks the keys and metrics against the scene.
    """
    where = str(path)
    _keys(where, "the file", table, _TOP_KEYS)
    head = table.get("campaign")
    if not isinstance(head, Mapping):
        raise CampaignFileError(where, "a [campaign] table with a `scene` key is required")
    _keys(where, "[campaign]", head, _CAMPAIGN_KEYS)
    if "scene" not in head:
        raise CampaignFileError(where, "[campaign] needs `scene` (a file or a built-in name)")
    scene_ref = _scene_ref(where, str(head["scene"]), path)
    scene_path = scene_file(scene_ref)
    scene_text = scene_path.read_text()
    try:
        scene_table = tomllib.loads(scene_text)
    except tomllib.TOMLDecodeError as error:
        reason = toml_error_message(error, scene_text)
        raise CampaignFileError(
            where, f"scene {str(scene_path)!r} is not valid TOML: {reason}"
        ) from error
    if "duration" in head:
        scene_table["duration"] = _positive(where, "duration", head["duration"])
    if "dt" in head:
        scene_table.setdefault("integrator", {})["dt"] = _positive(where, "dt", head["dt"])
    seed = head.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise CampaignFileError(where, f"`seed` must be an integer >= 0, got {seed!r}")
    grid = _grid(where, table.get("grid", {}))
    distributions_table = table.get("distributions", {})
    if not isinstance(distributions_table, Mapping):
        raise CampaignFileError(where, "[distributions] must be a table of tables")
    distributions = tuple(parse_distribution(k, v) for k, v in distributions_table.items())
    both = sorted(set(grid) & set(distributions_table))
    if both:
        raise ParameterKeyError(both[0], "declared both in [grid] and in [distributions]")
    for key in [*grid, *distributions_table]:
        split_key(key)
    runs = head.get("runs", 1)
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise CampaignFileError(where, f"`runs` must be an integer >= 1, got {runs!r}")
    if runs > 1 and not distributions:
        raise CampaignFileError(where, f"`runs` = {runs} needs [distributions] to draw from")
    criterion = None if "success" not in head else parse_criterion(head["success"])
    metrics = _metrics(where, head.get("metrics"), table.get("metrics", {}), criterion)
    clash = sorted({m.name for m in metrics} & {*grid, *distributions_table})
    if clash:
        raise CampaignFileError(where, f"{clash[0]!r} names both a metric and a parameter")
    worst = head.get("worst")
    if worst is not None and str(worst).removeprefix("-") not in {m.name for m in metrics}:
        raise UnknownMetricError(
            str(worst), "`worst` must name a collected metric", [m.name for m in metrics]
        )
    return Campaign(
        name=str(head.get("name", path.stem)),
        scene_table=scene_table,
        scene_ref=scene_ref,
        seed=seed,
        runs=runs,
        grid=grid,
        distributions=distributions,
        metrics=metrics,
        criterion=criterion,
        worst=None if worst is None else str(worst),
        python_path=(str(path.parent.resolve()),),
        source=path.resolve(),
    )


def check_campaign(campaign: Campaign) -> dict[str, Any]:
    """Check every swept key and every metric against the scene, before any run.

    Each key is set alone in the base scene (every grid and choice value; the middle of a
    continuous distribution) and the scene is built with its controller and integrator:
    unknown keys and rejected values raise. Then the scene with every key set runs two steps
    and the metrics are checked against its summary, which is returned.

    Raises:
        ParameterKeyError: Naming the dotted key and the scene's complaint.
        UnknownMetricError: Naming the metric and the keys available.
        CampaignError: The base scene itself cannot be built or run.
    """
    base_dir, name = campaign.scene_base_dir(), campaign.scene_name()
    _build(campaign.scene_table, base_dir, name, None)
    probes: dict[str, list[Any]] = {key: list(values) for key, values in campaign.grid.items()}
    for distribution in campaign.distributions:
        probes[distribution.key] = (
            list(distribution.values)
            if distribution.kind == "choice"
            else [distribution.representative()]
        )
    for key, values in probes.items():
        _check_path(campaign.scene_table, key)
        for value in values:
            _build(apply_overrides(campaign.scene_table, {key: value}), base_dir, name, key)
    representative = {key: values[0] for key, values in probes.items()}
    try:
        summary = _short_run(apply_overrides(campaign.scene_table, representative), base_dir, name)
    except CampaignError:  # e.g. a swept start inside an obstacle: that run will fail alone
        summary = _short_run(campaign.scene_table, base_dir, name)
    for metric in campaign.metrics:
        check_metric(metric, summary, campaign.python_path)
    return summary


def _check_path(table: Mapping[str, Any], key: str) -> None:
    """Walk the key in the base scene: array indices must exist, tables may be new."""
    parts = split_key(key)
    node: Any = table
    for depth, part in enumerate(parts[:-1]):
        if isinstance(node, Mapping) and isinstance(part, str) and part not in node:
            return  # a table the base scene lacks: the scene's own check decides
        node = child(node, part, key, depth)
    if isinstance(node, list) or isinstance(parts[-1], int):
        child(node, parts[-1], key, len(parts) - 1)


def _build(table: dict[str, Any], base_dir: Path, name: str, key: str | None) -> Any:
    from ucontrol.scene import Scene

    try:
        scene = Scene.from_dict(table, base_dir=base_dir, default_name=name)
        scene.build_controller()
        scene.build_integrator()
    except (UControlError, TypeError, ValueError) as error:
        if key is None:
            raise CampaignError(f"the base scene cannot be built: {error}") from error
        value = lookup(table, key) if _exists(table, key) else None
        raise ParameterKeyError(key, f"the scene rejects {value!r}: {error}") from error
    return scene


def _short_run(table: dict[str, Any], base_dir: Path, name: str) -> dict[str, Any]:
    from ucontrol.scene import Scene
    from ucontrol.simulate import simulate

    scene = Scene.from_dict(table, base_dir=base_dir, default_name=name)
    try:
        result = simulate(scene, duration=2.0 * scene.integrator.dt, progress=False)
    except UControlError as error:
        raise CampaignError(f"the scene cannot run two steps: {error}") from error
    return result.summary


def _exists(table: Mapping[str, Any], key: str) -> bool:
    try:
        lookup(table, key)
    except ParameterKeyError:
        return False
    return True


def _scene_ref(where: str, scene: str, campaign_path: Path) -> dict[str, str]:
    candidate = (campaign_path.parent / scene).resolve()
    if candidate.is_file() and candidate != campaign_path.resolve():
        return {"path": str(candidate)}
    from ucontrol.scene import builtin_scene

    try:
        builtin_scene(scene)
    except NotFoundError as error:
        raise CampaignFileError(
            where,
            f"scene {scene!r} is neither a file next to the campaign nor a built-in "
            f"scene ({', '.join(error.available)})",
        ) from error
    return {"builtin": scene}


def _grid(where: str, grid: Any) -> dict[str, list[Any]]:
    if not isinstance(grid, Mapping):
        raise CampaignFileError(where, "[grid] must be a table of lists")
    result = {}
    for key, values in grid.items():
        if not isinstance(values, Sequence) or isinstance(values, str) or not values:
            raise EmptyGridError(key, values)
        result[key] = list(values)
    return result


def _metrics(
    where: str, listed: Any, named: Any, criterion: Criterion | None
) -> tuple[Metric, ...]:
    if listed is not None and (
        not isinstance(listed, list) or not all(isinstance(m, str) for m in listed)
    ):
        raise CampaignFileError(
            where, f"[campaign] `metrics` must be a list of strings, got {listed!r}"
        )
    if not isinstance(named, Mapping) or not all(isinstance(v, str) for v in named.values()):
        raise CampaignFileError(where, "[metrics] must map column names to metric strings")
    metrics = {name: Metric(name, name) for name in (listed or [])}
    metrics.update({name: Metric(name, spec) for name, spec in named.items()})
    if listed is None and not named:
        metrics.update({name: Metric(name, name) for name in DEFAULT_METRICS})
    for name in criterion.names if criterion is not None else ():
        if name not in metrics:  # a name the criterion reads is collected too
            metrics[name] = Metric(name, name)
    return tuple(metrics.values())


def _keys(where: str, section: str, table: Any, allowed: set[str]) -> None:
    if not isinstance(table, Mapping):
        raise CampaignFileError(where, f"{section} must be a table")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise CampaignFileError(
            where,
            f"unknown key(s) {', '.join(map(repr, unknown))} in {section}; "
            f"allowed: {', '.join(sorted(allowed))}",
        )


def _positive(where: str, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise CampaignFileError(where, f"`{name}` must be a number > 0, got {value!r}")
    return float(value)


__all__ = ["VERDICTS", "Campaign", "PlannedRun", "check_campaign", "load_campaign"]
