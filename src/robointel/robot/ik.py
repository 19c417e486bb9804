"""Closed-form inverse kinematics of the FANUC LR Mate 200iD/7L (spherical wrist).

The arm is z-y-(-y) for the position (J1-J3, with the J2 shoulder offset a1 and the J4 elbow
offset a3) and a (-x)-(-y)-(-x) spherical wrist centred at J5. All joint origins have identity
rotation, so R_0^3 = Rz(q1) Ry(q2 - q3) and R_3^6 = Rx(-q4) Ry(-q5) Rx(-q6).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from robointel.errors import DescriptionError

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot.model import Robot

def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


class LRMateIK:
    """Analytic IK reading its link lengths from the robot model (so a re-measured description
    stays exact). Returns up to 8 solutions (shoulder x elbow x wrist)."""

    def __init__(self, robot: "Robot") -> None:
        m = robot.model
        if robot.nq != 6:
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
        self.flange = robot.model.frames[robot._flange_id].placement.homogeneous
        self.d6 = xyz[5, 0]
        self.lower, self.upper = robot.lower, robot.upper
        self.L3 = float(np.hypot(self.d4, self.a3))
        self.phi = float(np.arctan2(self.a3, self.d4))

    def solve(self, T_flange: np.ndarray, *, all_turns: bool = False, tol: float = 1e-9) -> list[np.ndarray]:
        """All solutions for the flange pose (4x4, base frame) within limits."""
        T6 = T_flange @ np.linalg.inv(self.flange)  # link_6 frame pose
        R, p = T6[:3, :3], T6[:3, 3]
        wc = p - self.d6 * R[:, 0]
        sols = []
        base = float(np.arctan2(wc[1], wc[0]))
        r = float(np.hypot(wc[0], wc[1]))
        z = wc[2] - self.d1
        for q1, x in ((base, r - self.a1), (base + np.pi, -r - self.a1)):
            s = (x * x + z * z - self.a2 ** 2 - self.L3 ** 2) / (2 * self.a2 * self.L3)
            if abs(s) > 1 + 1e-12:
                continue
            s = min(1.0, max(-1.0, s))
            for t in (np.arcsin(s), np.pi - np.arcsin(s)):
                q3 = t - self.phi
                # w' = [0,0,a2] + Ry(-q3) [d4, 0, a3] in the link-2 frame
                c3, s3 = np.cos(q3), np.sin(q3)
                wx = self.d4 * c3 - self.a3 * s3
                wz = self.a2 + self.d4 * s3 + self.a3 * c3
                q2 = np.arctan2(x, z) - np.arctan2(wx, wz)
                R03 = _rz(q1) @ _ry(q2 - q3)
                W = R03.T @ R
                cb = W[0, 0]
                sb = float(np.hypot(W[1, 0], W[2, 0]))
                if sb < 1e-10:  # wrist singular: J4 and J6 aligned, keep J4 = 0
                    for b in ((0.0,) if cb > 0 else (np.pi,)):
                        a = 0.0
                        # Rx(a) Ry(b) Rx(c) with a = 0: W[2,1], W[1,1] give c (sign flips for b = pi)
                        c = np.arctan2(W[2, 1], W[1, 1]) if cb > 0 else np.arctan2(-W[2, 1], W[1, 1])
                        sols.append(np.array([q1, q2, q3, -a, -b, -c]))
                    continue
                for sgn in (1.0, -1.0):
                    b = np.arctan2(sgn * sb, cb)
                    a = np.arctan2(sgn * W[1, 0], -sgn * W[2, 0])
                    c = np.arctan2(sgn * W[0, 1], sgn * W[0, 2])
                    sols.append(np.array([q1, q2, q3, -a, -b, -c]))
        out = []
        for q in sols:
            q = (q + np.pi) % (2 * np.pi) - np.pi
            for cand in self._turns(q) if all_turns else [q]:
                if np.all(cand >= self.lower - tol) and np.all(cand <= self.upper + tol):
                    out.append(np.clip(cand, self.lower, self.upper))
            if not all_turns:
                # principal angle outside limits, but a 2*pi turn may be inside (J1 is +-170 deg)
                if not (np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol)):
                    alt = [c for c in self._turns(q) if np.all(c >= self.lower - tol) and np.all(c <= self.upper + tol)]
                    if alt:
                        out.append(np.clip(min(alt, key=lambda c: np.abs(c).sum()), self.lower, self.upper))
        return out

    def _turns(self, q: np.ndarray) -> list[np.ndarray]:
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
