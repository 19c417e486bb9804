"""The MBM peers, each RRT-Connect + simplification + TOPP-RA on the same problems and limits.

* OMPL: ``og.RRTConnect`` + ``SimpleSetup.simplifySolution`` with the MoveIt-style exact state
  check: Pinocchio/coal collision of the URDF's collision meshes with the obstacles and between
  non-adjacent links (SRDF pairs removed), one C++ call per state, motions checked every
  ``1/32`` rad (VAMP's resolution).
* VAMP: ``vamp.<robot>.rrtc`` + ``vamp.<robot>.simplify`` (``ur5`` or ``fetch``) on VAMP's own sphere
  model of the robot and its own reading of the problem (``vamp.problem_dict_to_vamp``). Built by
  ``../shared/tools/vamp/build.sh``; a benchmark peer only.

Both geometric paths are timed by TOPP-RA (``toppra``) on a cubic spline through the waypoints
(points every 0.1 rad along the polyline so the spline stays near the checked edges, chord-length
parameter, zero velocity at both ends) under the same joint velocity (URDF) and
acceleration limits as ours, and sampled every 1 ms for the checker.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


@dataclass
class PeerResult:
    """A peer's outcome: path (K, n), timed samples (t, q, qd) at 1 ms, times in ms."""

    solved: bool
    path: np.ndarray
    t: np.ndarray | None
    q: np.ndarray | None
    qd: np.ndarray | None
    plan_ms: float
    simplify_ms: float
    toppra_ms: float
    reason: str = ""

    @property
    def total_ms(self) -> float:
        return self.plan_ms + self.simplify_ms + self.toppra_ms

    @property
    def duration(self) -> float:
        return float(self.t[-1]) if self.t is not None else float("nan")


def densify(path: np.ndarray, step: float) -> np.ndarray:
    """The polyline ``path`` (K, n) with points inserted so no joint moves more than ``step`` rad."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        k = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        out.append(a + (b - a) * (np.arange(1, k + 1) / k)[:, None])
    return np.concatenate(out)


def toppra_time(path: np.ndarray, vmax: np.ndarray, amax: np.ndarray, dt: float = 1e-3, step: float = 0.1):
    """TOPP-RA through the waypoints ``path`` (K, n), densified every ``step`` rad so the spline
    stays near the checked polyline: (t, q, qd) sampled every ``dt`` s, and ms."""
    import toppra
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    interp = constraint.DiscretizationType.Interpolation  # limits hold between grid points too
    t0 = time.perf_counter()
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    path = densify(path[keep], step)
    if len(path) < 2:
        return None, 0.0
    ss = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    ss /= ss[-1]
    spline = toppra.SplineInterpolator(ss, path, bc_type="clamped")
    grid = max(200, min(1000, 8 * len(path)))
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(np.stack([-vmax, vmax], 1)),
                        constraint.JointAccelerationConstraint(np.stack([-amax, amax], 1),
                                                             discretization_scheme=interp)], spline,
                       parametrizer="ParametrizeConstAccel", gridpoints=np.linspace(0, 1, grid))
    traj = inst.compute_trajectory(0, 0)
    ms = (time.perf_counter() - t0) * 1e3
    if traj is None:
        return None, ms
    ts = np.append(np.arange(0.0, traj.duration, dt), traj.duration)
    return (ts, traj(ts), traj(ts, 1)), ms


class OMPLPeer:
    """OMPL RRT-Connect on the exact mesh model (Pinocchio + coal) of one robot."""

    def __init__(self, checker) -> None:
        import pinocchio as pin

        self.pin = pin
        self.checker = checker
        self.model = checker.model
        self.data = self.model.createData()

    def _geometry(self, problem: dict):
        pin = self.pin
        gm = self.checker.geom.clone()
        nrobot = gm.ngeoms
        for name, shape, T in self.checker.obstacles(problem):
            obj = pin.GeometryObject(f"obstacle:{name}", 0, 0, pin.SE3(T.getRotation(), T.getTranslation()), shape)
            gm.addGeometryObject(obj)
        for a in range(nrobot):
            for k in range(nrobot, gm.ngeoms):
                gm.addCollisionPair(pin.CollisionPair(a, k))
        for a, b in self.checker.self_pairs:
            gm.addCollisionPair(pin.CollisionPair(a, b))
        return gm, pin.GeometryData(gm)

    def solve(self, problem: dict, vmax, amax, *, timeout: float = 10.0, seed: int = 0) -> PeerResult:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        pin = self.pin
        ou.setLogLevel(ou.LogLevel.LOG_NONE)
        ou.RNG.setSeed(int(seed) + 1)
        gm, gd = self._geometry(problem)
        model, data = self.model, self.data
        n = model.nq
        t0 = time.perf_counter()
        space = ob.RealVectorStateSpace(n)
        b = ob.RealVectorBounds(n)
        for i in range(n):
            b.setLow(i, float(model.lowerPositionLimit[i]))
            b.setHigh(i, float(model.upperPositionLimit[i]))
        space.setBounds(b)
        ss = og.SimpleSetup(space)
        q = np.empty(n)

        def valid(s) -> bool:
            for i in range(n):
                q[i] = s[i]
            return not pin.computeCollisions(model, data, gm, gd, q, True)

        ss.setStateValidityChecker(valid)
        si = ss.getSpaceInformation()
        si.setStateValidityCheckingResolution((1.0 / 32.0) / space.getMaximumExtent())
        s0, s1 = space.allocState(), space.allocState()
        start, goal = np.asarray(problem["start"], float), np.asarray(problem["goals"][0], float)
        for i in range(n):
            s0[i], s1[i] = float(start[i]), float(goal[i])
        ss.setStartAndGoalStates(s0, s1)
        planner = og.RRTConnect(si)
        planner.setRange(1.5)  # VAMP's UR5 range
        ss.setPlanner(planner)
        ss.solve(float(timeout))
        t1 = time.perf_counter()
        if not ss.haveExactSolutionPath():
            return PeerResult(False, np.zeros((0, n)), None, None, None, (t1 - t0) * 1e3, 0.0, 0.0,
                              "no path within the time limit")
        ss.simplifySolution()
        t2 = time.perf_counter()
        states = ss.getSolutionPath().getStates()
        path = np.array([[st[i] for i in range(n)] for st in states])
        timed, tms = toppra_time(path, vmax, amax)
        if timed is None:
            return PeerResult(False, path, None, None, None, (t1 - t0) * 1e3, (t2 - t1) * 1e3, tms,
                              "TOPP-RA failed")
        return PeerResult(True, path, *timed, (t1 - t0) * 1e3, (t2 - t1) * 1e3, tms)


class VAMPPeer:
    """VAMP RRT-Connect + simplification on VAMP's model of the robot (its own spheres): ``ur5`` or ``fetch``."""

    def __init__(self, robot: str = "ur5") -> None:
        import vamp

        self.vamp = vamp
        self.robot = robot
        self.module = getattr(vamp, robot)  # AttributeError: VAMP built without this robot

    def solve(self, problem: dict, vmax, amax, *, seed: int = 0) -> PeerResult:
        vamp = self.vamp
        t0 = time.perf_counter()
        env = vamp.problem_dict_to_vamp(problem)
        st = vamp.RRTCSettings()
        st.range = vamp.ROBOT_RRT_RANGES[self.robot]
        st.max_iterations = vamp.DEFAULT_ITERATIONS
        st.max_samples = vamp.DEFAULT_ITERATIONS
        mod = self.module
        rng = mod.xorshift()
        for _ in range(seed):
            rng.next()
        res = mod.rrtc(problem["start"], problem["goals"][0], env, st, rng)
        t1 = time.perf_counter()
        if not res.solved:
            return PeerResult(False, np.zeros((0, len(problem["start"]))), None, None, None, (t1 - t0) * 1e3, 0.0, 0.0,
                              "not solved")
        simp = mod.simplify(res.path, env, vamp.SimplifySettings(), rng)
        t2 = time.perf_counter()
        path = np.asarray(simp.path.numpy(), float)
        timed, tms = toppra_time(path, vmax, amax)
        if timed is None:
            return PeerResult(False, path, None, None, None, (t1 - t0) * 1e3, (t2 - t1) * 1e3, tms,
                              "TOPP-RA failed")
        return PeerResult(True, path, *timed, (t1 - t0) * 1e3, (t2 - t1) * 1e3, tms)
