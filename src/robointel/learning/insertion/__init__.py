"""The tight peg-in-hole insertion taught with the hand-held device and reproduced by the LR Mate (Sec. 5.5).

* :mod:`.peg_hole` - the task: a round peg with a hemispherical tip, a chamferless hole.
* :mod:`.hdd_scene` - the hand-held demonstration device over the task in MuJoCo.
* :mod:`.demonstrator` - the scripted person and its demonstrations.
* :mod:`.skill` - the skill model: GMR wrench -> corrective tool twist.
* :mod:`.felt` - feel the face, align, insert: the person's strategy as a stage machine (a policy).
* :mod:`.felt_skill` - the person demonstrating it with the device, and the rotation learned from them.
* :mod:`.policies` - the strategies by name: the learned skills' policies and the baselines (a constant push, a
  hand-tuned admittance).
* :mod:`.impedance` - the torque-level Cartesian impedance.
* :mod:`.robot_cell` - the LR Mate with the tool over the task; one trial.
* :mod:`.trials` - learn the felt skill; trials of a strategy (a skill or a baseline by name) from random starts.
* :mod:`.press_test` - the contact physics' honesty check.
"""

from robointel.learning.insertion.demonstrator import PHASES, Demonstrator, demonstrate, seated_demonstrations
from robointel.learning.insertion.felt import STAGES, FeltStrategy, PlaneFit, face_normal, fit_face
from robointel.learning.insertion.felt_skill import FeltSkill, demonstrate_felt
from robointel.learning.insertion.hdd_scene import HDDScene
from robointel.learning.insertion.impedance import CartesianImpedance, ImpedanceGains
from robointel.learning.insertion.peg_hole import R_DOWN, PegHole, tip_point
from robointel.learning.insertion.policies import (
    STRATEGIES,
    TIME_LIMIT_S,
    ConstantPush,
    HandTunedAdmittance,
    baseline_policy,
    skill_policy,
)
from robointel.learning.insertion.press_test import PressResult, press_test
from robointel.learning.insertion.robot_cell import (
    ARMATURE,
    R_FLANGE_TOOL,
    InsertionTrial,
    Policy,
    RobotCell,
    random_start_errors,
)
from robointel.learning.insertion.skill import PERCEPTION, POLICY, InsertionSkill, tool_velocities
from robointel.learning.insertion.trials import learn_felt_skill, run_trials, strategy_name

__all__ = [
    "seated_demonstrations", "STAGES", "FeltStrategy", "FeltSkill", "demonstrate_felt", "face_normal",
    "fit_face", "PlaneFit",
    "ARMATURE", "PERCEPTION", "PHASES", "POLICY", "R_DOWN", "R_FLANGE_TOOL", "CartesianImpedance",
    "ConstantPush", "Demonstrator", "HDDScene", "HandTunedAdmittance", "ImpedanceGains", "InsertionSkill",
    "InsertionTrial", "PegHole", "Policy", "PressResult", "RobotCell", "demonstrate", "press_test",
    "random_start_errors", "tip_point", "tool_velocities", "STRATEGIES", "TIME_LIMIT_S", "baseline_policy",
    "skill_policy", "learn_felt_skill", "run_trials", "strategy_name",
]
