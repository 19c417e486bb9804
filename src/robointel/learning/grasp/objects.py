"""Objects for grasping: real YCB scans, generated primitives and articulated toy robot arms.

Every object is an :class:`ObjectModel` in its own frame: resting upright on ``z = 0`` and centred
at the origin in x, y (metres), with a surface ``mesh`` (for point sampling and ray casting) and
convex collision ``pieces`` (for MuJoCo).

* :func:`ycb_object` reads ``objects/ycb/<name>/mesh.ply`` (scan) and ``collision.stl`` (V-HACD,
  split into its connected convex parts) from the shared reference data.
* :func:`primitive_object` builds cups, cans, boxes, balls and long tools with trimesh.
* :func:`toy_arm` poses a robot arm from ``example-robot-data`` (UR5, Panda) at given joint angles
  with Pinocchio, gathers its collision meshes and scales it to toy size (the articulated category).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import numpy.typing as npt
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from robointel.errors import DataMissing, InvalidInput
from robointel.learning.grasp.transfer import Grasp, grasp_from_axis

if TYPE_CHECKING:
    from robointel.learning.grasp.quality import ParallelGripper

__all__ = ["ObjectModel", "YCB_CATEGORIES", "ycb_object", "primitive_object", "toy_arm", "split_convex",
           "sample_points", "taught_grasps", "sampled_grasps", "top_down_grasps", "demo_objects", "ycb_objects"]

YCB_CATEGORIES: dict[str, list[str]] = {
    "cup": ["065-a_cups", "065-b_cups", "065-c_cups", "065-d_cups", "065-e_cups", "065-f_cups", "065-g_cups",
            "065-h_cups", "065-i_cups", "065-j_cups"],
    "clamp": ["050_medium_clamp", "051_large_clamp", "052_extra_large_clamp"],
    "can": ["005_tomato_soup_can", "002_master_chef_can", "007_tuna_fish_can", "010_potted_meat_can"],
    "box": ["004_sugar_box", "003_cracker_box", "008_pudding_box", "009_gelatin_box", "036_wood_block"],
    "ball": ["055_baseball", "053_mini_soccer_ball", "054_softball", "056_tennis_ball", "057_racquetball",
             "058_golf_ball"],
    "long_tool": ["043_phillips_screwdriver", "030_fork", "031_spoon", "032_knife", "040_large_marker",
                  "044_flat_screwdriver"],
}


@dataclass
class ObjectModel:
    """An object in its own frame (z up, resting on z = 0, centred in x, y)."""

    name: str
    category: str
    mesh: trimesh.Trimesh
    pieces: list = field(default_factory=list)
    mass: float = 0.1

    @property
    def height(self) -> float:
        """Height of the object's top above its resting plane (m)."""
        return float(self.mesh.bounds[1, 2])


def split_convex(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """Connected parts of a convex decomposition (e.g. YCB ``collision.stl``), each as its hull."""
    n = len(mesh.faces)
    adj = mesh.face_adjacency
    g = coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(n, n))
    k, lab = connected_components(g, directed=False)
    parts = []
    for i in range(k):
        faces = mesh.faces[lab == i]
        verts = mesh.vertices[np.unique(faces)]
        if len(verts) >= 4:
            try:
                hull = trimesh.convex.convex_hull(verts)
            except Exception:  # flat or degenerate piece
                continue
            if hull.volume > 1e-9:
                parts.append(hull)
    return parts


def _canonical(mesh: trimesh.Trimesh, pieces: list) -> tuple[trimesh.Trimesh, list]:
    c = mesh.bounds.mean(axis=0)
    off = np.array([-c[0], -c[1], -mesh.bounds[0, 2]])
    mesh = mesh.copy()
    mesh.apply_translation(off)
    out = []
    for p in pieces:
        p = p.copy()
        p.apply_translation(off)
        out.append(p)
    return mesh, out


def ycb_object(name: str, category: str | None = None, *, density: float = 400.0) -> ObjectModel:
    """Load a YCB object from ``../shared/data/objects/ycb/<name>`` (scan + convex pieces)."""
    from robointel.io.reference import data_path

    folder = data_path("objects", "ycb", name)
    mesh = cast(trimesh.Trimesh, trimesh.load(folder / "mesh.ply", force="mesh"))
    pieces = split_convex(cast(trimesh.Trimesh, trimesh.load(folder / "collision.stl", force="mesh")))
    if not pieces:
        raise DataMissing(f"no convex pieces in {folder / 'collision.stl'}", value=str(folder))
    mesh, pieces = _canonical(mesh, pieces)
    if category is None:
        category = next((c for c, names in YCB_CATEGORIES.items() if name in names), "other")
    mass = float(np.clip(density * sum(p.volume for p in pieces), 0.02, 1.0))
    return ObjectModel(name, category, mesh, pieces, mass)


def ycb_objects(categories: dict[str, list[str]] | None = None) -> dict[str, list[ObjectModel]]:
    """All listed YCB objects by category (default :data:`YCB_CATEGORIES`)."""
    cats = categories or YCB_CATEGORIES
    return {c: [ycb_object(n, c) for n in names] for c, names in cats.items()}


def _ring(r_in: float, r_out: float, z0: float, z1: float, segments: int) -> list[trimesh.Trimesh]:
    out = []
    for i in range(segments):
        a0, a1 = 2 * np.pi * i / segments, 2 * np.pi * (i + 1) / segments
        pts = []
        for a in (a0, a1):
            for r in (r_in, r_out):
                for z in (z0, z1):
                    pts.append([r * np.cos(a), r * np.sin(a), z])
        out.append(trimesh.convex.convex_hull(np.array(pts)))
    return out


def primitive_object(category: str, rng: np.random.Generator | int = 0, name: str | None = None) -> ObjectModel:
    """A generated object of one category with random proportions.

    A generated object of ``category`` ("cup", "can", "box", "ball", "long_tool") with random
    proportions (seeded ``rng``). Sizes fit a 48 mm gripper where the category's taught grasp needs it.
    """
    rng = np.random.default_rng(rng)
    name = name or f"{category}-{int(rng.integers(1 << 30))}"
    if category == "cup":
        r, h, t = rng.uniform(0.032, 0.042), rng.uniform(0.07, 0.095), 0.004
        wall = trimesh.creation.annulus(r_min=r - t, r_max=r, height=h, sections=48)
        wall.apply_translation([0, 0, h / 2])
        bottom = trimesh.creation.cylinder(radius=r, height=t, sections=48)
        bottom.apply_translation([0, 0, t / 2])
        mesh = cast(trimesh.Trimesh, trimesh.util.concatenate([wall, bottom]))
        pieces = _ring(r - t, r, t, h, 16) + [bottom]
        mass = 0.08
    elif category == "can":
        r, h = rng.uniform(0.017, 0.021), rng.uniform(0.085, 0.11)
        mesh = trimesh.creation.cylinder(radius=r, height=h, sections=48)
        mesh.apply_translation([0, 0, h / 2])
        pieces, mass = [mesh], 0.15
    elif category == "box":
        e = np.array([rng.uniform(0.05, 0.09), rng.uniform(0.025, 0.04), rng.uniform(0.05, 0.12)])
        mesh = trimesh.creation.box(extents=e)
        mesh.apply_translation([0, 0, e[2] / 2])
        pieces, mass = [mesh], 0.12
    elif category == "ball":
        r = rng.uniform(0.017, 0.022)
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=r)
        mesh.apply_translation([0, 0, r])
        pieces, mass = [mesh], 0.05
    elif category == "long_tool":
        L, r = rng.uniform(0.12, 0.2), rng.uniform(0.008, 0.013)
        handle = trimesh.creation.cylinder(radius=r, height=0.45 * L, sections=24)
        handle.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
        handle.apply_translation([-0.275 * L, 0, r])
        shaft = trimesh.creation.box(extents=[0.55 * L, 0.3 * r, 0.3 * r])
        shaft.apply_translation([0.225 * L, 0, r])
        mesh = cast(trimesh.Trimesh, trimesh.util.concatenate([handle, shaft]))
        pieces, mass = [handle, shaft], 0.06
    else:
        raise InvalidInput(f"unknown primitive category {category!r}", value=category)
    mesh, pieces = _canonical(mesh, pieces)
    return ObjectModel(name, category, mesh, pieces, mass)


_ARMS = {"ur5": "ur_description/urdf/ur5_robot.urdf", "panda": "panda_description/urdf/panda.urdf"}


def toy_arm(q: npt.ArrayLike | None = None, *, robot: str = "ur5", height: float = 0.25,
            rng: np.random.Generator | int | None = 0,
            name: str | None = None) -> ObjectModel:
    """A posed robot arm from ``example-robot-data`` scaled to a toy (the articulated category).

    A robot arm from ``example-robot-data`` posed at joint angles ``q`` (random within a safe band
    of its limits when None, seeded by ``rng``), its collision meshes merged and scaled so that its
    base-to-top height at the home pose is about ``height`` metres (a toy manipulator).
    """
    import pinocchio as pin

    from robointel.robot.catalogue import example_robot_data_dir

    root = example_robot_data_dir()
    if root is None or robot not in _ARMS:
        raise DataMissing(f"example-robot-data arm {robot!r} not available", value=robot)
    urdf = root / _ARMS[robot]
    model, cmodel, _ = pin.buildModelsFromUrdf(str(urdf),
                                               package_dirs=[str(root.parent.parent), str(root.parent), str(root)])
    data, cdata = model.createData(), cmodel.createData() if hasattr(cmodel, "createData") else pin.GeometryData(cmodel)
    if q is None:
        g = np.random.default_rng(rng)
        lo = np.maximum(model.lowerPositionLimit, -np.pi)
        hi = np.minimum(model.upperPositionLimit, np.pi)
        mid = 0.5 * (lo + hi)
        qr = mid + 0.35 * (hi - lo) * g.uniform(-1, 1, model.nq) * 0.6
        if robot == "ur5":
            qr[1] = g.uniform(-1.85, -1.3)  # upper arm near vertical: the toy stands on its base
            qr[2] = g.uniform(0.3, 1.6)
        q = qr
    q = np.asarray(q, float)
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, cmodel, cdata)
    parts = []
    for go, oMg in zip(cmodel.geometryObjects, cdata.oMg):
        path = Path(go.meshPath)
        if not path.exists():
            continue
        m = trimesh.load(path, force="mesh")
        m.apply_scale(np.asarray(go.meshScale, float))
        m.apply_transform(oMg.homogeneous)
        parts.append(m)
    if not parts:
        raise DataMissing(f"no collision meshes found for {robot}", value=str(urdf))
    mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(parts))
    scale = height / {"ur5": 1.0, "panda": 1.0}[robot]
    mesh.apply_scale(scale)
    pieces = []
    for p in parts:
        p = p.copy()
        p.apply_scale(scale)
        pieces.append(trimesh.convex.convex_hull(p.vertices))
    base = pieces[0]
    # centre on the base (the taught grasp holds the arm by its base)
    c = base.bounds.mean(axis=0)
    off = np.array([-c[0], -c[1], -mesh.bounds[0, 2]])
    mesh.apply_translation(off)
    for p in pieces:
        p.apply_translation(off)
    return ObjectModel(name or f"toy_{robot}", "toy_arm", mesh, pieces, 0.1)


def sample_points(obj: ObjectModel, n: int = 1500, rng: np.random.Generator | int = 0) -> np.ndarray:
    """``n`` points sampled uniformly on the object's surface (object frame)."""
    pts, _ = trimesh.sample.sample_surface(obj.mesh, int(n), seed=np.random.default_rng(rng))
    return np.asarray(pts, float)


def taught_grasps(obj: ObjectModel) -> list[Grasp]:
    """The demonstrated grasps of a category template, as a human would teach them.

    The demonstrated grasps of a category template (object frame), a few per object as a human
    would teach them: cups on the rim wall at four places, cans and balls across from above in two
    directions, boxes across the narrow side at three places, long tools across the handle at three
    places, toy arms around the upper arm in four directions, clamps across the body.
    """
    b = obj.mesh.bounds
    ext = b[1] - b[0]
    h = b[1, 2]
    down = np.array([0.0, 0.0, -1.0])
    cat = obj.category
    if cat == "cup":
        r = 0.5 * ext[0]
        out = []
        for k, a in enumerate(np.radians([0, 90, 180, 270])):
            u = np.array([np.cos(a), np.sin(a), 0.0])
            out.append(grasp_from_axis((r - 0.002) * u + [0, 0, h - 0.012], u, down, 0.01, f"rim{k}"))
        return out
    if cat in ("can", "ball"):
        z = min(0.6 * h, h - 0.01)
        return [grasp_from_axis([0, 0, z], [1, 0, 0], down, ext[0], "side"),
                grasp_from_axis([0, 0, z], [0, 1, 0], down, ext[1], "side2")]
    if cat in ("box", "clamp"):
        ax = 1 if ext[1] < ext[0] else 0
        long = 1 - ax
        out = []
        for k, f in enumerate((0.0, -0.25, 0.25)):
            c = np.zeros(3)
            c[long] = f * ext[long]
            c[2] = max(h - 0.015, 0.5 * h)
            out.append(grasp_from_axis(c, np.eye(3)[ax], down, ext[ax], f"narrow{k}"))
        return out
    if cat == "long_tool":
        long_ax = int(np.argmax(ext[:2]))
        out = []
        for k, f in enumerate((0.15, 0.25, 0.35)):
            c = np.zeros(3)
            c[long_ax] = b[0, long_ax] + f * ext[long_ax]
            c[2] = 0.5 * h
            out.append(grasp_from_axis(c, np.eye(3)[1 - long_ax], down, ext[1 - long_ax], f"handle{k}"))
        return out
    if cat == "toy_arm":
        # around the upper arm (third piece), which stands near vertical on the shoulder
        piece = obj.pieces[2] if len(obj.pieces) > 2 else obj.mesh
        c = piece.bounds.mean(axis=0)
        wb = float(min(piece.extents[:2]))
        return [grasp_from_axis(c, [np.cos(a), np.sin(a), 0], down, wb, f"upper_arm{k}")
                for k, a in enumerate(np.radians([0, 45, 90, 135]))]
    return [grasp_from_axis([0, 0, 0.5 * h], [1, 0, 0], down, ext[0], "middle")]


def top_down_grasps(obj: ObjectModel, *, gripper: ParallelGripper | None = None, samples: int = 400,
                    seed: int = 0) -> Iterator[tuple[float, Grasp]]:
    """The positive-quality, collision-free top-down antipodal grasps on the object's full model, as found.

    Candidates pass through a random surface point (``samples`` draws, seeded) and close along the
    horizontal part of its normal, centred in the middle of the chord (solid parts) or just inside the
    surface (thin walls, rims); they are re-centred between the contacts, scored by (6.20) and must
    not collide with the object or the table.

    Args:
        obj: The object (object frame).
        gripper: The jaw model (default the 48 mm one).
        samples: Surface points drawn.
        seed: Seed of the surface sampling and the draws.

    Yields:
        ``(quality, grasp)`` in the order found (object frame).
    """
    from robointel.learning.grasp.quality import NARROW_GRIPPER, estimate_normals, grasp_quality

    gripper = gripper or NARROW_GRIPPER
    rng = np.random.default_rng(seed)
    P = sample_points(obj, 3000, seed)
    tree = cKDTree(P)
    N = estimate_normals(P, 12, tree=tree)
    zmin = gripper.tip_depth + 0.004
    ok = (P[:, 2] > zmin) & (P[:, 2] < obj.height - 0.002) & (np.linalg.norm(N[:, :2], axis=1) > 0.7)
    cand, ncand = P[ok], N[ok]
    for _ in range(samples if len(cand) else 0):
        i = rng.integers(len(cand))
        y = np.array([ncand[i, 0], ncand[i, 1], 0.0])
        y /= np.linalg.norm(y)
        rel = P - cand[i]
        sv = rel @ y
        near = np.linalg.norm(rel - sv[:, None] * y, axis=1) < 0.004
        for centre in (cand[i] + 0.5 * (sv[near].max() + sv[near].min()) * y, cand[i] - 0.002 * y):
            g = grasp_from_axis(centre, y, [0, 0, -1])
            q = grasp_quality(P, g, gripper=gripper, tree=tree)
            if q.quality > 0 and q.grasp is not None and not gripper.collides(q.grasp, P, table_z=0.0):
                yield q.quality, q.grasp


def sampled_grasps(obj: ObjectModel, n: int = 3, *, gripper: ParallelGripper | None = None, samples: int = 400,
                   seed: int = 0, min_separation: float = 0.02) -> list[Grasp]:
    """Teach by sampling: the best top-down antipodal grasps on the object's full model.

    A stand-in for a human's demonstration on the template: the ``n`` best of
    :func:`top_down_grasps` by quality (6.20), at least ``min_separation`` m apart.

    Args:
        obj: The object (object frame).
        n: Grasps wanted.
        gripper: The jaw model (default the 48 mm one).
        samples: Surface points drawn.
        seed: Seed of the draws.
        min_separation: Least distance between the grasps' centres (m).

    Returns:
        Up to ``n`` grasps (object frame), best first, named ``sampled0``, ``sampled1``, ...
    """
    scored = sorted(top_down_grasps(obj, gripper=gripper, samples=samples, seed=seed), key=lambda t: -t[0])
    out: list[Grasp] = []
    for _, g in scored:
        if all(np.linalg.norm(g.centre - h.centre) >= min_separation for h in out):
            out.append(Grasp(g.centre, g.rotation, g.width, f"sampled{len(out)}"))
        if len(out) == n:
            break
    return out


def demo_objects(per_category: int = 4, seed: int = 0, *, arms: bool = True) -> dict[str, list[ObjectModel]]:
    """Generated objects of every category that need no shared data.

    Objects that need no shared data: primitives of five categories with varied proportions and
    toy UR5 arms at random joint angles (``per_category`` instances each).
    """
    rng = np.random.default_rng(seed)
    out = {c: [primitive_object(c, rng, f"{c}{i}") for i in range(per_category)]
           for c in ("cup", "can", "box", "ball", "long_tool")}
    if arms:
        try:
            out["toy_arm"] = [toy_arm(robot="ur5", rng=int(rng.integers(1 << 30)), name=f"toy_arm{i}")
                              for i in range(per_category)]
        except DataMissing:
            pass
    return out
