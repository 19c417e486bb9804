"""Simulated perception (Fig. 6.4): two depth cameras, background removal, DBSCAN, 5 mm voxels.

Depth images come from ray casting the MuJoCo scene (``mujoco.mj_multiRay`` against the table and the
objects' scan meshes). Noise follows the Kinect-style axial model of Nguyen et al. (2012),
``sigma_z = 1.2 mm + 1.9 mm (z - 0.4 m)^2``, with depth quantisation and random drop-outs.
Background removal compares each pixel with a snapshot of the empty workspace; the foreground
pixels of both cameras are back-projected to the world, merged, clustered with scikit-learn's
DBSCAN and voxel-downsampled (5 mm).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from sklearn.cluster import DBSCAN

from robointel._validate import as_array
from robointel.errors import InvalidInput

__all__ = ["DepthCamera", "default_cameras", "depth_image", "foreground_points", "voxel_downsample",
           "cluster_objects", "perceive", "look_at"]


def look_at(eye: npt.ArrayLike, target: npt.ArrayLike, up: npt.ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera rotation (3, 3), columns = camera x (right), y (down), z (forward), in the world."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


@dataclass(frozen=True)
class DepthCamera:
    """A pinhole depth camera at ``position`` with rotation ``R`` (columns x right, y down, z forward).

    ``width`` x ``height`` pixels, vertical field of view ``fovy`` (rad), range [``near``, ``far``] m,
    noise on (``noise=True``), quantisation step ``quant`` (m), drop-out probability ``dropout``.
    """

    position: np.ndarray
    R: np.ndarray
    width: int = 320
    height: int = 240
    fovy: float = np.radians(45.0)
    near: float = 0.2
    far: float = 2.5
    noise: bool = True
    quant: float = 0.001
    dropout: float = 0.01

    def rays(self) -> np.ndarray:
        """Unit ray directions (H*W, 3) in the world, row-major pixels."""
        f = 0.5 * self.height / np.tan(self.fovy / 2)
        u, v = np.meshgrid(np.arange(self.width) + 0.5 - self.width / 2, np.arange(self.height) + 0.5 - self.height / 2)
        d = np.stack([u / f, v / f, np.ones_like(u)], axis=-1).reshape(-1, 3)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return d @ self.R.T


def default_cameras(**kw: Any) -> list[DepthCamera]:
    """Two cameras on opposite sides of the workspace centre (0.5, 0, 0): front-left and back-right."""
    target = np.array([0.5, 0.0, 0.0])
    eyes = [np.array([0.95, 0.4, 0.55]), np.array([0.1, -0.4, 0.6])]
    return [DepthCamera(e, look_at(e, target), **kw) for e in eyes]


def depth_image(model: mujoco.MjModel, data: mujoco.MjData, cam: DepthCamera,
                rng: np.random.Generator | int | None = None) -> np.ndarray:
    """Ray-cast range along each pixel ray (H, W) in metres; NaN where nothing is hit or dropped.

    Noise (when ``cam.noise``): axial Gaussian noise growing with depth, 1 mm quantisation and random
    drop-outs.
    """
    rng = np.random.default_rng(rng)
    vec = cam.rays()
    n = vec.shape[0]
    dist = np.empty(n)
    geomid = np.empty(n, dtype=np.int32)
    group = np.array([1, 1, 0, 0, 0, 0], dtype=np.uint8)
    mujoco.mj_multiRay(model, data, np.asarray(cam.position, float), vec.ravel(), group, 1, -1, geomid, dist,
                       None, n, cam.far)
    dist[(geomid < 0) | (dist < 0)] = np.nan
    if cam.noise:
        z = dist * (vec @ cam.R[:, 2])  # axial depth
        sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
        z = z + rng.normal(size=n) * sigma
        z = np.round(z / cam.quant) * cam.quant
        dist = z / (vec @ cam.R[:, 2])
        dist[rng.random(n) < cam.dropout] = np.nan
    dist[(dist < cam.near) | (dist > cam.far)] = np.nan
    return dist.reshape(cam.height, cam.width)


def foreground_points(depth: np.ndarray, background: np.ndarray, cam: DepthCamera, *,
                      threshold: float = 0.005) -> np.ndarray:
    """World points (k, 3) of pixels at least ``threshold`` m closer than the empty-workspace snapshot."""
    d = depth.ravel()
    b = background.ravel()
    fg = np.isfinite(d) & (~np.isfinite(b) | (d < b - threshold))
    return cam.position + cam.rays()[fg] * d[fg, None]


def voxel_downsample(points: npt.ArrayLike, voxel: float = 0.005) -> np.ndarray:
    """Mean point of each occupied ``voxel`` (m) cube: (k, 3)."""
    P = as_array(points, "points", (None, 3))
    if voxel <= 0:
        raise InvalidInput(f"voxel size must be positive, got {voxel}", value=voxel)
    if len(P) == 0:
        return P.copy()
    key = np.floor(P / voxel).astype(np.int64)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    out = np.zeros((len(cnt), 3))
    np.add.at(out, inv, P)
    return out / cnt[:, None]


def cluster_objects(points: npt.ArrayLike, *, eps: float = 0.02, min_samples: int = 8,
                    min_points: int = 30) -> list[np.ndarray]:
    """DBSCAN (scikit-learn) clusters of the foreground points, largest first.

    DBSCAN (scikit-learn) clusters of the foreground points, largest first; noise and clusters
    smaller than ``min_points`` are dropped.
    """
    P = as_array(points, "points", (None, 3))
    if len(P) == 0:
        return []
    lab = DBSCAN(eps=eps, min_samples=min_samples).fit_predict(P)
    clusters = [P[lab == k] for k in set(lab.tolist()) if k >= 0]
    clusters = [c for c in clusters if len(c) >= min_points]
    return sorted(clusters, key=len, reverse=True)


def perceive(model: mujoco.MjModel, data: mujoco.MjData, cameras: list[DepthCamera], backgrounds: list[np.ndarray],
             *, voxel: float = 0.005, rng: np.random.Generator | int | None = None, table_z: float = 0.0,
             min_height: float = 0.004) -> list[np.ndarray]:
    """The Fig. 6.4 perception pipeline: one cloud per object seen by the cameras.

    The Fig. 6.4 pipeline: depth from each camera, background removal, merge, drop points at the
    table plane, DBSCAN, voxel downsampling. Returns one (k, 3) cloud per object, largest first.
    """
    rng = np.random.default_rng(rng)
    pts = [foreground_points(depth_image(model, data, c, rng), b, c) for c, b in zip(cameras, backgrounds)]
    P = np.vstack(pts) if pts else np.zeros((0, 3))
    P = P[P[:, 2] > table_z + min_height]
    return [voxel_downsample(c, voxel) for c in cluster_objects(P)]
