"""The thesis's experiments (6.4–6.8) as a campaign: their metrics, figures and report.

Theory of operation
-------------------
The campaign ``config/campaigns/experiments.toml`` repeats in simulation what
Žák 2023 measured on WHexaR: the tripod gait on the flat (6.4, 6.8.1), riding
straight, sideways, spinning in place and along a circle (6.5), the static
stances of Table 6.6 and the movements of Table 6.7 on slopes, with and
without the trochanter (6.8), and the steepest slope walked, ridden and stood
on (6.7.6).

What the thesis measured and how we explain each difference is data, beside
the campaign: ``config/campaigns/reference/experiments.toml``. The code is in
five parts, each importing only those above it:

* :mod:`~whexar.campaign.experiments.metrics` — the experiments' own metrics
  (total current, speed up the plane, cost of transport, gait period …),
  registered by name when this package is imported;
* :mod:`~whexar.campaign.experiments.reference` — the data file's models,
  validated at load;
* :mod:`~whexar.campaign.experiments.figures` — finds the campaign's rows the
  reference names, judges each run's outcome (made it, held) and sets the
  simulation's figures beside the thesis's, with a note where they differ;
* :mod:`~whexar.campaign.experiments.agreement` — the table summed up: the median
  deviation, the figures more than 2× off, the ranges and bounds missed;
* :mod:`~whexar.campaign.experiments.plots` and
  :mod:`~whexar.campaign.experiments.report` — the plots, the table and
  ``experiments.md``.

May import: what :mod:`whexar.campaign` may (the simulation and everything below
it) and the campaign's own modules; never the command line or the benches.
"""

from whexar.campaign.experiments.agreement import Agreement, agreement
from whexar.campaign.experiments.figures import (
    SLOPE_KEY,
    TROCHANTER_KEY,
    Figure,
    commanded_speed,
    figures,
    held,
    made_it,
    steepest,
)
from whexar.campaign.experiments.metrics import (
    circle_reckoned_return_m,
    circle_return_m,
    gait_period_s,
    spin_rpm,
    thesis_cost_of_transport,
    time_to_2m_s,
    top_speed_mps,
    total_current_a,
    travel_direction_deg,
    uphill_speed_mps,
    winding_current_a,
)
from whexar.campaign.experiments.reference import (
    REFERENCE_PATH,
    Reference,
    load_reference,
    parse_reference,
    reference,
)
from whexar.campaign.experiments.report import (
    json_document,
    report_markdown,
    table_markdown,
    table_text,
    write_report,
)

__all__ = [
    "REFERENCE_PATH",
    "SLOPE_KEY",
    "TROCHANTER_KEY",
    "Agreement",
    "Figure",
    "Reference",
    "agreement",
    "circle_reckoned_return_m",
    "circle_return_m",
    "commanded_speed",
    "figures",
    "gait_period_s",
    "held",
    "json_document",
    "load_reference",
    "made_it",
    "parse_reference",
    "reference",
    "report_markdown",
    "spin_rpm",
    "steepest",
    "table_markdown",
    "table_text",
    "thesis_cost_of_transport",
    "time_to_2m_s",
    "top_speed_mps",
    "total_current_a",
    "travel_direction_deg",
    "uphill_speed_mps",
    "winding_current_a",
    "write_report",
]
