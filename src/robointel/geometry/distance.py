"""Robot-obstacle distances with exact gradients.

The closest points and J_rep of Ch. 4 ((4.1)-(4.3), (4.6)) and the collision constraints d(x_t, O) >= d_min of the
CFS planner (Ch. 7, (7.1)-(7.3)).

The robot is covered by spheres on control points (Fig. 4.2, :class:`robointel.robot.SphereModel`).
For sphere i with centre c_i(q), radius r_i and obstacle k with signed distance field phi_k, the
surface-to-surface signed distance and its gradient are

    d_ik(q) = phi_k(c_i(q)) - r_i,        dd_ik/dq = n_ik^T J_i(q),

with n_ik = grad phi_k(c_i) the unit normal from the obstacle toward the sphere and J_i the linear
Jacobian of the centre. The closest robot point is p_i = c_i - r_i n_ik; the Jacobian J_rep of
(4.6) is that of p_i taken as a point fixed on its link, J_rep = J_v(c_i) - [p_i - c_i]x J_w.

All primitive obstacles of a list are evaluated by one compiled call (numba), whatever their types;
point clouds by one k-d tree query each. One robot-kinematics pass per configuration.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from robointel._validate import as_array
from robointel.errors import CollisionAtStart, InvalidInput
from robointel.geometry import _kernels as K
from robointel.geometry.obstacles import Box, Capsule, Cylinder, Obstacle, PointCloud, Sphere

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot, SphereModel

__all__ = [
    "ObstacleSet", "SphereDistances", "MinDistance", "ClosestPairs", "SelfDistance", "Collision",
    "sphere_distances", "sphere_distances_batch", "min_distance", "closest_pairs", "self_collision_distance",
    "in_collision", "check_collision_free", "warmup",
]


class ObstacleSet:
    """Obstacles packed for the compiled kernels (built once per obstacle list and cached).

    Functions here accept a sequence of :class:`Obstacle`, one obstacle or an ``ObstacleSet``;
    passing the same list object again reuses its packing. Column ``k`` of every result refers to
    ``obstacles[k]``.
    """

    __slots__ = ("obstacles", "types", "params", "cols", "clouds", "labels")

    def __init__(self, obstacles: Iterable[Obstacle] | Obstacle = ()) -> None:
        if isinstance(obstacles, Obstacle):
            obstacles = (obstacles,)
        obs = tuple(obstacles)
        for k, o in enumerate(obs):
            if not isinstance(o, Obstacle):
                raise InvalidInput(f"obstacles[{k}] is a {type(o).__name__}, not a robointel.geometry obstacle "
                                   "(Sphere, Capsule, Cylinder, Box, PointCloud)", value=o)
        self.obstacles = obs
        prim = [k for k, o in enumerate(obs) if not isinstance(o, PointCloud)]
        self.cols = np.array(prim, dtype=np.int64)
        self.types = np.array([obs[k]._code for k in prim], dtype=np.int64)
        packed = [obs[k]._packed for k in prim]  # type: ignore[attr-defined]  # every primitive packs its parameters
        self.params = np.array(packed, dtype=np.float64).reshape(-1, K.NPARAM)
        self.clouds = [(k, o) for k, o in enumerate(obs) if isinstance(o, PointCloud)]
        self.labels = tuple(o.label(k) for k, o in enumerate(obs))

    def __len__(self) -> int:
        return len(self.obstacles)

    def __iter__(self) -> Iterator[Obstacle]:
        return iter(self.obstacles)

    def __getitem__(self, k: int) -> Obstacle:
        return self.obstacles[k]


_CACHE: dict[tuple, tuple[tuple, ObstacleSet]] = {}


def _obstacle_set(obstacles: Any) -> ObstacleSet:
    if isinstance(obstacles, ObstacleSet):
        return obstacles
    if isinstance(obstacles, Obstacle):
        obstacles = (obstacles,)
    elif not isinstance(obstacles, (list, tuple)):
        obstacles = tuple(obstacles)
    key = tuple(map(id, obstacles))
    hit = _CACHE.get(key)
    if hit is not None:  # obstacles are immutable: same objects, same packing
        return hit[1]
    s = ObstacleSet(obstacles)
    if len(_CACHE) > 64:
        _CACHE.clear()
    _CACHE[key] = (s.obstacles, s)  # keep the objects alive so their ids stay unique
    return s


def _sphere_model(robot: Robot, spheres: SphereModel | None) -> SphereModel:
    s = robot.spheres if spheres is None else spheres
    if not hasattr(s, "kinematics") or not hasattr(s, "radii"):
        raise InvalidInput(f"spheres must be a robointel.robot.SphereModel, got {type(s).__name__}", value=s)
    return s


@dataclass
class SphereDistances:
    """Distances between m robot spheres and k obstacles at one configuration.

    Distances between m robot spheres and k obstacles at one configuration (leading (T,) axis added by
    :func:`sphere_distances_batch`).

    Attributes:
        d: (m, k) signed surface-to-surface distances (m), negative when penetrating.
        grad: (m, k, n) dd/dq (m/rad), n^T J (the linearisation CFS uses, Ch. 7).
        normals: (m, k, 3) unit normals from the obstacle toward the sphere.
        robot_points: (m, k, 3) closest points on the robot spheres.
        obstacle_points: (m, k, 3) closest points on the obstacles.
        spheres: (m,) index of each row's sphere in the sphere model.
        obstacles: the k obstacles (column order).
    """

    d: np.ndarray
    grad: np.ndarray
    normals: np.ndarray
    robot_points: np.ndarray
    obstacle_points: np.ndarray
    spheres: np.ndarray
    obstacles: tuple

    def argmin(self) -> tuple[int, int]:
        """(row, column) of the smallest distance (one configuration; raises if empty)."""
        if self.d.size == 0:
            raise InvalidInput("no sphere/obstacle pairs to take a minimum over")
        i, k = np.unravel_index(int(np.argmin(self.d)), self.d.shape)
        return int(i), int(k)


def _rows(sm: SphereModel, movable_only: bool) -> np.ndarray:
    """Indices of the spheres to use: all, or those on links that move."""
    if movable_only:
        return np.flatnonzero(np.asarray(sm.movable, bool))
    return np.arange(len(sm.radii))


def _fill(C: np.ndarray, J: np.ndarray, radii: np.ndarray, rows: np.ndarray, os_: ObstacleSet, D: np.ndarray,
          N: np.ndarray, RP: np.ndarray, OP: np.ndarray, G: np.ndarray) -> None:
    """Fill the output arrays for the spheres ``rows`` of centres C (M,3), Jacobians J (M,>=3,n)."""
    if len(os_.types):
        K.sphere_pairs(C, J, radii, rows, os_.types, os_.params, os_.cols, D, N, RP, OP, G)
    if os_.clouds:
        C, J, radii = C[rows], J[rows], radii[rows]
    for k, cloud in os_.clouds:
        dk, ok, nk = cloud.distance(C)
        D[:, k] = dk - radii
        N[:, k] = nk
        OP[:, k] = ok
        RP[:, k] = C - radii[:, None] * nk
        G[:, k] = np.einsum("mj,mjn->mn", nk, J[:, :3])


def _alloc(m: int, k: int, n: int) -> tuple[NDArray[np.float64], ...]:
    return np.empty((m, k)), np.empty((m, k, 3)), np.empty((m, k, 3)), np.empty((m, k, 3)), np.empty((m, k, n))


def sphere_distances(robot: Robot, q: ArrayLike, obstacles: Any, spheres: SphereModel | None = None, *,
                     movable_only: bool = False) -> SphereDistances:
    """Signed distances, closest points and exact gradients between every robot sphere and obstacle.

    Signed distances, closest points and exact gradients between every robot sphere and every obstacle at
    configuration ``q`` (n,) (d = phi(c(q)) - r, dd/dq = n^T J; the collision constraints of (7.1)-(7.3)).

    Args:
        robot: the robot (its :attr:`spheres` are used unless ``spheres`` is given).
        q: (n,) joint configuration (rad / m).
        obstacles: sequence of obstacles (or one, or an :class:`ObstacleSet`).
        spheres: another :class:`SphereModel` bound to ``robot``.
        movable_only: drop spheres on links that never move (their gradient is zero).

    Raises:
        ShapeError / NotFinite: bad ``q``. InvalidInput: not an obstacle.
    """
    sm = _sphere_model(robot, spheres)
    os_ = _obstacle_set(obstacles)
    C, J = sm.kinematics(q)
    radii = np.asarray(sm.radii, float)
    rows = _rows(sm, movable_only)
    D, N, RP, OP, G = _alloc(len(rows), len(os_), J.shape[2])
    _fill(C, J, radii, rows, os_, D, N, RP, OP, G)
    return SphereDistances(D, G, N, RP, OP, rows, os_.obstacles)


def sphere_distances_batch(robot: Robot, Q: ArrayLike, obstacles: Any, spheres: SphereModel | None = None, *,
                           movable_only: bool = False,
                           kinematics: tuple[np.ndarray, np.ndarray] | None = None) -> SphereDistances:
    """:func:`sphere_distances` at T configurations ``Q`` (T, n) in one compiled call.

    :func:`sphere_distances` at T configurations ``Q`` (T, n) in one compiled call (CFS collision constraints at all
    time steps, Ch. 7). Results carry a leading (T,) axis: d (T, m, k), grad (T, m, k, n), normals/points (T, m, k,
    3); ``spheres`` stays (m,). ``kinematics``: the sphere model's ``kinematics_batch(Q)`` (centres (T, M, 3) m,
    Jacobians (T, M, 3, n)) when the caller has it already (all M spheres of the model).
    """
    sm = _sphere_model(robot, spheres)
    os_ = _obstacle_set(obstacles)
    Q = as_array(Q, "Q", (None, robot.nq))
    idx = _rows(sm, movable_only)
    mask = np.asarray(sm.movable, bool)
    radii = np.asarray(sm.radii, float)[idx]
    T, m, n = len(Q), len(idx), robot.nq
    if T and (kinematics is not None or hasattr(sm, "kinematics_batch")):
        # one compiled kinematics pass over all configurations
        C, J = sm.kinematics_batch(Q) if kinematics is None else kinematics
        if movable_only:
            C, J = C[:, mask], J[:, mask]
        C, J = np.ascontiguousarray(C), np.ascontiguousarray(J)
    else:
        C = np.empty((T, m, 3))
        J = np.empty((T, m, 3, n))
        kin = sm.kinematics
        for t in range(T):
            c, j = kin(Q[t])
            C[t], J[t] = (c[mask], j[mask]) if movable_only else (c, j)
    k = len(os_)
    D, N, RP, OP, G = _alloc(T * m, k, n)
    _fill(C.reshape(T * m, 3), J.reshape(T * m, 3, n), np.tile(radii, T), np.arange(T * m), os_, D, N, RP, OP, G)
    return SphereDistances(D.reshape(T, m, k), G.reshape(T, m, k, n), N.reshape(T, m, k, 3),
                           RP.reshape(T, m, k, 3), OP.reshape(T, m, k, 3), idx, os_.obstacles)


@dataclass
class MinDistance:
    """The closest (robot control point, obstacle) pair at one configuration (Ch. 4).

    Attributes:
        distance: signed surface-to-surface distance (m); ``inf`` when there is no obstacle.
        sphere: index of the robot sphere in the sphere model (-1 when none).
        link: the link that sphere is fixed on.
        obstacle: index of the obstacle in the given list (-1 when none).
        obstacle_name: its name, or ``"<type>[index]"``.
        robot_point: (3,) closest point on the robot sphere (world, m).
        obstacle_point: (3,) closest point on the obstacle.
        normal: (3,) unit vector from the obstacle toward the robot.
        gradient: (n,) d distance / dq = normal^T jacobian.
        jacobian: (3, n) J_rep of (4.6): linear Jacobian of ``robot_point`` fixed on ``link``.
    """

    distance: float
    sphere: int
    link: str
    obstacle: int
    obstacle_name: str
    robot_point: np.ndarray
    obstacle_point: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray
    jacobian: np.ndarray


def _cloud_min(os_: ObstacleSet, C: np.ndarray, radii: np.ndarray, rows: np.ndarray, best: Any) -> Any:
    """Update ``best`` = (d, i, k, o, n) with the point clouds (i indexes C)."""
    for k, cloud in os_.clouds:
        dk, ok, nk = cloud.distance(C[rows])
        dk = dk - radii[rows]
        ii = int(np.argmin(dk))
        if dk[ii] < best[0]:
            best = (float(dk[ii]), int(rows[ii]), k, ok[ii].copy(), nk[ii].copy())
    return best


def min_distance(robot: Robot, q: ArrayLike, obstacles: Any, spheres: SphereModel | None = None, *,
                 movable_only: bool = False) -> MinDistance:
    """Minimum signed distance between the robot spheres and the obstacles at ``q`` (n,).

    Minimum signed distance between the robot spheres and the obstacles at ``q`` (n,), with the closest pair, the
    gradient (n,) and J_rep (3, n) of the closest robot point (Ch. 4: the distance and repulsive direction of
    (4.1)-(4.3), J_rep of (4.6)).

    With no obstacles (or no spheres) the distance is ``inf`` and indices are -1.
    """
    sm = _sphere_model(robot, spheres)
    os_ = _obstacle_set(obstacles)
    C, J = sm.kinematics(q, angular=True)
    radii = np.asarray(sm.radii, float)
    n = J.shape[2]
    rows = _rows(sm, movable_only)
    best = (np.inf, -1, -1, None, None)
    if len(os_.types) and len(rows):
        d, i, j, o, nrm = K.sphere_pairs_min(C, radii, rows, os_.types, os_.params)
        best = (d, i, int(os_.cols[j]), o, nrm)
    if os_.clouds and len(rows):
        best = _cloud_min(os_, C, radii, rows, best)
    d, i, k, o, nrm = best
    if i < 0:
        z = np.zeros(3)
        return MinDistance(np.inf, -1, "", -1, "", z, z.copy(), z.copy(), np.zeros(n), np.zeros((3, n)))
    assert o is not None and nrm is not None
    p, g, Jrep = K.rep_terms(C[i], J[i], radii[i], nrm)
    return MinDistance(float(d), int(i), sm.links[i], k, os_.labels[k], p, o, nrm, g, Jrep)


@dataclass
class ClosestPairs:
    """For each of k obstacles, its closest robot sphere at one configuration.

    One repulsive constraint per obstacle (the QP (4.11) of Ch. 4, with J_rep (4.6) of each closest point).

    Attributes:
        distance: (k,) signed surface distances (m); ``inf`` where there is no robot sphere.
        sphere: (k,) sphere index of each obstacle's closest robot sphere (-1 when none).
        links: k link names; obstacle_names: k obstacle labels.
        robot_point, obstacle_point, normal: (k, 3) as in :class:`MinDistance`.
        gradient: (k, n) d distance / dq. jacobian: (k, 3, n) J_rep of each robot point.
    """

    distance: np.ndarray
    sphere: np.ndarray
    links: list
    obstacle_names: list
    robot_point: np.ndarray
    obstacle_point: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray
    jacobian: np.ndarray

    def __len__(self) -> int:
        return len(self.distance)

    def __getitem__(self, k: int) -> MinDistance:
        """The pair of obstacle ``k`` as a :class:`MinDistance`."""
        return MinDistance(float(self.distance[k]), int(self.sphere[k]), self.links[k], k, self.obstacle_names[k],
                           self.robot_point[k], self.obstacle_point[k], self.normal[k], self.gradient[k],
                           self.jacobian[k])


def closest_pairs(robot: Robot, q: ArrayLike, obstacles: Any, spheres: SphereModel | None = None, *,
                  movable_only: bool = False) -> ClosestPairs:
    """For every obstacle, the closest robot sphere at ``q`` (n,).

    For every obstacle, the closest robot sphere at ``q`` (n,) with distance, closest points, normal, gradient and
    J_rep (4.6): the per-obstacle constraints of the guidance QP (4.11).
    """
    sm = _sphere_model(robot, spheres)
    os_ = _obstacle_set(obstacles)
    C, J = sm.kinematics(q, angular=True)
    radii = np.asarray(sm.radii, float)
    n, k = J.shape[2], len(os_)
    rows = _rows(sm, movable_only)
    D, S = np.full(k, np.inf), np.full(k, -1, np.int64)
    O, N, P, G, JR = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, n)), np.zeros((k, 3, n))
    if len(os_.types):
        K.per_obstacle_min(C, J, radii, rows, os_.types, os_.params, os_.cols, D, S, O, N, P, G, JR)
    if len(rows):
        for c, cloud in os_.clouds:
            dk, ok, nk = cloud.distance(C[rows])
            dk = dk - radii[rows]
            ii = int(np.argmin(dk))
            i = int(rows[ii])
            D[c], S[c], O[c], N[c] = dk[ii], i, ok[ii], nk[ii]
            P[c], G[c], JR[c] = K.rep_terms(C[i], J[i], radii[i], N[c])
    links = sm.links
    return ClosestPairs(D, S, [links[i] if i >= 0 else "" for i in S.tolist()], list(os_.labels), P, O, N, G, JR)


@dataclass
class SelfDistance:
    """Closest self-collision pair (spheres on non-adjacent links, ``SphereModel.self_pairs``).

    Attributes:
        distance: signed surface distance (m); ``inf`` when the model has no self pairs.
        spheres: (i, k) sphere indices; links: their links.
        normal: (3,) unit vector from sphere k toward sphere i.
        points: (2, 3) closest points on spheres i and k.
        gradient: (n,) d distance / dq.
    """

    distance: float
    spheres: tuple[int, int]
    links: tuple[str, str]
    normal: np.ndarray
    points: np.ndarray
    gradient: np.ndarray


def self_collision_distance(robot: Robot, q: ArrayLike, spheres: SphereModel | None = None) -> SelfDistance:
    """Minimum signed distance over the robot's self-collision sphere pairs, with its gradient."""
    sm = _sphere_model(robot, spheres)
    C, J = sm.kinematics(q)
    pairs = np.asarray(sm.self_pairs, int).reshape(-1, 2)
    n = J.shape[2]
    if len(pairs) == 0:
        return SelfDistance(np.inf, (-1, -1), ("", ""), np.zeros(3), np.zeros((2, 3)), np.zeros(n))
    radii = np.asarray(sm.radii, float)
    a, b = pairs[:, 0], pairs[:, 1]
    v = C[a] - C[b]
    L = np.sqrt(np.einsum("ij,ij->i", v, v))
    d = L - radii[a] - radii[b]
    p = int(np.argmin(d))
    i, k = int(a[p]), int(b[p])
    u = v[p] / L[p] if L[p] > 1e-12 else np.array([0.0, 0.0, 1.0])
    pts = np.array([C[i] - radii[i] * u, C[k] + radii[k] * u])
    return SelfDistance(float(d[p]), (i, k), (sm.links[i], sm.links[k]), u, pts, u @ (J[i] - J[k]))


@dataclass
class Collision:
    """Result of :func:`in_collision`; true (``bool(result)``) when in collision.

    Attributes:
        colliding: distance < margin.
        distance: the smallest signed distance found (m).
        link: robot link of the closest sphere; obstacle: obstacle index (-1 for self-collision);
        obstacle_name: obstacle name, or the other link for a self-collision.
        message: a sentence naming link and obstacle (for :class:`CollisionAtStart`).
    """

    colliding: bool
    distance: float
    link: str
    obstacle: int
    obstacle_name: str
    margin: float = 0.0

    def __bool__(self) -> bool:
        return self.colliding

    @property
    def message(self) -> str:
        """Human-readable verdict naming the closest link and obstacle."""
        if not np.isfinite(self.distance):
            return "no obstacles to collide with"
        what = "penetrates" if self.distance < 0 else ("is within the margin of" if self.colliding else "clears")
        return (f"link {self.link!r} {what} {self.obstacle_name!r} (signed distance {self.distance * 1e3:.1f} mm, "
                f"margin {self.margin * 1e3:.1f} mm)")


def in_collision(robot: Robot, q: ArrayLike, obstacles: Any, margin: float = 0.0, *, spheres: SphereModel | None = None,
                 self_collision: bool = False) -> Collision:
    """Whether any robot sphere is closer than ``margin`` (m) to an obstacle or (optionally) another link.

    Is any robot sphere closer than ``margin`` (m) to an obstacle (or, with ``self_collision``, to a non-adjacent
    link)? The result is truthy when colliding and names link and obstacle.
    """
    margin = float(as_array(margin, "margin", ()))
    md = min_distance(robot, q, obstacles, spheres)
    res = Collision(md.distance < margin, md.distance, md.link, md.obstacle, md.obstacle_name, margin)
    if self_collision:
        sd = self_collision_distance(robot, q, spheres)
        if sd.distance < res.distance:
            res = Collision(sd.distance < margin, sd.distance, sd.links[0], -1, f"self: {sd.links[1]}", margin)
    return res


def check_collision_free(robot: Robot, q: ArrayLike, obstacles: Any, margin: float = 0.0, *,
                         what: str = "start configuration", spheres: SphereModel | None = None,
                         self_collision: bool = False) -> Collision:
    """Raise :class:`CollisionAtStart` naming link and obstacle when ``q`` is in collision.

    Returns the (non-colliding) :class:`Collision` result otherwise.
    """
    res = in_collision(robot, q, obstacles, margin, spheres=spheres, self_collision=self_collision)
    if res:
        raise CollisionAtStart(f"{what} is in collision: {res.message}; move the {what} or the obstacle",
                               value=np.asarray(q, float))
    return res


def warmup() -> None:
    """Compile (or load from numba's on-disk cache) every distance kernel now.

    Compile (or load from numba's on-disk cache) every distance kernel now, so that the first call inside a control
    loop does not pay the compilation (about a second per kernel, once).
    """
    z, e = np.zeros(3), np.array([0.0, 0.0, 1.0])
    prims = [Sphere(z, 0.1), Capsule(z, e, 0.1), Cylinder(z, e, 0.1), Box(z, np.ones(3))]
    os_ = ObstacleSet(prims)
    C = np.zeros((2, 3))
    radii = np.full(2, 0.05)
    rows = np.arange(2)
    for n in (6,):
        J6 = np.zeros((2, 6, n))
        for J in (J6[:, :3], np.ascontiguousarray(J6[:, :3])):  # the view the robot core returns, and contiguous
            D, N, RP, OP, G = _alloc(2, len(prims), n)
            K.sphere_pairs(C, J, radii, rows, os_.types, os_.params, os_.cols, D, N, RP, OP, G)
        d, i, j, o, nrm = K.sphere_pairs_min(C, radii, rows, os_.types, os_.params)
        K.rep_terms(C[i], J6[i], radii[i], nrm)
        k = len(prims)
        K.per_obstacle_min(C, J6, radii, rows, os_.types, os_.params, os_.cols, np.zeros(k), np.zeros(k, np.int64),
                           np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, n)),
                           np.zeros((k, 3, n)))
    for p in prims:
        p.distance(C)
