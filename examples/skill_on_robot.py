"""A learned insertion skill on the robot interface: learn from two HDD demonstrations, then insert the
peg in the simulated cell over streamed joint positions (the same call drives a FANUC controller).

    python examples/skill_on_robot.py
"""
import numpy as np

from robointel.control.payload import PayloadCompensation
from robointel.interface.sim import SimRobot
from robointel.interface.wrench_source import StateWrench
from robointel.learning import insertion as ins
from robointel.skills.cells import HoleTask, PegTool, ik_near, peg_hole_workcell
from robointel.skills.insertion import run_insertion

# learn: scripted hand-held demonstrations -> GMR skill (felt wrench -> corrective tool twist)
task = ins.PegHole()
rng = np.random.default_rng(0)
demos = ins.seated_demonstrations(task, rng, 4)  # the person does not seat every try at 20 um
peg, hole = PegTool(), HoleTask(clearance=0.5e-3)
skill = ins.InsertionSkill(4, centre=peg.centre).fit(demos)

# the cell: the peg on the flange over a square pocket, 1 mm off and tilted 2 degrees
wc, robot = peg_hole_workcell(peg, hole)  # robot.tool = the peg's tip-sphere centre, z down the peg
wc.reset(ik_near(robot, hole.start_tcp(peg, lateral=(1e-3, -0.5e-3), tilt=(0.3, np.radians(2.0)))))
wc.hold(0.2)
arm = SimRobot(wc)  # or open_robot("fanuc://HOST") with a wrench source for its F/T sensor

# run: every 8 ms, wrench -> skill -> twist + admittance -> joint position target -> arm.stream
source = StateWrench(robot, PayloadCompensation(peg.mass, np.asarray(peg.payload().com)))
res = run_insertion(arm, robot, skill.predict, hole.advance(), source=source, time_limit=8.0)
print("seated" if res.success else res.outcome.detail, res.outcome.figures)
