r"""The campaign table: one row per finished run, read back from the run files.

Layout of a campaign directory::

    DIR/campaign.json        the campaign (scene, seed, parameters, metrics, fingerprint)
    DIR/plan.csv             every planned run and its parameters (JSON values)
    DIR/runs/<run_id>.json   one record per finished run, written as soon as it ends
    DIR/campaign.csv         the table (and campaign.parquet when asked for)

The table is rebuilt from the run files, so it is complete after an interruption too. Columns:
``run_id``, ``index``, one column per swept dotted key, one per metric, ``success``,
``status`` (``ok``, ``error``, ``killed``), ``error``, ``wall_time_s``, ``worker``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ucontrol.exceptions import (
    CampaignError,
    CampaignFileError,
    InvalidParameterError,
    OptionalDependencyError,
)

CAMPAIGN_FILE = "campaign.json"
PLAN_FILE = "plan.csv"
RUNS_DIR = "runs"
TABLE_FORMATS = ("csv", "parquet")
_STATUSES = {"ok", "error", "killed"}


def finished_runs(directory: str | Path) -> dict[str, dict[str, Any]]:
    """The records of ``DIR/runs/*.json`` by run id (unreadable files are skipped: re-run)."""
    records = {}
    for path in sorted(Path(directory, RUNS_DIR).glob("run-*.json")):
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if record.get("run_id") == path.stem and record.get("status") in _STATUSES:
            records[path.stem] = record
    return records


def read_campaign(directory: str | Path) -> dict[str, Any]:
    """The ``campaign.json`` of a campaign directory.

    Raises:
        CampaignError: The directory is not a campaign's.
        CampaignFileError: Its ``campaign.json`` is not a JSON object (truncated, edited).
    """
    path = Path(directory, CAMPAIGN_FILE)
    if not path.is_file():
        raise CampaignError(f"{str(directory)!r} is not a campaign directory (no {CAMPAIGN_FILE})")
    try:
        content = json.loads(path.read_text())
    except (OSError, ValueError) as error:  # ValueError: JSONDecodeError, UnicodeDecodeError
        raise CampaignFileError(str(path), f"not readable as JSON: {error}") from error
    if not isinstance(content, dict):
        raise CampaignFileError(str(path), f"not a JSON object, got {type(content).__name__}")
    return content


def load(directory: str | Path) -> Any:
    """The campaign table of a directory as a pandas DataFrame, one row per finished run.

    Raises:
        CampaignError: The directory is not a campaign's.
    """
    import pandas as pd

    info = read_campaign(directory)
    parameters, metrics = list(info["parameters"]), list(info["metrics"])
    rows = []
    for record in finished_runs(directory).values():
        row: dict[str, Any] = {"run_id": record["run_id"], "index": record["index"]}
        row.update({name: record["parameters"].get(name) for name in parameters})
        row.update({name: record["metrics"].get(name) for name in metrics})
        row.update(
            {
                "success": bool(record["success"]),
                "status": record["status"],
                "error": record.get("error", ""),
                "wall_time_s": record.get("wall_time_s"),
                "worker": record.get("worker", ""),
            }
        )
        rows.append(row)
    columns = [
        "run_id",
        "index",
        *parameters,
        *metrics,
        "success",
        "status",
        "error",
        "wall_time_s",
        "worker",
    ]
    frame = pd.DataFrame(rows, columns=columns)
    return frame.sort_values("index", ignore_index=True)


def check_formats(formats: tuple[str, ...] | list[str]) -> None:
    """Check table formats; Parquet needs pyarrow.

    Raises:
        InvalidParameterError: An unknown format.
        OptionalDependencyError: Parquet asked for without pyarrow.
    """
    for name in formats:
        if name not in TABLE_FORMATS:
            raise InvalidParameterError("--format", name, f"one of {list(TABLE_FORMATS)}")
    if "parquet" in formats:
        try:
            import pyarrow  # noqa: F401
        except ImportError as error:
            raise OptionalDependencyError("pyarrow", "parquet") from error


def write_table(directory: str | Path, formats: tuple[str, ...] = ("csv",)) -> list[Path]:
    """Write ``campaign.csv`` (and ``campaign.parquet``) from the run files; return the paths."""
    import os

    frame = load(directory)
    paths = []
    for name in formats:
        path = Path(directory, f"campaign.{name}")
        tmp = path.with_name(f".{path.name}.tmp")
        if name == "csv":
            frame.to_csv(tmp, index=False)
        else:
            _for_parquet(frame).to_parquet(tmp, index=False)
        os.replace(tmp, path)
        paths.append(path)
    return paths


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    r"""Wilson score interval of a success probability (95 % by default).

    .. math::
        \frac{\hat p + \frac{z^2}{2n} \pm z \sqrt{\frac{\hat p (1 - \hat p)}{n}
        + \frac{z^2}{4 n^2}}}{1 + \frac{z^2}{n}}, \qquad \hat p = k / n.

    Args:
        successes: Successful runs k.
        n: Runs n (0 gives the whole interval [0, 1]).
        z: Standard normal quantile (1.96 for 95 %).
    """
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    denominator = 1.0 + z * z / n
    centre = p + z * z / (2.0 * n)
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n))
    return max(0.0, (centre - half) / denominator), min(1.0, (centre + half) / denominator)


def _for_parquet(frame: Any) -> Any:
    """Object columns of mixed values (lists, None) as JSON text, which Parquet can hold."""
    frame = frame.copy()
    for column in frame.columns:
        if frame[column].dtype == object and column not in ("run_id", "status", "error", "worker"):
            frame[column] = [json.dumps(value) for value in frame[column]]
    return frame
