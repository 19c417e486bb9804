"""Controllers, written once (Ch. 2-3).

- :class:`JointController`, :class:`PIDGains` -- joint servo: PID + model feed-forward (Fig. 2.3).
- :class:`JerkLimitedFollower` -- the jerk-limited online follower of a moving target (ruckig).
- :class:`AdmittanceController`, :func:`admittance_twist`, :func:`admittance_velocity`,
  :func:`damped_pinv` -- Cartesian
  admittance (3.10)-(3.13): wrench -> twist -> joint position command.
- :class:`PayloadCompensation` -- F/T payload and bias compensation (3.14)-(3.15), (3.20).
- :class:`ComputedTorqueLQ`, :func:`lq_gain`, :func:`double_integrator` -- computed torque (3.9)
  around discrete LQ tracking (3.2)-(3.8).
"""
from robointel.control.admittance import (
                                          AdmittanceController,
                                          AdmittanceGains,
                                          admittance_twist,
                                          admittance_velocity,
                                          damped_pinv,
                                          shift_wrench,
                                          wrench_to_world,
)
from robointel.control.follower import JerkLimitedFollower
from robointel.control.lq import ComputedTorqueLQ, double_integrator, lq_gain
from robointel.control.payload import GRAVITY, PayloadCompensation
from robointel.control.servo import JointController, PIDGains, max_inertia, model_with_payload

__all__ = ["JointController", "PIDGains", "max_inertia", "model_with_payload", "JerkLimitedFollower",
           "AdmittanceController", "AdmittanceGains", "admittance_twist", "admittance_velocity", "damped_pinv",
           "shift_wrench", "wrench_to_world", "PayloadCompensation", "GRAVITY", "ComputedTorqueLQ", "lq_gain",
           "double_integrator"]
