"""Learned skills and grasp execution on any robot interface (above :mod:`robointel.interface`).

- :mod:`robointel.skills.insertion` -- a learned insertion skill: admittance over streamed joint positions.
- :mod:`robointel.skills.grinding` -- a learned grinding skill: a force set-point map over streamed positions.
- :mod:`robointel.skills.grasp_execution` -- approach, descend, close, lift with a gripper beside the arm.
- :mod:`robointel.skills.cells` -- the simulated workcells the skills run in on the ``sim`` backend.
"""
