"""Synthetic rigs shared by the tests (imported by name: ``tests/`` is on the path)."""

#: A small Bandai-named rig: (name, parent, offset in metres, end-site offset or None).
RIG = (
    ("Hips", -1, (0, 0.95, 0), None),
    ("Spine", 0, (0, 0.1, 0), None),
    ("Chest", 1, (0, 0.2, 0), None),
    ("Neck", 2, (0, 0.25, 0), None),
    ("Head", 3, (0, 0.1, 0), (0, 0.15, 0)),
    ("UpperArm_L", 2, (0.18, 0.2, 0), None),
    ("LowerArm_L", 5, (0, -0.28, 0), None),
    ("Hand_L", 6, (0, -0.25, 0), (0, -0.08, 0)),
    ("UpperArm_R", 2, (-0.18, 0.2, 0), None),
    ("LowerArm_R", 8, (0, -0.28, 0), None),
    ("Hand_R", 9, (0, -0.25, 0), (0, -0.08, 0)),
    ("UpperLeg_L", 0, (0.1, 0, 0), None),
    ("LowerLeg_L", 11, (0, -0.42, 0), None),
    ("Foot_L", 12, (0, -0.42, 0), None),
    ("Toes_L", 13, (0, -0.08, 0.12), (0, 0, 0.05)),
    ("UpperLeg_R", 0, (-0.1, 0, 0), None),
    ("LowerLeg_R", 15, (0, -0.42, 0), None),
    ("Foot_R", 16, (0, -0.42, 0), None),
    ("Toes_R", 17, (0, -0.08, 0.12), (0, 0, 0.05)),
)
