"""Independent trajectory checker for the MotionBenchMaker problems (shares no code with robointel).

Exact distances with ``coal`` between the URDF's collision meshes (loaded by Pinocchio's
``buildGeomFromUrdf``, ``package://`` and relative paths resolved next to the URDF) and the problem's
obstacles, built here from the raw ``problems.json`` entries (boxes from their quaternion, cylinders
along their local z axis). Self-collision: every pair of geometries on different, non-adjacent links
(adjacent = joined by one URDF joint), minus the SRDF's ``disable_collisions`` pairs and minus pairs
rigidly attached to the same moving body (their distance cannot change).

A trajectory is resampled every 1 ms (cubic Hermite through (t, q, qd) when velocities are given,
else piecewise linear). Every pair is evaluated exactly at every sample where it could be the
closest one: after an exact evaluation with distance ``d`` at ``q0``, a pair is skipped at ``q`` while
``d - sum_j |q_j - q0_j| R_j > current minimum``, where ``R_j`` bounds the distance of the pair's
geometry from joint ``j``'s axis (chain offsets plus the mesh's bounding radius), so no point of the
pair moves more than ``sum_j |dq_j| R_j``. The reported minimum is therefore the exact minimum over
the 1 ms samples, and no collision at a sample is missed. A mesh pair is first measured between the
convex hulls (a lower bound); the exact mesh distance is computed only when the hulls are closer than
the current minimum. The check stops at the first colliding
sample and reports that pair.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicHermiteSpline


@dataclass
class Verdict:
    """The outcome of one check: min clearance (m), the pair realising it, collision flag."""

    min_clearance: float
    pair: tuple[str, str]
    collision: bool
    t_collision: float | None = None
    samples: int = 1
    evaluations: int = 0
    limit_violation: str | None = None
    max_vel_ratio: float = 0.0
    max_acc_ratio: float = 0.0
    reaches_goal: bool = True
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.collision and self.limit_violation is None and self.reaches_goal


def _quat_xyzw(q) -> np.ndarray:
    x, y, z, w = (float(v) for v in q)
    return pin.Quaternion(w, x, y, z).normalized().matrix()


class MBMChecker:
    """Exact collision checker of one robot (URDF + optional SRDF) against MBM problem scenes."""

    def __init__(self, urdf: str | Path, srdf: str | Path | None = None, *, joints: list[str] | None = None,
                 held: dict[str, float] | None = None, package_dirs: list[str] | None = None) -> None:
        urdf = Path(urdf)
        full = pin.buildModelFromUrdf(str(urdf))
        geom = pin.buildGeomFromUrdf(full, str(urdf), pin.COLLISION,
                                     package_dirs=[str(urdf.parent)] + list(package_dirs or []))
        names = [full.names[j] for j in range(1, full.njoints)]
        lock = [n for n in names if joints is not None and n not in joints]
        if lock:  # held joints: locked at the given value (default 0, or mid-range when 0 is outside the limits)
            q = pin.neutral(full)
            for n in lock:
                jm = full.joints[full.getJointId(n)]
                lo, hi = full.lowerPositionLimit[jm.idx_q], full.upperPositionLimit[jm.idx_q]
                v = (held or {}).get(n, 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi))
                if jm.nq == 2:
                    q[jm.idx_q:jm.idx_q + 2] = np.cos(v), np.sin(v)
                else:
                    q[jm.idx_q] = v
            self.model, self.geom = pin.buildReducedModel(full, geom, [full.getJointId(n) for n in lock], q)
        else:
            self.model, self.geom = full, geom
        self.data = self.model.createData()
        self.nq = self.model.nv  # configurations are angles (a continuous joint's cos/sin made here)
        # continuous joints (nq 2, nv 1): index of each angle in pinocchio's q
        self._cont = [(self.model.joints[j].idx_v, self.model.joints[j].idx_q) for j in range(1, self.model.njoints)
                      if self.model.joints[j].nq == 2]
        self.joint_names = [self.model.names[j] for j in range(1, self.model.njoints)]
        self.lower = np.full(self.nq, -np.inf)
        self.upper = np.full(self.nq, np.inf)
        for j in range(1, self.model.njoints):
            jm = self.model.joints[j]
            if jm.nq == 1:
                self.lower[jm.idx_v] = self.model.lowerPositionLimit[jm.idx_q]
                self.upper[jm.idx_v] = self.model.upperPositionLimit[jm.idx_q]
        self.vmax = self.model.velocityLimit.copy()
        self.links = [self.model.frames[g.parentFrame].name for g in self.geom.geometryObjects]
        self.hulls = [self._hull(g.geometry) for g in self.geom.geometryObjects]
        self._weights = np.array([self._motion_weights(g) for g in self.geom.geometryObjects])
        self.self_pairs = self._self_pairs(urdf, srdf)

    # construction -------------------------------------------------------------------------------
    def _motion_weights(self, g) -> np.ndarray:
        """W (nq,): a point of geometry ``g`` moves at most ``sum_j |dq_j| W_j`` (m)."""
        geo = g.geometry
        geo.computeLocalAABB()
        r_geo = float(np.linalg.norm(g.placement.translation) + np.linalg.norm(geo.aabb_center) + geo.aabb_radius)
        w = np.zeros(self.nq)
        j = g.parentJoint
        reach = r_geo
        while j > 0:
            jm = self.model.joints[j]
            kind = jm.shortname()
            if "Prismatic" in kind or kind in ("JointModelPX", "JointModelPY", "JointModelPZ"):
                w[jm.idx_v] = 1.0
            elif "Revolute" in kind or kind.startswith("JointModelR"):  # revolute, continuous (RUB)
                w[jm.idx_v] = reach
            else:
                raise ValueError(f"joint {self.model.names[j]} of type {kind} is not handled")
            reach += float(np.linalg.norm(self.model.jointPlacements[j].translation))
            j = self.model.parents[j]
        return w

    @staticmethod
    def _hull(geo):
        """The convex hull of a mesh (a lower bound of its distances), or the primitive itself."""
        if isinstance(geo, coal.BVHModelBase):
            geo.buildConvexHull(False, "Qt")
            return geo.convex
        return geo

    def _self_pairs(self, urdf: Path, srdf: str | Path | None) -> list[tuple[int, int]]:
        adjacent: set[frozenset[str]] = set()
        for jn in ET.parse(urdf).getroot().iter("joint"):
            parent, child = jn.find("parent"), jn.find("child")
            if parent is not None and child is not None:
                adjacent.add(frozenset((parent.get("link"), child.get("link"))))
        disabled: set[frozenset[str]] = set()
        if srdf is not None:
            known = {f.name for f in self.model.frames}
            for d in ET.parse(srdf).getroot().iter("disable_collisions"):
                a, b = d.get("link1"), d.get("link2")
                if a in known and b in known:  # an entry naming an absent link is skipped, as MoveIt does
                    disabled.add(frozenset((a, b)))
        pairs = []
        objs = self.geom.geometryObjects
        for a in range(len(objs)):
            for b in range(a + 1, len(objs)):
                la, lb = self.links[a], self.links[b]
                key = frozenset((la, lb))
                if la == lb or key in adjacent or key in disabled:
                    continue
                if objs[a].parentJoint == objs[b].parentJoint:
                    continue  # rigidly attached: the distance is constant
                pairs.append((a, b))
        return pairs

    def obstacles(self, problem: dict) -> list[tuple[str, coal.CollisionGeometry, coal.Transform3s]]:
        """coal shapes and poses of a raw ``problems.json`` problem's obstacles."""
        out = []
        for kind in ("sphere", "box", "cylinder"):
            for k, o in enumerate(problem.get(kind, [])):
                R = _quat_xyzw(o["orientation_quat_xyzw"]) if "orientation_quat_xyzw" in o else np.eye(3)
                T = coal.Transform3s(R, np.asarray(o["position"], float))
                if kind == "sphere":
                    shape: coal.CollisionGeometry = coal.Sphere(float(o["radius"]))
                elif kind == "box":
                    shape = coal.Box(*(2.0 * np.asarray(o["half_extents"], float)))
                else:
                    shape = coal.Cylinder(float(o["radius"]), float(o["length"]))
                out.append((str(o.get("name") or f"{kind}[{k}]"), shape, T))
        return out

    # checking -----------------------------------------------------------------------------------
    def _pin_q(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio's configuration of the angle vector q (a continuous joint as cos, sin)."""
        if not self._cont and self.model.nq == self.nq:
            return q
        out = np.empty(self.model.nq)
        for j in range(1, self.model.njoints):
            jm = self.model.joints[j]
            if jm.nq == 2:
                out[jm.idx_q:jm.idx_q + 2] = np.cos(q[jm.idx_v]), np.sin(q[jm.idx_v])
            else:
                out[jm.idx_q] = q[jm.idx_v]
        return out

    def _pair_distance(self, ga, Ta, gb, Tb, ha=None, hb=None, bound: float = np.inf) -> tuple[float, bool]:
        """Exact distance (or, when the convex hulls ``ha``, ``hb`` are already farther apart than
        ``bound``, their distance: a lower bound that is above ``bound``) and the collision flag."""
        if ha is not None or hb is not None:
            d_hull = float(coal.distance(ha if ha is not None else ga, Ta, hb if hb is not None else gb, Tb,
                                         coal.DistanceRequest(), coal.DistanceResult()))
            if d_hull > bound:
                return d_hull, False
        req = coal.DistanceRequest()
        res = coal.DistanceResult()
        d = float(coal.distance(ga, Ta, gb, Tb, req, res))
        if d <= 1e-9:
            creq = coal.CollisionRequest()
            cres = coal.CollisionResult()
            if coal.collide(ga, Ta, gb, Tb, creq, cres) > 0:
                return min(d, 0.0), True
        return d, False

    def check_configuration(self, q, problem: dict) -> Verdict:
        """Exact min clearance of one configuration (n,) rad in a raw problem's scene."""
        return self.check_path(np.asarray(q, float)[None], problem)

    def check_path(self, Q: np.ndarray, problem: dict, t: np.ndarray | None = None) -> Verdict:
        """Exact min clearance over the configurations Q (M, n), stopping at the first collision."""
        Q = np.asarray(Q, float)
        obst = self.obstacles(problem)
        objs = self.geom.geometryObjects
        pairs: list[tuple[int, int]] = [(a, -1 - k) for a in range(len(objs)) for k in range(len(obst))]
        pairs += self.self_pairs
        W = np.array([self._weights[a] + (self._weights[b] if b >= 0 else 0.0) for a, b in pairs])
        names = [(self.links[a], obst[-1 - b][0] if b < 0 else self.links[b]) for a, b in pairs]
        P = len(pairs)
        q_last = np.repeat(Q[:1], P, axis=0)
        d_last = np.full(P, -np.inf)  # force an evaluation of every pair at the first sample
        best, best_pair, evals = np.inf, ("", ""), 0
        for k in range(len(Q)):
            lb = d_last - np.einsum("pj,pj->p", W, np.abs(Q[k] - q_last))
            due = np.flatnonzero(lb <= best)
            if due.size == 0:
                continue
            pin.forwardKinematics(self.model, self.data, self._pin_q(Q[k]))
            Ts: dict[int, coal.Transform3s] = {}  # placements of the geometries needed at this sample
            for p in due:
                a, b = pairs[p]
                for g in (a, b):
                    if g >= 0 and g not in Ts:
                        M = self.data.oMi[objs[g].parentJoint] * objs[g].placement
                        Ts[g] = coal.Transform3s(M.rotation, M.translation)
                if b < 0:
                    _, shape, T = obst[-1 - b]
                    d, hit = self._pair_distance(objs[a].geometry, Ts[a], shape, T, self.hulls[a], None, best)
                else:
                    d, hit = self._pair_distance(objs[a].geometry, Ts[a], objs[b].geometry, Ts[b],
                                                 self.hulls[a], self.hulls[b], best)
                evals += 1
                d_last[p], q_last[p] = d, Q[k]
                if d < best:
                    best, best_pair = d, names[p]
                if hit:
                    return Verdict(min_clearance=d, pair=names[p], collision=True,
                                   t_collision=None if t is None else float(t[k]), samples=k + 1,
                                   evaluations=evals)
        return Verdict(min_clearance=float(best), pair=best_pair, collision=False, samples=len(Q), evaluations=evals)

    def check_trajectory(self, t, q, problem: dict, *, qd=None, amax=None, dt: float = 1e-3,
                         goal_tol: float = 1e-3, limit_tol: float = 0.1) -> Verdict:
        """Check a timed trajectory on a ``dt`` resample: collisions, joint limits, start and goal.

        ``t`` (K,) s, ``q`` (K, n) rad, ``qd`` (K, n) rad/s or None (then piecewise linear).
        Velocity and acceleration limits (URDF velocity, ``amax``) are checked on the resample with
        a ``limit_tol`` relative tolerance (TOPP-RA enforces them only at its grid points; the
        largest ratios are reported on the verdict); the trajectory must start at the problem's start and end at one of
        its goals within ``goal_tol`` rad.
        """
        t = np.asarray(t, float)
        q = np.asarray(q, float)
        if len(t) < 2:
            ts, Q = t, q
            Qd = np.zeros_like(q)
            Qdd = np.zeros_like(q)
        else:
            ts = np.arange(t[0], t[-1], dt)
            ts = np.append(ts, t[-1])
            if qd is not None:
                sp = CubicHermiteSpline(t, q, np.asarray(qd, float), axis=0)
                Q, Qd, Qdd = sp(ts), sp(ts, 1), sp(ts, 2)
            else:
                Q = np.stack([np.interp(ts, t, q[:, j]) for j in range(q.shape[1])], 1)
                Qd = np.gradient(Q, ts, axis=0)
                Qdd = np.gradient(Qd, ts, axis=0)
        v = self.check_path(Q, problem, ts)
        v.samples = len(Q)
        tol = 1e-6
        lo = np.flatnonzero((Q < self.lower - tol).any(0) | (Q > self.upper + tol).any(0))
        if lo.size:
            v.limit_violation = f"position of {self.joint_names[lo[0]]}"
        v.max_vel_ratio = float(np.max(np.abs(Qd) / self.vmax))
        if v.max_vel_ratio > 1.0 + limit_tol and v.limit_violation is None:
            v.limit_violation = f"velocity {v.max_vel_ratio:.4f} x limit"
        if amax is not None:
            v.max_acc_ratio = float(np.max(np.abs(Qdd) / np.asarray(amax, float)))
            if v.max_acc_ratio > 1.0 + limit_tol and v.limit_violation is None:
                v.limit_violation = f"acceleration {v.max_acc_ratio:.4f} x limit"
        start = np.asarray(problem["start"], float)
        goals = np.asarray(problem["goals"], float)
        v.reaches_goal = bool(np.abs(Q[0] - start).max() <= goal_tol
                              and np.abs(goals - Q[-1]).max(1).min() <= goal_tol)
        return v
