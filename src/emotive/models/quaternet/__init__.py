"""QuaterNet (Pavllo et al. 2018), the baseline of Emotive Gaits sections 5.5-5.6.

* :mod:`~emotive.models.quaternet.config`: :class:`QuaterNetConfig`, sizes, switches, weights.
* :mod:`~emotive.models.quaternet.network`: :class:`QuaterNetwork`, a quaternion GRU with a
  streaming one-frame :meth:`~QuaterNetwork.step` and a teacher-forced window ``forward``.
* :mod:`~emotive.models.quaternet.training`: :func:`train_quaternet` on the gait network's data
  and recipe, :func:`load_quaternet_checkpoint`, :func:`load_quaternet_settings`.
"""

from emotive.models.quaternet.config import QuaterNetConfig
from emotive.models.quaternet.network import QuaterNetOutputs, QuaterNetwork

__all__ = ["QuaterNetConfig", "QuaterNetOutputs", "QuaterNetwork"]
