"""Report layer: matplotlib figures and the self-contained HTML report. Only ``cli`` imports it."""
