"""Local Grid Bootstrap resampling of end-effector trajectories (issue 7, section 2).

* :mod:`~emotive.models.lgb.bootstrap`: :class:`LocalGridBootstrap` of one process.
* :mod:`~emotive.models.lgb.model`: :class:`EmotionResampler`, per-emotion closed
  trajectories, four processes and the IK rebuild.

Import the submodules; this package imports nothing heavy.
"""
