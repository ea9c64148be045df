"""Campaigns: sweeps and Monte Carlo over scenes on dask.distributed.

A campaign file (TOML, ``docs/campaigns.md``) names a base scene, the dotted scene keys to sweep
(a grid, or distributions with a seed), the metrics to collect and a success criterion.
:func:`load_campaign` checks all of it before any run; :func:`run_campaign` runs it on a local
cluster or an existing scheduler, one file per finished run, resumable; :func:`load` reads the
table back. ``import ucontrol`` does not import this package; dask and distributed are imported
only when a campaign runs, pandas only when a table is built.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names
from ucontrol.exceptions import (
    CampaignError,
    CampaignFileError,
    CampaignMismatchError,
    CriterionError,
    DistributionError,
    EmptyGridError,
    OutputDirectoryError,
    ParameterKeyError,
    SchedulerUnreachableError,
    UnknownMetricError,
)

if TYPE_CHECKING:
    from ucontrol.campaign.overrides import apply_overrides
    from ucontrol.campaign.runner import CampaignOutcome, run_campaign, run_task
    from ucontrol.campaign.spec import Campaign, PlannedRun, check_campaign, load_campaign
    from ucontrol.campaign.table import load, wilson_interval

#: Each public name and its module, imported on first use (``ucontrol run --set`` and the
#: command line's parser import single modules of the package, not the runner).
_EXPORTS = {
    "Campaign": "ucontrol.campaign.spec",
    "CampaignOutcome": "ucontrol.campaign.runner",
    "PlannedRun": "ucontrol.campaign.spec",
    "apply_overrides": "ucontrol.campaign.overrides",
    "check_campaign": "ucontrol.campaign.spec",
    "load": "ucontrol.campaign.table",
    "load_campaign": "ucontrol.campaign.spec",
    "run_campaign": "ucontrol.campaign.runner",
    "run_task": "ucontrol.campaign.runner",
    "wilson_interval": "ucontrol.campaign.table",
}

__all__ = [
    "Campaign",
    "CampaignError",
    "CampaignFileError",
    "CampaignMismatchError",
    "CampaignOutcome",
    "CriterionError",
    "DistributionError",
    "EmptyGridError",
    "OutputDirectoryError",
    "ParameterKeyError",
    "PlannedRun",
    "SchedulerUnreachableError",
    "UnknownMetricError",
    "apply_overrides",
    "check_campaign",
    "load",
    "load_campaign",
    "run_campaign",
    "run_task",
    "wilson_interval",
]


__getattr__ = lazy_names(__name__, _EXPORTS)
