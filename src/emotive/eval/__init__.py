"""Evaluation: motion metrics, study statistics, the perceived-emotion classifier and reports.

Modules:

* :mod:`~emotive.eval.metrics` -- batched motion metrics with documented formulas.
* :mod:`~emotive.eval.stats` -- statistics of perceptual studies, through SciPy, statsmodels and
  pingouin.
"""
