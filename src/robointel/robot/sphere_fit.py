"""Spheres fitted automatically to a robot's collision geometry: few, tight, inside the meshes.

For each link, the collision meshes and primitives are merged (link frame) and their surface is
sampled every ~``spacing`` m. Candidate centres fill the link's bounding box on a grid and are
kept when they lie inside the surface (the nearest sample's outward normal points away from
them); each has an inscribed radius, its distance to the nearest surface sample. A greedy set
cover then picks, again and again, the candidate whose ball grown by ``slack`` m holds the most
surface samples not yet held, until every sample is held. The fitted spheres are the picked
centres with their *inscribed* radii (inside the meshes: their clearance is never below the
meshes', so a configuration the meshes find free is free in them); the planner grows them to
cover every surface sample (:func:`robointel.robot.sphere_cover.cover_meshes`, at most about
``slack`` beyond the surface) for its conservative checks, and measures the exact meshes (coal)
wherever the two disagree.

The fit is cached on disk per description (``$ROBOINTEL_CACHE`` or ``~/.cache/robointel``,
folder ``spheres``), keyed by the links' collision elements, the mesh files' bytes and the
parameters: the same URDF and meshes load it in milliseconds.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from robointel.errors import DescriptionError
from robointel.robot.protocol import KinematicRobot

#: bump when the fit changes, so that cached fits are made again
FIT_VERSION = 4
#: at most this many surface samples and candidate centres per link
MAX_SAMPLES, MAX_CANDIDATES = 8000, 3000
#: the fitted (inscribed) spheres stay this far inside the surface, m
INSET = 2e-4


def cache_dir() -> Path:
    """The folder fitted sphere models are cached in (``$ROBOINTEL_CACHE/spheres``, default ``~/.cache/robointel``)."""
    root = os.environ.get("ROBOINTEL_CACHE")
    return (Path(root) if root else Path.home() / ".cache" / "robointel") / "spheres"


def primitive_mesh(p: dict) -> Any:
    """A trimesh of one collision primitive or mesh (scaled), placed in its link frame."""
    kind, size = p["type"], np.asarray(p["size"], float)
    if kind == "mesh":
        try:
            m: Any = trimesh.load(p["path"], force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise DescriptionError(f"cannot read mesh {p['path']}: {exc}", value=str(p["path"])) from None
        m = trimesh.Trimesh(np.asarray(m.vertices) * size, np.asarray(m.faces), process=True)
    elif kind == "box":
        m = trimesh.creation.box(extents=size)
    elif kind == "cylinder":
        m = trimesh.creation.cylinder(radius=size[0], height=size[1], sections=32)
    elif kind == "capsule":
        m = trimesh.creation.capsule(radius=size[0], height=size[1], count=[16, 16])
    else:
        m = trimesh.creation.icosphere(subdivisions=3, radius=size[0])
    return m.apply_transform(np.asarray(p["origin"], float))


def winding_numbers(tri: np.ndarray, P: np.ndarray, chunk: int = 2_000_000) -> np.ndarray:
    """Generalised winding number (P,) of the closed surface ``tri`` (F, 3, 3) around each point of P (N, 3).

    About 1 inside a closed surface and 0 outside, whatever the orientation of the faces near the
    point (solid angles of the triangles, Van Oosterom and Strackee).
    """
    out = np.empty(len(P))
    step = max(1, chunk // max(len(tri), 1))
    for s in range(0, len(P), step):
        R = tri[None] - P[s:s + step, None, None, :]  # (k, F, 3, 3)
        a, b, c = R[:, :, 0], R[:, :, 1], R[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("kfi,kfi->kf", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("kfi,kfi->kf", a, b) * lc + np.einsum("kfi,kfi->kf", b, c) * la
               + np.einsum("kfi,kfi->kf", c, a) * lb)
        out[s:s + step] = np.arctan2(det, den).sum(1) / (2 * np.pi)
    return np.abs(out)


def _link_spheres(parts: list[Any], *, spacing: float, slack: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Fitted spheres (centres (k, 3), inscribed radii (k,)) of one link's collision meshes (link frame)."""
    mesh: Any = trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]
    if len(mesh.faces) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    area = float(mesh.area)
    n = int(np.clip(area / spacing ** 2, 500, MAX_SAMPLES))
    pts, fi = trimesh.sample.sample_surface(mesh, n, seed=seed)
    nrm = np.asarray(mesh.face_normals)[fi]
    tree = cKDTree(pts)
    lo, hi = pts.min(0), pts.max(0)
    ext = float(np.max(hi - lo))
    h = max(min(ext / 24.0, slack), 1e-3)
    axes = [np.arange(lo[i] + h / 2, hi[i], h) if hi[i] - lo[i] > h else np.array([(lo[i] + hi[i]) / 2])
            for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    cand = np.vstack([grid, pts - nrm * min(h, 0.25 * ext)])  # inward offsets of the samples reach thin parts
    d, k = tree.query(cand)
    # a cheap first guess (the nearest sample's normal), wrong near edges: each centre picked below is
    # confirmed by its winding number before it is kept
    inside = np.einsum("ij,ij->i", cand - pts[k], nrm[k]) < 0.0
    cand, rin = cand[inside], d[inside]
    tri = np.asarray(mesh.triangles)
    if len(cand) > MAX_CANDIDATES:  # the deepest half and an even draw of the rest
        order = np.argsort(-rin)
        rng = np.random.default_rng(seed)
        keep = np.concatenate([order[:MAX_CANDIDATES // 2],
                               rng.choice(order[MAX_CANDIDATES // 2:], MAX_CANDIDATES // 2, replace=False)])
        cand, rin = cand[keep], rin[keep]
    if len(cand) == 0:  # an open or inverted surface: centres on the samples themselves
        cand, rin = pts.copy(), np.full(len(pts), 1e-4)
    balls = tree.query_ball_point(cand, rin + slack)
    covered = np.zeros(len(pts), bool)
    gain = np.array([len(b) for b in balls], float)
    centres, radii = [], []
    while not covered.all():
        i = int(np.argmax(gain))
        if gain[i] <= 0:
            break
        idx = np.asarray(balls[i], int)
        new = idx[~covered[idx]]
        if len(new) < gain[i]:  # a stale count: refresh it and look again (lazy greedy)
            gain[i] = len(new)
            continue
        if winding_numbers(tri, cand[i][None])[0] < 0.5:  # outside after all: never a centre
            gain[i] = 0.0
            continue
        covered[new] = True
        centres.append(cand[i])
        radii.append(max(rin[i], 1e-4))
        gain[i] = 0.0
    if centres:  # inscribed radii from the exact surface (samples alone overstate them by up to their spacing)
        dist = np.array([np.linalg.norm(trimesh.triangles.closest_point(tri, np.repeat(c[None], len(tri), 0)) - c,
                                        axis=1).min() for c in centres])
        radii = list(np.maximum(np.minimum(np.array(radii), dist) - INSET, 1e-4))
    left = np.flatnonzero(~covered)
    if len(left):  # samples no candidate reaches: a small sphere on each cluster of them
        for p in pts[left][:: max(1, len(left) // 64)]:
            centres.append(p)
            radii.append(1e-4)
    return np.array(centres).reshape(-1, 3), np.array(radii)


def _key(robot: KinematicRobot, links: list[str], prims: dict[str, list[dict]], spacing: float, slack: float,
         seed: int) -> str:
    hsh = hashlib.sha256(f"v{FIT_VERSION} {spacing!r} {slack!r} {seed}".encode())
    digests: dict[str, str] = {}
    for link in links:
        for p in prims.get(link, []):
            hsh.update(f"{link} {p['type']} {np.round(np.asarray(p['size'], float), 9).tolist()} "
                       f"{np.round(p['origin'], 9).tolist()}".encode())
            if p["type"] == "mesh":
                f = str(p["path"])
                if f not in digests:
                    digests[f] = hashlib.sha256(Path(f).read_bytes()).hexdigest()
                hsh.update(digests[f].encode())
    return hsh.hexdigest()[:32]


def fit_spheres(robot: KinematicRobot, *, spacing: float = 0.004, slack: float = 0.025, seed: int = 0,
                cache: bool = True) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Spheres fitted to every link's collision geometry (see the module docstring).

    Args:
        robot: the robot (its links' collision primitives, mesh files resolved).
        spacing: surface sample spacing, m.
        slack: how far beyond its inscribed radius a sphere may be grown to hold surface samples, m
            (fewer spheres the larger it is; the covering spheres reach about this far beyond the meshes).
        seed: sampling seed.
        cache: read and write the disk cache.

    Returns:
        (link of each sphere, centres (m, 3) in the link frames, inscribed radii (m,)), m.

    Raises:
        DescriptionError: a mesh file that cannot be read.
    """
    prims = robot.collision_primitives()
    links = [lk for lk in robot.link_names if prims.get(lk)]
    key = _key(robot, links, prims, spacing, slack, seed)
    f = cache_dir() / f"{key}.npz"
    if cache and f.is_file():
        try:
            z = np.load(f, allow_pickle=False)
            return [str(s) for s in z["links"]], z["centres"], z["radii"]
        except (OSError, ValueError, KeyError):
            pass  # a damaged cache file: fit again
    out_links: list[str] = []
    centres, radii = [], []
    for link in links:
        parts = [primitive_mesh(p) for p in prims[link]]
        c, r = _link_spheres(parts, spacing=spacing, slack=slack, seed=seed)
        out_links += [link] * len(r)
        centres.append(c)
        radii.append(r)
    C = np.concatenate(centres) if centres else np.zeros((0, 3))
    R = np.concatenate(radii) if radii else np.zeros(0)
    if cache:
        try:
            f.parent.mkdir(parents=True, exist_ok=True)
            tmp = f.with_suffix(f".{os.getpid()}.tmp.npz")
            np.savez(tmp, links=np.array(out_links, dtype=str), centres=C, radii=R)
            tmp.replace(f)
        except OSError:
            pass  # a read-only home: the fit is simply not kept
    return out_links, C, R
