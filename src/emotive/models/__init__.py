"""Generative motion models.

* :mod:`~emotive.models.gait`: the affect-based autoregression network of Emotive Gaits
  (Bhattacharya et al. 2020), its config and its losses.
"""
