"""The thesis's experiments (6.4–6.8) as a campaign: their metrics and their report."""
