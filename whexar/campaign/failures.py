"""Single servo failures as a campaign: their metrics and their table."""
