"""Judging motion: comparing the conditions on a recording, reports, plots, the drawn-face previews and
the paired-comparison studies."""
