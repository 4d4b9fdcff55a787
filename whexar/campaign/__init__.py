"""Campaigns: many simulated runs of one base scenario, on local processes or on Ray.

A campaign file (:mod:`whexar.campaign.spec`) names a base scenario, the
variations to run it with and the metrics to keep (:mod:`whexar.campaign.metrics`);
:func:`run_campaign` (:mod:`whexar.campaign.runner`) runs them and writes one row
per run (:mod:`whexar.campaign.results`). ``whexar campaign FILE`` is the command.

May import: :mod:`whexar.sim` and everything below it; Ray only inside the functions
that use it (an optional extra); never the command line or the benches.
"""

from whexar.campaign.metrics import Metric, Value, Window, metric, registry
from whexar.campaign.rows import CampaignResult, Row
from whexar.campaign.runner import Progress, default_workers, run_campaign, run_one
from whexar.campaign.spec import Campaign, RunSpec, campaign_names, load_campaign, parse_campaign

__all__ = [
    "Campaign",
    "CampaignResult",
    "Metric",
    "Progress",
    "Row",
    "RunSpec",
    "Value",
    "Window",
    "campaign_names",
    "default_workers",
    "load_campaign",
    "metric",
    "parse_campaign",
    "registry",
    "run_campaign",
    "run_one",
]
