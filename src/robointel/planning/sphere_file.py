"""Collision spheres read from a "spherized" URDF (VAMP's ``*_spherized.urdf``): an option, never a requirement."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from robointel.errors import DescriptionError, InvalidInput
from robointel.planning._sphere_pack import robot_cache
from robointel.robot.collision import SphereModel, primitive_spheres
from robointel.robot.model import Robot


def sphere_model_from_urdf(robot: Robot, path: str | Path) -> SphereModel:
    """Spheres read from a "spherized" URDF.

    One ``<sphere>`` collision per sphere, as shipped with VAMP/MotionBenchMaker; bound to ``robot`` by link name.

    Args:
        robot: the arm the spheres belong to (same link names).
        path: the spherized URDF file.

    Returns:
        The sphere model, bound to ``robot``.

    Raises:
        InvalidInput: the file cannot be read, has no spheres, or names a link ``robot`` lacks.
    """
    links, centres, radii = urdf_spheres(robot, path)
    return SphereModel(links, centres, radii).bind(robot)


def urdf_spheres(robot: Robot, path: str | Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Links, centres and radii of a spherized URDF's spheres (the file read once per path and version)."""
    try:
        st = Path(path).stat()
    except OSError as exc:
        raise InvalidInput(f"cannot read sphere URDF {path}: {exc}", value=str(path)) from None
    key = (str(Path(path).resolve()), st.st_mtime_ns, st.st_size)
    hit = robot_cache(robot).get(key)
    if hit is None:
        hit = _read_urdf_spheres(robot, path)
        robot_cache(robot)[key] = hit
    links, centres, radii = hit
    return list(links), centres.copy(), radii.copy()


def _read_urdf_spheres(robot: Robot, path: str | Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    try:
        src = Robot.load(path)
    except (DescriptionError, OSError) as exc:
        raise InvalidInput(f"cannot read sphere URDF {path}: {exc}", value=str(path)) from None
    links, centres, radii = [], [], []
    for link, prims in src.collision_primitives().items():
        for p in prims:
            if p["type"] != "sphere":
                continue
            if link not in robot.link_names:
                raise InvalidInput(f"sphere URDF {path}: link {link!r} is not a link of {robot.name!r}", value=link)
            c, r = primitive_spheres(p)
            links += [link] * len(r)
            centres.append(c)
            radii.append(r)
    if not links:
        raise InvalidInput(f"sphere URDF {path} holds no <sphere> collision geometry", value=str(path))
    return links, np.concatenate(centres), np.concatenate(radii)


__all__ = ["sphere_model_from_urdf", "urdf_spheres"]
