"""Per-frame motion features: pose affective features, foot contacts and movement features.

* :mod:`~emotive.features.affective`: the 18 pose affective features (torch kernel + NumPy).
* :mod:`~emotive.features.contacts`: foot contacts from heel and toe height and speed.
* :mod:`~emotive.features.movement`: root joint and stepping features of the paper.
"""

from emotive.features.affective import (
    AFFECTIVE_FEATURE_KINDS,
    AFFECTIVE_FEATURE_NAMES,
    AFFECTIVE_ROLES,
    affective_features,
    affective_features_np,
)
from emotive.features.contacts import (
    CONTACT_NAMES,
    FOOT_ROLES,
    ContactThresholds,
    foot_contacts,
    foot_positions,
    foot_strikes,
)
from emotive.features.movement import (
    MOVEMENT_FEATURE_NAMES,
    MovementFeatures,
    movement_features,
    stepping_phase,
)

__all__ = [
    "AFFECTIVE_FEATURE_KINDS",
    "AFFECTIVE_FEATURE_NAMES",
    "AFFECTIVE_ROLES",
    "CONTACT_NAMES",
    "FOOT_ROLES",
    "MOVEMENT_FEATURE_NAMES",
    "ContactThresholds",
    "MovementFeatures",
    "affective_features",
    "affective_features_np",
    "foot_contacts",
    "foot_positions",
    "foot_strikes",
    "movement_features",
    "stepping_phase",
]
