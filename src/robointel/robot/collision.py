"""Collision model of the arm: spheres on control points along each link (Fig. 4.2).

Spheres are generated from each link's collision primitives so that they cover the primitive
(conservative envelope) and can be read, edited, saved and loaded.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from robointel._validate import as_array
from robointel.errors import DescriptionError, InvalidInput
from robointel.robot.protocol import KinematicRobot


def _spine_spheres(half_length: float, radius: float, count: int | None, inflate: float) -> tuple[np.ndarray, float]:
    """Centres along the local z axis and the common radius covering a cylinder (r, 2*half_length)."""
    length = 2.0 * half_length
    n = count if count is not None else max(1, int(np.ceil(length / max(radius, 1e-6) - 1e-9)))
    s = length / n
    z = -half_length + s * (np.arange(n) + 0.5)
    r = float(np.sqrt(radius ** 2 + (s / 2) ** 2)) + inflate
    return np.stack([np.zeros(n), np.zeros(n), z], 1), r


def primitive_spheres(prim: dict, count: int | None = None, inflate: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Sphere centres (k, 3) in the link frame and radii (k,) covering one collision primitive."""
    T = prim["origin"]
    kind, size = prim["type"], np.asarray(prim["size"], float)
    if kind == "sphere":
        return T[:3, 3][None].copy(), np.array([size[0] + inflate])
    if kind in ("cylinder", "capsule"):
        r, L = size
        half = L / 2 if kind == "cylinder" else L / 2 + r * 0.0
        c, rad = _spine_spheres(half, r, count, inflate)
        return c @ T[:3, :3].T + T[:3, 3], np.full(len(c), rad)
    if kind == "box":
        ax = int(np.argmax(size))
        others = [i for i in range(3) if i != ax]
        cross_r = 0.5 * float(np.hypot(size[others[0]], size[others[1]]))
        c, rad = _spine_spheres(size[ax] / 2, cross_r, count, inflate)
        perm = np.zeros((3, 3))
        perm[ax, 2] = 1.0
        perm[others[0], 0] = 1.0
        perm[others[1], 1] = 1.0
        c = c @ perm.T  # spine along the box's longest axis
        return c @ T[:3, :3].T + T[:3, 3], np.full(len(c), rad)
    if kind == "mesh" and prim.get("vertices") is not None:
        v = prim["vertices"] @ T[:3, :3].T + T[:3, 3]
        lo, hi = v.min(0), v.max(0)
        box = {"type": "box", "size": np.maximum(hi - lo, 1e-3), "origin": np.eye(4)}
        box["origin"][:3, 3] = (lo + hi) / 2
        return primitive_spheres(box, count, inflate)
    return np.zeros((0, 3)), np.zeros(0)


@dataclass
class SphereModel:
    """Spheres fixed on the robot's links.

    Attributes:
        links: link name of each sphere (m,).
        centers: centre of each sphere in its link frame, (m, 3), metres.
        radii: (m,), metres.
        joints: Pinocchio joint index each sphere moves with (filled by :meth:`bind`).
    """

    links: list[str]
    centers: np.ndarray
    radii: np.ndarray
    joints: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    _in_joint: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)), repr=False)
    self_pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), int), repr=False)
    _robot: KinematicRobot | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.links)

    @classmethod
    def from_robot(cls, robot: KinematicRobot, *, count: int | None = None, inflate: float = 0.0,
                   include_base: bool = True) -> SphereModel:
        """Generate spheres covering every collision primitive of ``robot``'s URDF.

        Args:
            robot: The robot whose URDF collision primitives are covered.
            count: spheres per primitive (default: enough that spacing <= primitive radius).
            inflate: extra radius added to every sphere (m), a safety margin.
            include_base: keep spheres of links that never move.
        """
        links, centers, radii = [], [], []
        prims = robot.collision_primitives()
        for link, plist in prims.items():
            if link not in robot.link_names:
                continue
            if not include_base and robot.link_joint(link) == 0:
                continue
            for p in plist:
                if p["type"] == "mesh":
                    p = dict(p, vertices=_mesh_vertices(p))
                c, r = primitive_spheres(p, count, inflate)
                links += [link] * len(r)
                centers.append(c)
                radii.append(r)
        m = cls(links, np.concatenate(centers) if centers else np.zeros((0, 3)),
                np.concatenate(radii) if radii else np.zeros(0))
        m.bind(robot)
        return m

    def bind(self, robot: KinematicRobot) -> SphereModel:
        """Attach to a robot: resolve joints, joint-frame centres and self-collision pairs."""
        self.centers = as_array(self.centers, "centers", (len(self.links), 3))
        self.radii = as_array(self.radii, "radii", (len(self.links),))
        if np.any(self.radii <= 0):
            raise InvalidInput("sphere radii must be positive", value=self.radii)
        self._robot = robot
        self.joints = np.array([robot.link_joint(l) for l in self.links], dtype=int)
        Ts = [robot._link_in_joint[l] for l in self.links]
        self._in_joint = np.array([T[:3, :3] @ c + T[:3, 3] for T, c in zip(Ts, self.centers)]).reshape(-1, 3)
        self.self_pairs = self._self_pairs(robot)
        return self

    def _self_pairs(self, robot: KinematicRobot) -> np.ndarray:
        """Sphere pairs to check for self-collision.

        Not on the same or adjacent links, and not already overlapping at the zero configuration (pairs that always
        touch by design).
        """
        m = len(self.links)
        if m == 0:
            return np.zeros((0, 2), int)
        parents = [int(p) for p in robot.model.parents]
        q_mid = np.clip(np.zeros(robot.nq), robot.lower, robot.upper)
        P, _ = robot.points_kinematics(q_mid, self.joints, self._in_joint)
        pairs = []
        for i in range(m):
            for k in range(i + 1, m):
                a, b = self.joints[i], self.joints[k]
                if a == b or parents[a] == b or parents[b] == a:
                    continue
                if np.linalg.norm(P[i] - P[k]) < self.radii[i] + self.radii[k]:
                    continue
                pairs.append((i, k))
        return np.array(pairs, dtype=int).reshape(-1, 2)

    @property
    def movable(self) -> np.ndarray:
        """Boolean mask of spheres that move with some joint."""
        return self.joints > 0

    def kinematics(self, q: ArrayLike, *, angular: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """World centres (m, 3) and linear Jacobians (m, 3, n) of all spheres at ``q`` (``angular=True``.

        Full (m, 6, n) Jacobians [v; w], for points offset from the centres).
        """
        if self._robot is None:
            raise InvalidInput("sphere model is not bound to a robot; call bind(robot)")
        q = self._robot.check_q(q)
        return self._robot.points_kinematics(q, self.joints, self._in_joint, angular=angular)

    def kinematics_batch(self, Q: ArrayLike, *, angular: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Centres (B, m, 3) and Jacobians (B, m, 3, n) (or (B, m, 6, n)) for configurations Q (B, n)."""
        if self._robot is None:
            raise InvalidInput("sphere model is not bound to a robot; call bind(robot)")
        return self._robot.points_kinematics_batch(Q, self.joints, self._in_joint, angular=angular)

    def positions(self, q: ArrayLike) -> np.ndarray:
        """World centres (m, 3) of all spheres."""
        return self.kinematics(q)[0]

    def self_distances(self, q: ArrayLike) -> np.ndarray:
        """Signed distances between the spheres of every self-collision pair."""
        P = self.positions(q)
        i, k = self.self_pairs.T
        return np.linalg.norm(P[i] - P[k], axis=1) - self.radii[i] - self.radii[k]

    # editing -----------------------------------------------------------------
    def add(self, link: str, center: ArrayLike, radius: float) -> None:
        """Add a sphere on ``link`` (centre in the link frame)."""
        self.links.append(link)
        self.centers = np.vstack([self.centers, as_array(center, "center", (3,))])
        self.radii = np.append(self.radii, float(radius))
        if self._robot is not None:
            self.bind(self._robot)

    def remove(self, index: int) -> None:
        """Remove sphere ``index``."""
        if not 0 <= index < len(self.links):
            raise InvalidInput(f"sphere index {index} out of range [0, {len(self.links)})", value=index)
        del self.links[index]
        self.centers = np.delete(self.centers, index, 0)
        self.radii = np.delete(self.radii, index)
        if self._robot is not None:
            self.bind(self._robot)

    def to_dict(self) -> dict:
        """Plain-data form (for YAML/JSON)."""
        return {"spheres": [{"link": l, "center": c.tolist(), "radius": float(r)}
                            for l, c, r in zip(self.links, self.centers, self.radii)]}

    @classmethod
    def from_dict(cls, d: dict, robot: KinematicRobot) -> SphereModel:
        """Inverse of :meth:`to_dict`, bound to ``robot``."""
        try:
            s = d["spheres"]
            m = cls([e["link"] for e in s], np.array([e["center"] for e in s], float).reshape(-1, 3),
                    np.array([e["radius"] for e in s], float))
        except (KeyError, TypeError) as exc:
            raise InvalidInput(f"sphere model dict must be {{'spheres': [{{link, center, radius}}]}}: {exc}") from None
        return m.bind(robot)


def _mesh_vertices(prim: dict) -> np.ndarray | None:
    """Vertices of a mesh collision primitive (scaled; the file found when the robot was loaded)."""
    path = prim.get("path")
    if path is None:
        return None
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise DescriptionError(f"cannot read mesh {path}: {exc}", value=str(path)) from None
    return np.asarray(mesh.vertices) * np.asarray(prim["size"], float)  # type: ignore[union-attr,attr-defined]
