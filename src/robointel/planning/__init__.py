"""Part III (Ch. 7): CFS, trajectory planning, the SQP baseline, temporal optimization, the FRMP.

- :func:`cfs` -- the Convex Feasible Set algorithm (Algorithm 2) for any strictly convex quadratic
  cost with nonlinear constraints of the three CFS cases (:class:`NonlinearConstraint`).
- :class:`TrajectoryPlanner` -- collision-free joint trajectories through stop-by waypoints,
  (7.1)-(7.3), on the robot's collision spheres and :mod:`robointel.geometry` obstacles.
- :func:`temporal_optimize` -- re-timing by CFS, (7.7)-(7.9), switched by :class:`TemporalSettings`.
- :class:`Scene` / :func:`load_scene` -- planning scenes (YAML files, built-in ``table71``).
- :func:`plan_scene` / :func:`execute` -- the FRMP on a scene, run in the MuJoCo workcell.
- :func:`plan_motion` -- start-to-goal planning in cluttered cells for any arm (RRT-Connect on the
  compiled sphere checks, shortcutting, temporal optimization, dense check) in an :class:`Environment`.
- :func:`receding_horizon` -- warm-started replanning with a moving obstacle.
- Baselines: :func:`slsqp`, :func:`slsqp_segment` (SQP), :func:`rrtconnect` (OMPL, the ``peers`` extra).
"""


from robointel.planning.cfs import CFSResult, NonlinearConstraint, cfs
from robointel.planning.environment import Contact, Environment
from robointel.planning.frmp import (
    Execution,
    FRMPResult,
    TrajectoryCheck,
    check_trajectory,
    execute,
    make_planners,
    plan_scene,
    planner_settings,
)
from robointel.planning.motion import MotionPlan, plan_motion
from robointel.planning.motion_settings import MotionSettings
from robointel.planning.ompl_peer import OMPLResult, rrtconnect
from robointel.planning.qp import DenseQP, SparseQP
from robointel.planning.replan import ReplanResult, receding_horizon
from robointel.planning.scene import Scene, builtin_scenes, load_scene, scene_from_dict
from robointel.planning.sphere_file import sphere_model_from_urdf
from robointel.planning.sqp import SQPResult, slsqp, slsqp_segment
from robointel.planning.temporal import (
    TemporalResult,
    TemporalSettings,
    concatenate_segments,
    fixed_dt_segment,
    temporal_optimize,
)
from robointel.planning.waypoints import PlannerSettings, SegmentPlan, TrajectoryPlanner, straight_reference

__all__ = [
    "cfs", "CFSResult", "NonlinearConstraint", "SparseQP", "DenseQP",
    "TrajectoryPlanner", "PlannerSettings", "SegmentPlan", "straight_reference",
    "temporal_optimize", "TemporalResult", "TemporalSettings", "concatenate_segments", "fixed_dt_segment",
    "Scene", "load_scene", "scene_from_dict", "builtin_scenes",
    "plan_scene", "execute", "check_trajectory", "make_planners", "planner_settings",
    "FRMPResult", "Execution", "TrajectoryCheck",
    "receding_horizon", "ReplanResult", "slsqp", "slsqp_segment", "SQPResult", "rrtconnect", "OMPLResult",
    "plan_motion", "MotionSettings", "MotionPlan", "Environment", "Contact", "sphere_model_from_urdf",
]
