"""Trajectories and per-chain inverse kinematics (issue 7, section 1).

Five IK chains (two legs, two arms with elbow targets, head-torso) with joint limits, a
damped least squares solver warm-started from the previous frame, extraction of pelvis,
end-effector and elbow trajectories in chain frames, and helpers built on them:
:func:`reconstruct` rebuilds a clip from its own trajectories, :func:`pin_feet` keeps planted
feet still (foot-plant cleanup for the generators), :func:`root_from_stance` rebuilds a
gliding root's path from the stance foot and :func:`~emotive.ik.floor.keep_above_floor` lifts
feet that sink under the floor. Chains work on any humanoid rig: consecutive chain
joints may have intermediate joints between them (CMU's ``Neck1``, Unreal's ``spine_02``), which
keep the clip's rotations (:func:`link_transforms`), and knee and elbow hinges count flexion
from the straight limb whatever the rig's joint frames.
"""

from emotive.ik.api import (
    IKResult,
    pin_feet,
    pin_feet_two_bone,
    rebuild,
    reconstruct,
    solve_chains,
)
from emotive.ik.chains import (
    CHAIN_NAMES,
    CHAIN_SPECS,
    Chain,
    ChainSpec,
    IKError,
    JointSpec,
    build_chain,
    link_transforms,
    resolve_chains,
)
from emotive.ik.solver import ChainSolution, Unreachable, solve_chain
from emotive.ik.stance_root import root_from_stance
from emotive.ik.trajectories import (
    PelvisTrajectory,
    Trajectories,
    chain_targets,
    extract_trajectories,
    integrate_pelvis,
    pelvis_trajectory,
    to_frame,
    to_world,
)

__all__ = [
    "CHAIN_NAMES",
    "CHAIN_SPECS",
    "Chain",
    "ChainSolution",
    "ChainSpec",
    "IKError",
    "IKResult",
    "JointSpec",
    "PelvisTrajectory",
    "Trajectories",
    "Unreachable",
    "build_chain",
    "chain_targets",
    "extract_trajectories",
    "integrate_pelvis",
    "link_transforms",
    "pelvis_trajectory",
    "pin_feet",
    "pin_feet_two_bone",
    "rebuild",
    "reconstruct",
    "resolve_chains",
    "root_from_stance",
    "solve_chain",
    "solve_chains",
    "to_frame",
    "to_world",
]
