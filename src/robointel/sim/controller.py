"""Moved to :mod:`robointel.control.servo` (the joint servo is written once, in ``control/``)."""
from robointel.control.servo import JointController, PIDGains, max_inertia, model_with_payload

__all__ = ["JointController", "PIDGains", "max_inertia", "model_with_payload"]
