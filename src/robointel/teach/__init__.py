"""Part I (Ch. 3-4): imitation, compliance and kinesthetic teaching, F/T identification, key points.

Teleoperation (:mod:`.teleop`), streaming (:mod:`.streaming`) and the SCARA study (:mod:`.scara`) are
imported from their modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robointel._lazy import lazy_exports

if TYPE_CHECKING:  # the names below are imported on first access (keeps `import` light)
    from robointel.teach.compliance import ComplianceGains, compliance_velocity, damped_pinv
    from robointel.teach.ft_identification import FTCalibration, calibrate_in_workcell, identify_ft
    from robointel.teach.guidance import GuidanceConfig, GuidanceController, GuidanceStep
    from robointel.teach.imitation import ImitationPlan, ImitationRun, kinematic_imitation, simulate_imitation
    from robointel.teach.keypoints import (
        BlendedTrajectory,
        Reproduction,
        blended_trajectory,
        extract_keypoints,
        reproduce_path,
    )
    from robointel.teach.scenarios import Scenario, ScenarioResult, run_scenario, scenario
    from robointel.teach.skeleton import Skeleton, clean, load_skeleton

_EXPORTS = {
    "ComplianceGains": "robointel.teach.compliance",
    "compliance_velocity": "robointel.teach.compliance",
    "damped_pinv": "robointel.teach.compliance",
    "FTCalibration": "robointel.teach.ft_identification",
    "calibrate_in_workcell": "robointel.teach.ft_identification",
    "identify_ft": "robointel.teach.ft_identification",
    "GuidanceConfig": "robointel.teach.guidance",
    "GuidanceController": "robointel.teach.guidance",
    "GuidanceStep": "robointel.teach.guidance",
    "ImitationPlan": "robointel.teach.imitation",
    "ImitationRun": "robointel.teach.imitation",
    "kinematic_imitation": "robointel.teach.imitation",
    "simulate_imitation": "robointel.teach.imitation",
    "BlendedTrajectory": "robointel.teach.keypoints",
    "Reproduction": "robointel.teach.keypoints",
    "blended_trajectory": "robointel.teach.keypoints",
    "extract_keypoints": "robointel.teach.keypoints",
    "reproduce_path": "robointel.teach.keypoints",
    "Scenario": "robointel.teach.scenarios",
    "ScenarioResult": "robointel.teach.scenarios",
    "run_scenario": "robointel.teach.scenarios",
    "scenario": "robointel.teach.scenarios",
    "Skeleton": "robointel.teach.skeleton",
    "clean": "robointel.teach.skeleton",
    "load_skeleton": "robointel.teach.skeleton",
}

__all__ = [
    "BlendedTrajectory", "ComplianceGains", "FTCalibration", "GuidanceConfig", "GuidanceController",
    "GuidanceStep", "ImitationPlan", "ImitationRun", "Reproduction", "Scenario", "ScenarioResult", "Skeleton",
    "blended_trajectory", "calibrate_in_workcell", "clean", "compliance_velocity", "damped_pinv",
    "extract_keypoints", "identify_ft", "kinematic_imitation", "load_skeleton", "reproduce_path",
    "run_scenario", "scenario", "simulate_imitation",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
