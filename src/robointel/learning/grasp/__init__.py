"""Grasp transfer by non-rigid registration (Ch. 6): CPD (6.3)-(6.13), grasp transfer (6.14)-(6.16),
classification by registration residual (6.17)-(6.19), grasp isotropy (6.20), orientation search (6.21),
simulated depth cameras (Fig. 6.4) and MuJoCo lift-and-shake trials (Table 6.2).
"""
from robointel.learning.grasp.classify import (
                                               Classification,
                                               ComposedWarp,
                                               Fit,
                                               Template,
                                               classify,
                                               confusion_matrix,
                                               fit_template,
                                               normal_disagreement,
                                               yaw_matrix,
)
from robointel.learning.grasp.cpd import (
                                               AffineWarp,
                                               CPDResult,
                                               NonrigidWarp,
                                               RigidWarp,
                                               cpd_affine,
                                               cpd_nonrigid,
                                               cpd_rigid,
                                               farthest_point_sample,
                                               mean_nn_residual,
                                               register,
)
from robointel.learning.grasp.objects import (
                                               YCB_CATEGORIES,
                                               ObjectModel,
                                               demo_objects,
                                               primitive_object,
                                               sample_points,
                                               sampled_grasps,
                                               split_convex,
                                               taught_grasps,
                                               toy_arm,
                                               ycb_object,
                                               ycb_objects,
)
from robointel.learning.grasp.perception import (
                                               DepthCamera,
                                               cluster_objects,
                                               default_cameras,
                                               depth_image,
                                               foreground_points,
                                               perceive,
                                               voxel_downsample,
)
from robointel.learning.grasp.pipeline import (
                                               GraspPlan,
                                               GraspPlanner,
                                               TrialResult,
                                               grasp_trial,
                                               lrmate_with_gripper,
                                               perceived_template,
)
from robointel.learning.grasp.quality import (
                                               GraspQuality,
                                               ParallelGripper,
                                               estimate_normals,
                                               grasp_map,
                                               grasp_quality,
                                               isotropy,
)
from robointel.learning.grasp.scene import Placement, random_placements, scene_xml
from robointel.learning.grasp.search import SearchResult, orientation_search
from robointel.learning.grasp.transfer import Grasp, grasp_from_axis, nearest_rotation, transfer_grasp, transfer_grasps

__all__ = [
    "AffineWarp", "CPDResult", "NonrigidWarp", "RigidWarp", "cpd_affine", "cpd_nonrigid", "cpd_rigid",
    "farthest_point_sample", "mean_nn_residual", "register",
    "Grasp", "grasp_from_axis", "nearest_rotation", "transfer_grasp", "transfer_grasps",
    "Classification", "ComposedWarp", "Fit", "Template", "classify", "confusion_matrix", "fit_template", "yaw_matrix",
    "normal_disagreement",
    "GraspQuality", "ParallelGripper", "estimate_normals", "grasp_map", "grasp_quality", "isotropy",
    "SearchResult", "orientation_search",
    "YCB_CATEGORIES", "ObjectModel", "demo_objects", "primitive_object", "sample_points", "split_convex",
    "taught_grasps", "sampled_grasps", "toy_arm", "ycb_object", "ycb_objects",
    "DepthCamera", "cluster_objects", "default_cameras", "depth_image", "foreground_points", "perceive",
    "voxel_downsample", "Placement", "random_placements", "scene_xml",
    "GraspPlan", "GraspPlanner", "TrialResult", "grasp_trial", "lrmate_with_gripper", "perceived_template",
]
