"""Factored Conditional RBM for affect-expressive movement (Alemi et al. 2015, issue 6).

* :mod:`~emotive.models.fcrbm.config`: :class:`FCRBMConfig`, sizes and training settings.
* :mod:`~emotive.models.fcrbm.model`: :class:`FCRBM` (contrastive divergence training and
  context-controlled generation) and :func:`sliding_windows`.

Import the submodule; this package imports nothing heavy.
"""
