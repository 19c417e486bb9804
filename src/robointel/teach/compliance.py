"""Compliance control for lead-through teaching (Ch. 3.3, eqs. (3.10)-(3.13)), the names Part I uses.

The law is written once, in :mod:`robointel.control.admittance`: the measured (compensated) wrench
F_E becomes a tool twist V_r = C F_E, C = diag(K_d I_3, K_r I_3) (3.10)-(3.11), and a joint velocity
dq_r = J^#(q) V_r with a singularity-robust pseudo-inverse (3.12)-(3.13). This module only gives
those functions their Part I names.
"""
from __future__ import annotations

from robointel.control.admittance import AdmittanceGains as ComplianceGains
from robointel.control.admittance import admittance_twist as compliance_twist
from robointel.control.admittance import admittance_velocity as compliance_velocity
from robointel.control.admittance import damped_pinv, shift_wrench, wrench_to_world

__all__ = ["ComplianceGains", "compliance_twist", "compliance_velocity", "damped_pinv", "shift_wrench",
           "wrench_to_world"]
