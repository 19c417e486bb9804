"""The robot core (Ch. 2): one fixed-base robot model on Pinocchio, from its URDF (and SRDF) as shipped.

:class:`Robot` loads a URDF (a built-in name or a path) with revolute, continuous, prismatic, fixed
and mimic joints, optionally one planning group of it (an SRDF group, a base and tip link, or a
list of joints; the other joints held), and gives forward kinematics of any frame, world-aligned
Jacobians of any point on any link, inverse kinematics (closed form for the LR Mate's spherical
wrist, a compiled Levenberg-Marquardt search for any chain), rigid-body dynamics (2.5) with viscous
and Coulomb friction, and the sphere collision model of Fig. 4.2.

Conventions: SI units; the model's world frame is the URDF root link (for the built-in LR Mate,
``base_link`` on the mounting plane; the FANUC world frame ``base`` is 0.330 m above it). Joint
vectors are ordered as ``Robot.joint_names`` (the planned joints); a continuous joint is an angle
in [-2 pi, 2 pi].
"""
from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from robointel._validate import as_array
from robointel.errors import DescriptionError, DescriptionWarning, IKFailure, InvalidInput
from robointel.robot._kernels import chain_jacobians_batch, points_jacobians, points_jacobians_batch
from robointel.robot.catalogue import find_urdf
from robointel.robot.chain import chain_arrays
from robointel.robot.collision import SphereModel
from robointel.robot.description import load_description
from robointel.robot.dynamics import RigidBodyDynamics
from robointel.robot.geometry_urdf import read_collision_geometry
from robointel.robot.ik import LRMateIK
from robointel.robot.ik_numeric import numeric_ik
from robointel.robot.joint_space import JointSpace
from robointel.robot.sphere_fit import fit_spheres
from robointel.robot.srdf import SRDF, read_srdf

#: velocity limit given to a planned joint whose URDF gives none (rad/s or m/s), with a warning
DEFAULT_VELOCITY = 1.0
#: frame types in the order a name shared by several frames resolves to
_FRAME_ORDER = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT,
                pin.FrameType.SENSOR)


class Robot(JointSpace, RigidBodyDynamics):
    """A fixed-base robot on Pinocchio: one planning group of a URDF, the other joints held.

    Args:
        urdf: the URDF text.
        name: a short name.
        urdf_path: where the text came from (mesh paths are resolved from it).
        flange_frame: the frame :meth:`fk` reports (default: ``tip_link``, else ``"flange"`` if
            present, else the last frame of the model).
        tool: optional 4x4 tool transform (TCP in the flange frame).
        srdf: SRDF file: its groups and its disabled collision pairs (entries naming absent
            links are skipped with a :class:`~robointel.errors.DescriptionWarning`).
        group: SRDF planning group to plan.
        base_link: with ``tip_link``: plan the joints of the chain between them.
        tip_link: see ``base_link`` (the root link when ``base_link`` is None).
        joints: plan these joints (names).
        held: values of movable joints outside the group, rad or m (default: 0, or the mid-range
            when 0 is outside the joint's limits; a mimic joint follows its master).
        package_dirs: extra directories for ``package://`` mesh paths (before ``ROS_PACKAGE_PATH``).

    Raises:
        DescriptionError: a malformed URDF, a joint Pinocchio cannot model, or a collision mesh
            that cannot be found (named with where it was looked for).
        InvalidInput: a bad SRDF, group, chain, joint list or held value.
    """

    def __init__(self, urdf: str, *, name: str = "robot", urdf_path: Path | None = None,
                 flange_frame: str | None = None, tool: np.ndarray | None = None, srdf: str | Path | None = None,
                 group: str | None = None, base_link: str | None = None, tip_link: str | None = None,
                 joints: Sequence[str] | None = None, held: Mapping[str, float] | None = None,
                 package_dirs: Sequence[str | Path] = ()) -> None:
        source = str(urdf_path) if urdf_path is not None else f"<{name}>"
        self._init_args: dict[str, Any] = dict(name=name, urdf_path=urdf_path, srdf=srdf, group=group,
                                               base_link=base_link, tip_link=tip_link, joints=joints, held=held,
                                               package_dirs=package_dirs)
        self.srdf_path = Path(srdf) if srdf is not None else None
        self.srdf: SRDF | None = None
        if srdf is not None:
            try:
                links = {lk.get("name") or "" for lk in ET.fromstring(urdf).iter("link")}
            except ET.ParseError:
                links = set()
            self.srdf = read_srdf(srdf, links)
        desc = load_description(urdf, source, srdf=self.srdf, group=group, base_link=base_link, tip_link=tip_link,
                                joints=joints, held=held)
        self.description = desc
        model = desc.model
        self.name = name
        self.urdf = urdf
        self.urdf_path = urdf_path
        self.package_dirs = [Path(d) for d in package_dirs]
        self.model = model
        self.data = model.createData()
        self.nq = int(model.nq)
        self.joint_names: list[str] = [model.names[i] for i in range(1, model.njoints)]
        self.held: dict[str, float] = dict(desc.held)
        self.continuous = np.array([n in desc.continuous for n in self.joint_names], dtype=bool)
        self.lower = np.array(model.lowerPositionLimit, dtype=float)
        self.upper = np.array(model.upperPositionLimit, dtype=float)
        self.velocity_limit = np.array(model.velocityLimit, dtype=float)
        if np.any(self.velocity_limit <= 0):
            bad = [n for n, v in zip(self.joint_names, self.velocity_limit) if v <= 0]
            warnings.warn(f"URDF {source}: joints {bad} give no velocity limit; {DEFAULT_VELOCITY} used",
                          DescriptionWarning, stacklevel=2)
            self.velocity_limit[self.velocity_limit <= 0] = DEFAULT_VELOCITY
        self.effort_limit = np.array(model.effortLimit, dtype=float)
        self.viscous = np.array(model.damping, dtype=float)
        self.coulomb = np.array(model.friction, dtype=float)
        self.acceleration_limit = 3.0 * self.velocity_limit  # reachable in ~0.33 s; override per task
        self.frame_names: list[str] = [f.name for f in model.frames]
        self._frame_index: dict[str, int] = {}
        for kind in _FRAME_ORDER:
            for i, f in enumerate(model.frames):
                if f.type == kind and f.name not in self._frame_index:
                    self._frame_index[f.name] = i
        if flange_frame is None:
            last = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == model.njoints - 1]
            flange_frame = tip_link if tip_link is not None else (
                "flange" if "flange" in self._frame_index else (last[-1] if last else model.frames[-1].name))
        self._flange_id = self._frame_id(flange_frame)
        self.flange_frame = flange_frame
        self._tool = np.eye(4)
        self._tool_is_identity = True
        if tool is not None:
            self.tool = tool
        self._root = ET.fromstring(urdf)
        self._link_names = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        # joint index each body hangs on, and the body placement in that joint's frame
        self._link_joint = {f.name: int(f.parentJoint) for f in model.frames if f.type == pin.FrameType.BODY}
        self._link_in_joint = {f.name: f.placement.homogeneous.copy()
                               for f in model.frames if f.type == pin.FrameType.BODY}
        # ancestor[j, k]: does configuration index k move joint j?  (tree-safe ancestry mask)
        self._ancestor = np.zeros((model.njoints, self.nq), dtype=bool)
        for j in range(1, model.njoints):
            for a in model.supports[j]:
                if a > 0:
                    self._ancestor[j, model.joints[a].idx_v] = True
        self.chain = chain_arrays(model)
        # the compiled batch kinematics need each joint on its own configuration index
        q_of = self.chain[4][1:]
        self._chain_batch = len(np.unique(q_of)) == len(q_of) and len(q_of) == self.nq
        # live references into Pinocchio's data (they follow every kinematics call)
        self._oMi = [self.data.oMi[i] for i in range(model.njoints)]
        self._Jw = self.data.J
        self._T = np.empty((model.njoints, 4, 4))
        self._primitives = self._read_primitives()
        self._spheres: SphereModel | None = None
        self._fitted = False
        self._ik = None
        if name == "lrmate200id7l":
            fl = model.frames[self._flange_id].placement.homogeneous
            self._ik = LRMateIK(model, fl, self.lower, self.upper)

    @property
    def fitted_spheres(self) -> bool:
        """True when :attr:`spheres` is (or will be) fitted to the collision meshes (inside them)."""
        if self._spheres is not None:
            return self._fitted
        return any(p["type"] == "mesh" for ps in self._primitives.values() for p in ps)

    @property
    def spheres(self) -> SphereModel:
        """The robot's collision spheres, made on first use (assignable).

        Fitted to its collision meshes (:func:`~robointel.robot.sphere_fit.fit_spheres`, cached on disk)
        when it has meshes, else covering its collision primitives.
        """
        if self._spheres is None:
            if any(p["type"] == "mesh" for ps in self._primitives.values() for p in ps):
                links, centres, radii = fit_spheres(self)
                self._spheres = SphereModel(links, centres, radii).bind(self)
                self._fitted = True
            else:
                self._spheres = SphereModel.from_robot(self)
        return self._spheres

    @spheres.setter
    def spheres(self, model: SphereModel) -> None:
        if not isinstance(model, SphereModel):
            raise InvalidInput(f"spheres must be a SphereModel, got {type(model).__name__}", value=model)
        self._spheres = model.bind(self)
        self._fitted = False

    def clone(self) -> Robot:
        """A new robot of the same description, group, held values, flange frame and tool (its own Pinocchio data)."""
        return Robot(self.urdf, flange_frame=self.flange_frame, tool=self.tool, **self._init_args)

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, name_or_path: str | Path, *, flange_frame: str | None = None, tool: np.ndarray | None = None,
             srdf: str | Path | None = None, group: str | None = None, base_link: str | None = None,
             tip_link: str | None = None, joints: Sequence[str] | None = None,
             held: Mapping[str, float] | None = None, package_dirs: Sequence[str | Path] = ()) -> Robot:
        """Load a built-in robot, an ``example-robot-data`` arm or a URDF file (and optionally an SRDF and a group).

        Load a built-in robot (``"lrmate200id7l"``, ``"scara2"``), an ``example-robot-data`` arm (``"ur5"``,
        ``"panda"``) or a URDF file. The other keyword
        arguments are those of :class:`Robot`.

        Raises:
            UnknownRobot: the name is not built in and no such file exists.
            DescriptionError: the file is not a readable URDF, or a mesh cannot be found.
            InvalidInput: a bad SRDF, group or held value.
        """
        path, name, maker_flange = find_urdf(name_or_path)
        if flange_frame is None and tip_link is None:
            flange_frame = maker_flange
        try:
            text = path.read_text()
            ET.fromstring(text)
        except (OSError, UnicodeDecodeError, ET.ParseError) as exc:
            raise DescriptionError(f"cannot read URDF {path}: {exc}; check that it is a valid URDF XML file",
                                   value=str(path)) from None
        return cls(text, name=name, urdf_path=path, flange_frame=flange_frame, tool=tool, srdf=srdf, group=group,
                   base_link=base_link, tip_link=tip_link, joints=joints, held=held, package_dirs=package_dirs)

    # ------------------------------------------------------------------ helpers
    def _frame_id(self, frame: str) -> int:
        i = self._frame_index.get(frame)
        if i is None:
            raise InvalidInput(f"robot {self.name!r} has no frame {frame!r}; frames: {self.frame_names}", value=frame)
        return i

    def frame_id(self, frame: str) -> int:
        """Pinocchio index of the frame named ``frame``: a link (BODY frame) first when several frames share the name.

        Raises:
            InvalidInput: no frame of that name.
        """
        return self._frame_id(frame)

    @property
    def link_names(self) -> list[str]:
        """Names of the links (URDF bodies)."""
        return list(self._link_names)

    def link_joint(self, link: str) -> int:
        """Pinocchio joint index a link hangs on (0: the fixed base)."""
        if link not in self._link_joint:
            raise InvalidInput(f"robot {self.name!r} has no link {link!r}; links: {self._link_names}", value=link)
        return self._link_joint[link]

    @property
    def tool(self) -> np.ndarray:
        """4x4 tool transform: the TCP in the flange frame (identity: TCP = flange)."""
        return self._tool

    @tool.setter
    def tool(self, T: ArrayLike) -> None:
        T = as_array(T, "tool", (4, 4))
        R = T[:3, :3]
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise InvalidInput("tool must be a rigid transform (proper rotation in its upper-left 3x3)", value=T)
        self._tool = T.copy()
        self._tool_is_identity = bool(np.array_equal(T, np.eye(4)))

    # ------------------------------------------------------------------ kinematics
    def frame_pose(self, q: ArrayLike, frame: str | None = None) -> np.ndarray:
        """4x4 pose of ``frame`` (default: the flange, without the tool) in the world frame."""
        q = self.check_q(q)
        fid = self._flange_id if frame is None else self._frame_id(frame)
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[fid].homogeneous

    def fk(self, q: ArrayLike) -> np.ndarray:
        """4x4 pose of the TCP (flange composed with :attr:`tool`) in the world frame."""
        return self.frame_pose(q) @ self._tool

    def link_poses(self, q: ArrayLike) -> dict[str, np.ndarray]:
        """4x4 world pose of every link."""
        q = self.check_q(q)
        pin.framesForwardKinematics(self.model, self.data, q)
        return {n: self.data.oMf[self._frame_index[n]].homogeneous for n in self._link_names}

    def jacobian(self, q: ArrayLike) -> np.ndarray:
        """6xn world-aligned Jacobian [v; w] of the TCP: linear velocity of the TCP point."""
        q = self.check_q(q)
        p_local = (self.model.frames[self._flange_id].placement.homogeneous @ self._tool)[:3, 3]
        j = self.model.frames[self._flange_id].parentJoint
        return self._point_jacobians(q, np.array([j]), p_local[None])[1][0]

    def point_jacobian(self, q: ArrayLike, link: str, point: ArrayLike) -> np.ndarray:
        """6xn world-aligned Jacobian of a point fixed on ``link`` (``point`` in the link frame).

        Rows 0-2 map qd to the point's linear velocity (J_rep of Ch. 4 when the point is the
        closest point), rows 3-5 to the link's angular velocity.
        """
        q = self.check_q(q)
        point = as_array(point, "point", (3,))
        j = self.link_joint(link)
        p = (self._link_in_joint[link] @ np.append(point, 1.0))[:3]
        return self._point_jacobians(q, np.array([j]), p[None])[1][0]

    def points_kinematics(self, q: np.ndarray, joints: np.ndarray, points: np.ndarray, *,
                          angular: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """World positions (m, 3) and world-aligned Jacobians of m points fixed on joints.

        ``joints[i]`` is the Pinocchio joint index point i hangs on and ``points[i]`` its position
        in that joint's frame. One Pinocchio pass for all points. Returns linear Jacobians
        (m, 3, n), or with ``angular=True`` full (m, 6, n) Jacobians [v; w].
        """
        P, J = self._point_jacobians(q, joints, points)
        return (P, J) if angular else (P, J[:, :3])

    def points_kinematics_batch(self, Q: ArrayLike, joints: np.ndarray, points: np.ndarray, *,
                                angular: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`points_kinematics` for many configurations Q (B, n).

        Positions (B, m, 3) and Jacobians (B, m, 3, n) (``angular=True``: (B, m, 6, n)). One compiled pass for all.
        """
        Q = as_array(Q, "Q", (None, self.nq))
        B, nj = len(Q), self.model.njoints
        Ts = np.empty((B, nj, 4, 4))
        Jws = np.empty((B, 6, self.nq))
        if self._chain_batch:  # compiled over the joint chain: Pinocchio's placements and joint Jacobians
            chain_jacobians_batch(np.ascontiguousarray(Q, dtype=float), *self.chain, Ts, Jws)
        else:
            for b in range(B):
                pin.computeJointJacobians(self.model, self.data, Q[b])
                for i, x in enumerate(self._oMi):
                    Ts[b, i] = x.np
                Jws[b] = self._Jw
        m = len(joints)
        P = np.empty((B, m, 3))
        J = np.empty((B, m, 6, self.nq))
        points_jacobians_batch(Ts, Jws, np.asarray(joints, np.int64), np.asarray(points, float), self._ancestor, P, J)
        return (P, J) if angular else (P, J[:, :, :3])

    def _point_jacobians(self, q: np.ndarray, joints: np.ndarray,
                         points: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        d = self.data
        pin.computeJointJacobians(self.model, d, q)
        for i, x in enumerate(self._oMi):
            self._T[i] = x.np
        m = len(joints)
        P = np.empty((m, 3))
        J = np.empty((m, 6, self.nq))
        points_jacobians(self._T, self._Jw, np.asarray(joints, np.int64), np.asarray(points, float),
                         self._ancestor, P, J)
        return P, J

    # ------------------------------------------------------------------ inverse kinematics
    @property
    def has_closed_form_ik(self) -> bool:
        """Whether the robot has an analytic IK (the LR Mate)."""
        return self._ik is not None

    def ik(self, T: ArrayLike, *, q_ref: ArrayLike | None = None, all_turns: bool = False) -> list[np.ndarray]:
        """All joint solutions reaching the TCP pose ``T`` (4x4), within joint limits.

        Closed form for the LR Mate (up to 8 solutions; ``all_turns=True`` adds the 2*pi turns of
        J4 and J6 that stay within limits); a damped least-squares search for other arms. With
        ``q_ref``, solutions are sorted by distance to it.

        Raises:
            IKFailure: no solution within joint limits.
        """
        if not (type(T) is np.ndarray and T.shape == (4, 4) and T.dtype == np.float64 and np.isfinite(T.sum())):
            T = as_array(T, "T", (4, 4))
        Tf = T if self._tool_is_identity else T @ np.linalg.inv(self._tool)
        if self._ik is not None:
            sols = self._ik.solve(Tf, all_turns=all_turns)
        else:
            q0 = self.check_q(q_ref) if q_ref is not None else None
            sols = [self.ik_numeric(T, q0=q0)]
        if not sols:
            raise IKFailure(f"no IK solution within joint limits for the pose with position "
                            f"{np.round(T[:3, 3], 4).tolist()} m; move it into the workspace", value=T)
        if q_ref is not None:
            q_ref = self.check_q(q_ref, "q_ref")
            sols.sort(key=lambda s: float(np.linalg.norm(s - q_ref)))
        return sols

    def ik_numeric(self, T: ArrayLike, *, q0: ArrayLike | None = None, tol: float = 1e-9, max_iter: int = 100,
                   restarts: int = 200, rng: int | None = 0, damping: float | None = None) -> np.ndarray:
        """Numeric IK for any chain: q within the joint limits such that fk(q) = T.

        Levenberg-Marquardt on the 6-D pose error [p* - p; log(R* R^T)] (world frame) with
        error-adapted damping, each step clipped to the limits, compiled; from ``q0`` (or the
        mid-range), then from uniform random configurations until one converges.

        Args:
            T: (4, 4) TCP pose (flange composed with :attr:`tool`) in the world frame.
            q0: first start (nq,), rad.
            tol: converged when the 6-D error's norm is below it (m and rad).
            max_iter: iterations per start.
            restarts: random starts after the first.
            rng: seed of the random starts.
            damping: unused (kept for callers of the damped least-squares solver it replaced).

        Returns:
            (nq,) the solution, rad (m for prismatic joints).

        Raises:
            IKFailure: no start converged (the pose is unreachable within the limits, or needs more restarts).
        """
        return numeric_ik(self, T, q0=q0, tol=tol, max_iter=max_iter, restarts=restarts, rng=rng)

    # ------------------------------------------------------------------ URDF geometry
    def _read_primitives(self) -> dict[str, list[dict]]:
        return read_collision_geometry(self._root, self.urdf_path, self.package_dirs, set(self._link_names))

    def collision_primitives(self) -> dict[str, list[dict]]:
        """Collision geometry of each link from the URDF.

        Dicts with ``type`` (box, cylinder, sphere, capsule, mesh), ``size`` (a mesh's scale),
        ``origin`` (4x4 in the link frame), ``filename`` and, for a mesh, ``path`` (the resolved file).
        """
        return {k: [dict(p) for p in v] for k, v in self._primitives.items()}

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nq={self.nq}, flange={self.flange_frame!r})"
