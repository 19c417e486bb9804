"""Closed-form inverse kinematics of the FANUC LR Mate 200iD/7L (spherical wrist).

The arm is z-y-(-y) for the position (J1-J3, with the J2 shoulder offset a1 and the J4 elbow
offset a3) and a (-x)-(-y)-(-x) spherical wrist centred at J5. All joint origins have identity
rotation, so R_0^3 = Rz(q1) Ry(q2 - q3) and R_3^6 = Rx(-q4) Ry(-q5) Rx(-q6).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robointel.errors import DescriptionError
from robointel.robot._kernels import lrmate_ik


class LRMateIK:
    """Analytic IK reading its link lengths from the robot model (so a re-measured description stays exact).

    Returns up to 8 solutions (shoulder x elbow x wrist).
    """

    def __init__(self, model: pin.Model, flange: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
        """Read the link lengths of ``model`` (6 joints); ``flange``: the flange frame in the last joint's frame."""
        m = model
        if model.nq != 6:
            raise DescriptionError("closed-form LR Mate IK needs a 6-joint arm")
        xyz = np.array([m.jointPlacements[i].translation for i in range(1, 7)])
        rots = np.array([m.jointPlacements[i].rotation for i in range(1, 7)])
        if not np.allclose(rots, np.eye(3)):
            raise DescriptionError("closed-form LR Mate IK needs identity joint-origin rotations")
        self.d1 = xyz[0, 2]
        self.a1 = xyz[1, 0]
        self.a2 = xyz[2, 2]
        self.a3 = xyz[3, 2]
        self.d4 = xyz[4, 0]
        self.flange = np.asarray(flange, float)
        self.d6 = xyz[5, 0]
        self.lower, self.upper = lower, upper
        self._flange_inv = np.linalg.inv(self.flange)
        self._flange_identity = bool(np.allclose(self.flange, np.eye(4), atol=0))
        self.L3 = float(np.hypot(self.d4, self.a3))
        self.phi = float(np.arctan2(self.a3, self.d4))

    def solve(self, T_flange: np.ndarray, *, all_turns: bool = False, tol: float = 1e-9) -> list[np.ndarray]:
        """All solutions for the flange pose (4x4, base frame) within limits."""
        T6 = T_flange if self._flange_identity else T_flange @ self._flange_inv
        sols = lrmate_ik(np.ascontiguousarray(T6, dtype=float), self.d1, self.a1, self.a2, self.a3, self.d4,
                         self.d6, self.lower, self.upper, tol)
        out = list(sols)
        if all_turns:
            out = [c for q in out for c in self._turns(q)]
        return out

    def _turns(self, q: np.ndarray) -> list[np.ndarray]:
        """Q and every variant with joints turned by +-2*pi that stays within limits."""
        outs = [q]
        for j in range(6):
            new = []
            for c in outs:
                for k in (-1, 1):
                    d = c.copy()
                    d[j] += 2 * np.pi * k
                    if self.lower[j] - 1e-9 <= d[j] <= self.upper[j] + 1e-9:
                        new.append(d)
            outs += new
        return outs
