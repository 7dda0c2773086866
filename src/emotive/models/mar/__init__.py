"""Realtime style transfer by online local mixtures of autoregressive models (Xia et al. 2015).

* :mod:`~emotive.models.mar.config`: :class:`MARConfig` (paper values) and
  :class:`TransferError`.
* :mod:`~emotive.models.mar.representation`: invariant pose vectors and point clouds.
* :mod:`~emotive.models.mar.registration`: time warping onto a reference, canonical time.
* :mod:`~emotive.models.mar.database`: the registered, annotated database and its index file.
* :mod:`~emotive.models.mar.build`: registering, annotating and indexing labelled examples.
* :mod:`~emotive.models.mar.default_index`: the cached index of the default data sets.
* :mod:`~emotive.models.mar.search`: equation 1 and the fast nearest-neighbour search.
* :mod:`~emotive.models.mar.regression`: local AR mixtures, bias, timing.
* :mod:`~emotive.models.mar.retarget`: other rigs through the joint roles.
* :mod:`~emotive.models.mar.transfer`: the streaming :class:`StyleTransfer` and
  :func:`transfer_motion`.

Import the submodules; this package imports nothing heavy.
"""
