"""Part I (Ch. 3-4): imitation, compliance and kinesthetic teaching, F/T identification, key points.

Teleoperation (:mod:`.teleop`), streaming (:mod:`.streaming`) and the SCARA study (:mod:`.scara`) are
imported from their modules.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the names below are imported on first access (keeps `import` light)
    from robointel.programming.compliance import ComplianceGains, compliance_velocity, damped_pinv
    from robointel.programming.ft_identification import FTCalibration, calibrate_in_workcell, identify_ft
    from robointel.programming.guidance import GuidanceConfig, GuidanceController, GuidanceStep
    from robointel.programming.imitation import ImitationPlan, ImitationRun, kinematic_imitation, simulate_imitation
    from robointel.programming.keypoints import (
        BlendedTrajectory,
        Reproduction,
        blended_trajectory,
        extract_keypoints,
        reproduce_path,
    )
    from robointel.programming.scenarios import Scenario, ScenarioResult, run_scenario, scenario
    from robointel.programming.skeleton import Skeleton, clean, load_skeleton

_EXPORTS = {
    "ComplianceGains": "robointel.programming.compliance",
    "compliance_velocity": "robointel.programming.compliance",
    "damped_pinv": "robointel.programming.compliance",
    "FTCalibration": "robointel.programming.ft_identification",
    "calibrate_in_workcell": "robointel.programming.ft_identification",
    "identify_ft": "robointel.programming.ft_identification",
    "GuidanceConfig": "robointel.programming.guidance",
    "GuidanceController": "robointel.programming.guidance",
    "GuidanceStep": "robointel.programming.guidance",
    "ImitationPlan": "robointel.programming.imitation",
    "ImitationRun": "robointel.programming.imitation",
    "kinematic_imitation": "robointel.programming.imitation",
    "simulate_imitation": "robointel.programming.imitation",
    "BlendedTrajectory": "robointel.programming.keypoints",
    "Reproduction": "robointel.programming.keypoints",
    "blended_trajectory": "robointel.programming.keypoints",
    "extract_keypoints": "robointel.programming.keypoints",
    "reproduce_path": "robointel.programming.keypoints",
    "Scenario": "robointel.programming.scenarios",
    "ScenarioResult": "robointel.programming.scenarios",
    "run_scenario": "robointel.programming.scenarios",
    "scenario": "robointel.programming.scenarios",
    "Skeleton": "robointel.programming.skeleton",
    "clean": "robointel.programming.skeleton",
    "load_skeleton": "robointel.programming.skeleton",
}

__all__ = [
    "BlendedTrajectory", "ComplianceGains", "FTCalibration", "GuidanceConfig", "GuidanceController",
    "GuidanceStep", "ImitationPlan", "ImitationRun", "Reproduction", "Scenario", "ScenarioResult", "Skeleton",
    "blended_trajectory", "calibrate_in_workcell", "clean", "compliance_velocity", "damped_pinv",
    "extract_keypoints", "identify_ft", "kinematic_imitation", "load_skeleton", "reproduce_path",
    "run_scenario", "scenario", "simulate_imitation",
]


def __getattr__(name: str) -> Any:
    """Import a public name from its module on first access."""
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names."""
    return list(__all__)
