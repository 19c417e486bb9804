"""Grasp transfer by non-rigid registration (Ch. 6): CPD, grasp transfer, classification, grasp
quality, orientation search, simulated perception and grasp trials."""
from robointel.learning.grasp.cpd import (AffineWarp, CPDResult, NonrigidWarp, RigidWarp, cpd_affine,
                                          cpd_nonrigid, cpd_rigid, farthest_point_sample, mean_nn_residual,
                                          register)

__all__ = ["AffineWarp", "CPDResult", "NonrigidWarp", "RigidWarp", "cpd_affine", "cpd_nonrigid", "cpd_rigid",
           "farthest_point_sample", "mean_nn_residual", "register"]
