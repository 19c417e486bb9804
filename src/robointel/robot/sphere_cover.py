"""Grow a sphere model until it covers the robot's collision meshes.

Sphere decompositions fitted for speed (such as the ones shipped with VAMP) leave parts of the
collision meshes outside every sphere, so a sphere clearance can overstate the real one by up to
the uncovered depth. Here the mesh surfaces are sampled densely and every sample left outside the
spheres of its rigid body is assigned to the sphere that needs the least growth to contain it;
each sphere grows to contain all samples assigned to it. The grown model is conservative: its
clearance never exceeds the meshes' (up to the sample spacing, ``tol``).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import trimesh

from robointel.robot.collision import SphereModel
from robointel.robot.model import Robot
from robointel.robot.sphere_fit import primitive_mesh

_CACHE: dict[tuple, np.ndarray] = {}


def _surface(robot: Robot, samples: int, seed: int, primitives: bool = False) -> dict[int, np.ndarray]:
    """Surface samples (and vertices) of every collision mesh (and, ``primitives``, primitive), per joint frame."""
    out: dict[int, list[np.ndarray]] = {}
    for link, prims in robot.collision_primitives().items():
        if link not in robot.link_names:
            continue
        j = robot.link_joint(link)
        for p in prims:
            if p["type"] == "mesh" and p.get("path") is not None:
                mesh: Any = trimesh.load(p["path"], force="mesh")
                mesh.apply_scale(np.asarray(p["size"], float))
                T = robot._link_in_joint[link] @ p["origin"]
            elif primitives and p["type"] != "mesh":
                mesh = primitive_mesh(p)  # already placed in the link frame
                T = robot._link_in_joint[link]
            else:
                continue
            pts = np.vstack([trimesh.sample.sample_surface(mesh, samples, seed=seed)[0], mesh.vertices])
            out.setdefault(j, []).append(pts @ T[:3, :3].T + T[:3, 3])
    return {j: np.vstack(v) for j, v in out.items()}


def cover_meshes(robot: Robot, spheres: SphereModel, *, samples: int = 20000, tol: float = 5e-4,
                 seed: int = 0, primitives: bool = False) -> SphereModel:
    """A copy of ``spheres`` whose radii are grown until every collision-mesh sample is inside one.

    Args:
        robot: the arm whose URDF collision meshes are covered.
        spheres: the starting sphere model (bound to ``robot``); links without spheres stay uncovered.
        samples: surface samples per mesh (plus its vertices).
        tol: margin added to every grown radius, m (covers the gaps between samples).
        seed: sampling seed.
        primitives: cover the collision primitives (boxes, cylinders, spheres) too (their spheres
            may lie inside them, as the fitted spheres do).

    Returns:
        The grown sphere model, bound to ``robot`` (same links and centres).
    """
    key = (str(robot.urdf_path), spheres.centers.tobytes(), spheres.radii.tobytes(), samples, tol, seed, primitives)
    rad = _CACHE.get(key)
    if rad is None:
        rad = np.asarray(spheres.radii, float).copy()
        for j, P in _surface(robot, samples, seed, primitives).items():
            own = np.flatnonzero(spheres.joints == j)
            if not len(own):
                continue
            Dm = np.linalg.norm(P[:, None] - spheres._in_joint[own][None], axis=2)
            need = Dm - rad[own][None]
            k = np.argmin(need, axis=1)
            out = need[np.arange(len(P)), k] > 0
            for s in np.unique(k[out]):
                rad[own[s]] = max(rad[own[s]], float(Dm[out & (k == s), s].max()) + tol)
        _CACHE[key] = rad
    return SphereModel(list(spheres.links), np.asarray(spheres.centers).copy(), rad.copy()).bind(robot)
