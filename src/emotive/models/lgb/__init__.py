"""Local Grid Bootstrap resampling of end-effector trajectories (issue 7, section 2).

* :mod:`~emotive.models.lgb.bootstrap`: :class:`LocalGridBootstrap` of one process.
* :mod:`~emotive.models.lgb.features`: feature rows of a clip (chain layout, anchors, links).
* :mod:`~emotive.models.lgb.blending`: the closed sequence of the clips and the fading of jumps.
* :mod:`~emotive.models.lgb.resampler`: :class:`EmotionResampler`, per-emotion closed
  trajectories resampled by four processes.
* :mod:`~emotive.models.lgb.rebuild`: the IK rebuild in chunks, in worker processes.
* :mod:`~emotive.models.lgb.novelty`: the not-a-replay measure and guard.

Import the submodules; this package imports nothing heavy.
"""
