"""Torque-level Cartesian impedance about a compliance centre on the tool, (2.x) hybrid position/force control."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from robointel.geometry.rotations import so3_log


@dataclass(frozen=True)
class ImpedanceGains:
    """Gains of :class:`CartesianImpedance` (SI units), in the tool frame at the compliance centre.

    Lateral (tool x, y): a spring to the equilibrium and a damper (critical when None, 2 sqrt(K Lambda_ii)
    with the operational-space inertia Lambda at the start). Axial (tool z): no spring; force =
    ``axial_damping`` x (policy speed - speed), clipped to +-``max_axial_force``: a force-limited damper.
    Rotation about the tool x, y axes through the centre: spring and damper; about the tool axis:
    ``twist_stiffness`` with critical damping. ``friction_compensation`` adds the URDF's viscous + Coulomb
    joint friction at the measured joint velocity (Coulomb smoothed by tanh(qd / ``friction_velocity``)).

    Attributes:
        center_from_tip: Compliance centre behind the tip (m); None: the tip sphere's centre.
        lateral_stiffness: Lateral spring (N/m) while holding the start.
        lateral_damping: Lateral damper (N s/m); None: critical.
        axial_damping: Axial damper (N s/m).
        max_axial_force: Axial force limit (N).
        rot_stiffness: Rotational spring about tool x, y (N m/rad).
        rot_damping: Rotational damper (N m s/rad); None: critical.
        twist_stiffness: Spring about the tool axis (N m/rad).
        damping_ratio: Ratio of the critical dampers.
        friction_compensation: Add the joint friction model to the torques.
        friction_velocity: Coulomb smoothing velocity (rad/s).
        insert_lateral_stiffness: Lateral spring (N/m) while inserting; None: ``lateral_stiffness``.
        friction_feedforward: Compensate the Coulomb friction at the measured joint velocity plus the one
            the commanded motion asks for (J_c^+ [v_eq; w_eq]): a joint at rest that is commanded to move
            starts moving, instead of waiting for the spring to wind up past its stiction.
    """

    center_from_tip: float | None = None
    lateral_stiffness: float = 2000.0
    lateral_damping: float | None = None
    axial_damping: float = 1000.0
    max_axial_force: float = 20.0
    rot_stiffness: float = 300.0
    rot_damping: float | None = None
    twist_stiffness: float = 50.0
    damping_ratio: float = 1.0
    friction_compensation: bool = True
    friction_velocity: float = 0.01
    insert_lateral_stiffness: float | None = 300.0
    friction_feedforward: bool = True


class CartesianImpedance:
    """Torque-level Cartesian impedance about a compliance centre on the tool (hybrid position/force control).

    As on a torque-controlled arm::

        tau = J_c(q)^T W + h(q, qd) + tau_f(qd),
        W = [K_l (x_0 - x)_xy - D_l v_xy ;  clip(D_a (v_ref - v_z), +-f_max) ;
             K_r log(R_0 R^T)_xy - D_r w_xy ;  K_t log(R_0 R^T)_z - D_t w_z],

    all in the frame of the compliance centre C (tool axes, origin on the tool axis), where
    J_c is C's 6xn body Jacobian [v; w] (Pinocchio, LOCAL), (x, R) its pose and (v, w) its twist
    from the measured joints, h = C(q, qd) qd + g(q) the Coriolis/centrifugal and gravity torques of
    the Pinocchio model with the tool as payload (RNEA at zero acceleration), tau_f the URDF's
    viscous + Coulomb friction at the measured velocity. (x_0, R_0) is the equilibrium the skill
    moves; v_ref the axial speed it asks for. The inertia is not shaped: the arm keeps its own
    operational-space inertia Lambda = (J_c M^-1 J_c^T)^-1 (armature included).
    """

    def __init__(self, pin_model, flange_frame: str, T_flange_centre: np.ndarray, gains: ImpedanceGains,
                 viscous, coulomb, effort_limit) -> None:
        self.pin = pin
        model = pin_model.copy()
        parent = model.frames[model.getFrameId(flange_frame)]
        placement = parent.placement * pin.SE3(np.ascontiguousarray(T_flange_centre[:3, :3]),
                                               np.ascontiguousarray(T_flange_centre[:3, 3]))
        self.fid = model.addFrame(pin.Frame("compliance_centre", parent.parentJoint, placement,
                                            pin.FrameType.OP_FRAME))
        self.model = model
        self.data = model.createData()
        self.gains = gains
        self.viscous = np.asarray(viscous, float)
        self.coulomb = np.asarray(coulomb, float)
        self.effort = np.asarray(effort_limit, float)
        self.K = np.zeros(6)
        self.D = np.zeros(6)

    def pose_twist(self, q, qd) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Pose (x (3,), R (3,3)), body twist [v; w] (6,) of the centre and its LOCAL Jacobian (6, n)."""
        pin, m, d = self.pin, self.model, self.data
        pin.forwardKinematics(m, d, q, qd)
        pin.updateFramePlacement(m, d, self.fid)
        M = d.oMf[self.fid]
        tw = pin.getFrameVelocity(m, d, self.fid, pin.LOCAL)
        J = pin.computeFrameJacobian(m, d, q, self.fid, pin.LOCAL)
        return M.translation.copy(), M.rotation.copy(), np.concatenate([tw.linear, tw.angular]), J

    def set_gains(self, q, *, lateral_stiffness: float | None = None) -> None:
        """Set the stiffness K and damping D (6,) for the operational inertia at ``q`` (critical where None).

        Args:
            q: (n,) joint configuration (rad).
            lateral_stiffness: Overrides the gains' lateral spring (N/m).
        """
        pin, m, d = self.pin, self.model, self.data
        g = self.gains
        if lateral_stiffness is not None:
            g = replace(g, lateral_stiffness=float(lateral_stiffness))
        J = pin.computeFrameJacobian(m, d, q, self.fid, pin.LOCAL)
        Minv = pin.computeMinverse(m, d, q)
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        lam = np.diag(np.linalg.inv(J @ Minv @ J.T))
        self.K = np.array([g.lateral_stiffness, g.lateral_stiffness, 0.0, g.rot_stiffness, g.rot_stiffness,
                           g.twist_stiffness])
        crit = 2.0 * g.damping_ratio * np.sqrt(self.K * lam)
        self.D = crit.copy()
        if g.lateral_damping is not None:
            self.D[:2] = g.lateral_damping
        if g.rot_damping is not None:
            self.D[3:5] = g.rot_damping
        self.D[2] = 0.0
        self.lam = lam

    def torque(self, q, qd, x0, R0, v_ref: float, twist_ref=None) -> tuple[np.ndarray, np.ndarray]:
        """Joint torques (n,) N m (clipped to the effort limits) and the commanded wrench W (6,).

        ``twist_ref`` (6,) is the commanded motion of the equilibrium (centre frame, m/s and rad/s), used by
        the friction feed-forward.
        """
        x, R, tw, J = self.pose_twist(q, qd)
        e = np.concatenate([R.T @ (x0 - x), R.T @ so3_log(R0 @ R.T)])
        W = self.K * e - self.D * tw
        g = self.gains
        W[2] = float(np.clip(g.axial_damping * (v_ref - tw[2]), -g.max_axial_force, g.max_axial_force))
        tau = J.T @ W + self.pin.rnea(self.model, self.data, q, qd, np.zeros_like(q))
        if g.friction_compensation:
            qd_f = qd
            if g.friction_feedforward and twist_ref is not None and np.any(twist_ref):
                qd_f = qd + np.linalg.lstsq(J, np.asarray(twist_ref, float), rcond=None)[0]
            tau += self.viscous * qd + self.coulomb * np.tanh(qd_f / g.friction_velocity)
        return np.clip(tau, -self.effort, self.effort), W

