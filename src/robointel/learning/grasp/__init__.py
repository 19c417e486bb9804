"""Grasp transfer by non-rigid registration (Ch. 6).

CPD (6.3)-(6.13), grasp transfer (6.14)-(6.16), classification by registration residual (6.17)-(6.19),
grasp isotropy (6.20), orientation search (6.21), simulated depth cameras (Fig. 6.4) and MuJoCo
lift-and-shake trials (Table 6.2) with a 48 mm or an 85 mm parallel gripper chosen per object.
Helpers that are not part of the API stay in their modules (``robointel.learning.grasp.cpd`` etc.).
"""

from robointel.learning.grasp.classify import Classification, Fit, Template, classify, confusion_matrix, fit_template
from robointel.learning.grasp.cpd import (
    AffineWarp,
    CPDResult,
    NonrigidWarp,
    RigidWarp,
    cpd_affine,
    cpd_nonrigid,
    cpd_rigid,
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
    taught_grasps,
    toy_arm,
    ycb_object,
    ycb_objects,
)
from robointel.learning.grasp.perception import DepthCamera, default_cameras, depth_image, perceive
from robointel.learning.grasp.pipeline import (
    GraspPlan,
    GraspPlanner,
    lrmate_with_gripper,
    perceived_template,
)
from robointel.learning.grasp.quality import (
    NARROW_GRIPPER,
    WIDE_GRIPPER,
    GraspQuality,
    ParallelGripper,
    choose_gripper,
    grasp_quality,
    isotropy,
)
from robointel.learning.grasp.scene import Placement, arm_scene, random_placements, scene_xml
from robointel.learning.grasp.search import SearchResult, orientation_search
from robointel.learning.grasp.teaching import classifying_templates, holdable, seen_template, ycb_teaching_set
from robointel.learning.grasp.transfer import Grasp, grasp_from_axis, transfer_grasp, transfer_grasps
from robointel.learning.grasp.trial import GraspTrialResult, grasp_trial

__all__ = [
    # registration (6.3)-(6.13)
    "AffineWarp", "CPDResult", "NonrigidWarp", "RigidWarp", "cpd_affine", "cpd_nonrigid", "cpd_rigid",
    "mean_nn_residual", "register",
    # grasps and their transfer (6.14)-(6.16)
    "Grasp", "grasp_from_axis", "transfer_grasp", "transfer_grasps",
    # classification (6.17)-(6.19)
    "Classification", "Fit", "Template", "classify", "confusion_matrix", "fit_template",
    # grippers, quality (6.20) and orientation search (6.21)
    "NARROW_GRIPPER", "WIDE_GRIPPER", "GraspQuality", "ParallelGripper", "choose_gripper", "grasp_quality",
    "isotropy", "SearchResult", "orientation_search",
    # objects and the taught set
    "YCB_CATEGORIES", "ObjectModel", "demo_objects", "primitive_object", "sample_points", "sampled_grasps",
    "taught_grasps", "toy_arm", "ycb_object", "ycb_objects", "classifying_templates", "holdable",
    "seen_template", "ycb_teaching_set",
    # perception (Fig. 6.4) and scenes
    "DepthCamera", "default_cameras", "depth_image", "perceive", "Placement", "arm_scene", "random_placements",
    "scene_xml",
    # the pipeline and the lift-and-shake trial (Table 6.2)
    "GraspPlan", "GraspPlanner", "GraspTrialResult", "grasp_trial", "lrmate_with_gripper", "perceived_template",
]
