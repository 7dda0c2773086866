"""Evaluation: motion metrics, study statistics, the perceived-emotion classifier and reports.

Modules:

* Batched motion metrics with documented formulas (conventions and input checks in
  :mod:`~emotive.eval.metric_inputs`): :mod:`~emotive.eval.pose_errors` (against ground
  truth), :mod:`~emotive.eval.feet`, :mod:`~emotive.eval.path_following`,
  :mod:`~emotive.eval.smoothness`, :mod:`~emotive.eval.stability` and
  :mod:`~emotive.eval.distributions`.
* Statistics of perceptual studies, through SciPy, statsmodels and pingouin:
  :mod:`~emotive.eval.stats` (sample comparisons), :mod:`~emotive.eval.anova` (mixed ANOVA) and
  :mod:`~emotive.eval.agreement` (rater agreement).
"""
