"""QuaterNet (Pavllo et al. 2018), the baseline of Emotive Gaits sections 5.5-5.6 (Table 1).

A sub-package of the gait network's on purpose: the baseline is trained and evaluated through
the gait data, controls, losses and recipe, so that the comparison is between the networks.

* :mod:`~emotive.models.gait.quaternet.config`: :class:`QuaterNetConfig`, sizes, switches,
  weights.
* :mod:`~emotive.models.gait.quaternet.network`: :class:`QuaterNetwork`, a quaternion GRU with
  a streaming one-frame :meth:`~QuaterNetwork.step` and a teacher-forced window ``forward``.
* :mod:`~emotive.models.gait.quaternet.training`: :func:`train_quaternet` on the gait network's
  data and recipe, :func:`load_quaternet_checkpoint`, :func:`load_quaternet_settings`.
* :mod:`~emotive.models.gait.quaternet.predict`: :class:`QuaterNetPredictor`, the Table 1
  predictor.
"""

from emotive.models.gait.quaternet.config import QuaterNetConfig
from emotive.models.gait.quaternet.network import QuaterNetOutputs, QuaterNetwork

__all__ = ["QuaterNetConfig", "QuaterNetOutputs", "QuaterNetwork"]
