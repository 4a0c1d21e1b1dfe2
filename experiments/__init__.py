"""Held-out measures of the models (``make evaluate``): each experiment runs as ``python -m experiments.NAME``
from the checkout, prints its table, and records it in ``results/NAME.json`` with the commit and a digest of the
data it read (:func:`experiments.common.record`). ``python -m experiments.render`` writes ``docs/results.md``
from those records."""
