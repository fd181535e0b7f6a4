"""Divide and conquer (Huang, Wu & Lin): the finger configuration space, the manifold
proposal, the edge likelihood with an occlusion map, resampling, and the palm pose by ICP
and factorisation. The tracker is :mod:`digiteyes.trackers.divide_conquer`; see
docs/divide-and-conquer.md."""

from digiteyes.smc.configuration import ConfigurationSpace, PriorError, fit_configuration_space
from digiteyes.smc.likelihood import (
    FingerGeometry,
    LikelihoodOptions,
    LikelihoodResult,
    finger_log_likelihood,
    observe_edges,
)
from digiteyes.smc.manifolds import (
    ManifoldProjection,
    basis_joint_angles,
    basis_names,
    manifold_pairs,
    project_onto_manifolds,
)
from digiteyes.smc.palm import (
    IcpOptions,
    PalmFit,
    PalmPoseError,
    calibrate_palm_scale,
    icp_palm,
    palm_pose_from_correspondences,
    planar_pose_candidates,
)
from digiteyes.smc.prior import default_configuration_space, fit_glove_prior
from digiteyes.smc.proposal import Proposal, ProposalOptions, propose_on_manifolds
from digiteyes.smc.resample import effective_sample_size, normalised_weights, systematic_resample

__all__ = [
    "ConfigurationSpace", "FingerGeometry", "IcpOptions", "LikelihoodOptions",
    "LikelihoodResult", "ManifoldProjection", "PalmFit", "PalmPoseError", "PriorError",
    "Proposal", "ProposalOptions", "basis_joint_angles", "basis_names",
    "calibrate_palm_scale", "default_configuration_space", "effective_sample_size",
    "finger_log_likelihood", "fit_configuration_space", "fit_glove_prior", "icp_palm",
    "manifold_pairs", "normalised_weights", "observe_edges", "palm_pose_from_correspondences",
    "planar_pose_candidates", "project_onto_manifolds", "propose_on_manifolds",
    "systematic_resample",
]
