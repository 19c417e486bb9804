"""The collision geometry of a URDF's links: primitives and meshes, each mesh file found or named as missing."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from robointel.errors import DescriptionError
from robointel.robot.meshes import resolve_mesh


def _floats(src: str, where: str, raw: str | None, n: int, default: str) -> np.ndarray:
    text = default if raw is None else raw
    try:
        v = np.array([float(x) for x in text.split()], dtype=float)
    except ValueError:
        raise DescriptionError(f"URDF {src}: {where} {text!r} is not {n} numbers", value=text) from None
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise DescriptionError(f"URDF {src}: {where} {text!r} is not {n} finite numbers", value=text)
    return v


def read_collision_geometry(root: ET.Element, urdf_path: Path | None, package_dirs: Sequence[str | Path],
                            links: set[str]) -> dict[str, list[dict]]:
    """Collision geometry of each link of ``links`` from the URDF tree ``root``.

    Args:
        root: the parsed ``<robot>``.
        urdf_path: the URDF file (mesh paths are resolved from it), or None.
        package_dirs: extra ``package://`` directories.
        links: the links to read (others are left out).

    Returns:
        ``{link: [primitive]}``; a primitive is a dict with ``type`` (box, cylinder, sphere,
        capsule, mesh), ``size`` (box sides; cylinder/capsule radius, length; sphere radius; mesh
        scale), ``origin`` (4x4 in the link frame), ``filename`` and, for a mesh, ``path``.

    Raises:
        DescriptionError: a mesh file that cannot be found (the path and where it was looked
            for), or a malformed size or origin (the link named).
    """
    src = str(urdf_path) if urdf_path is not None else "<text>"
    out: dict[str, list[dict]] = {}
    for link in root.iter("link"):
        name = link.get("name", "")
        if name not in links:
            continue
        prims = []
        for k, col in enumerate(link.findall("collision")):
            where = f"link {name!r} <collision> {k}"
            origin = col.find("origin")
            xyz = _floats(src, f"{where} origin xyz", None if origin is None else origin.get("xyz"), 3, "0 0 0")
            rpy = _floats(src, f"{where} origin rpy", None if origin is None else origin.get("rpy"), 3, "0 0 0")
            T = np.eye(4)
            T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
            T[:3, 3] = xyz
            g = col.find("geometry")
            if g is None or len(g) == 0:
                continue
            shape = g[0]
            path = None
            if shape.tag == "box":
                size = _floats(src, f"{where} box size", shape.get("size"), 3, "")
            elif shape.tag in ("cylinder", "capsule"):
                size = np.array([_floats(src, f"{where} {shape.tag} radius", shape.get("radius"), 1, "")[0],
                                 _floats(src, f"{where} {shape.tag} length", shape.get("length"), 1, "")[0]])
            elif shape.tag == "sphere":
                size = _floats(src, f"{where} sphere radius", shape.get("radius"), 1, "")
            elif shape.tag == "mesh":
                fn = shape.get("filename")
                if not fn:
                    raise DescriptionError(f"URDF {src}: {where} <mesh> has no filename", value=name)
                sc = shape.get("scale", "1 1 1").split()
                size = _floats(src, f"{where} mesh scale", " ".join(sc * 3 if len(sc) == 1 else sc), 3, "")
                path = resolve_mesh(fn, urdf_path, package_dirs, link=name)
            else:
                continue
            if np.any(size <= 0) and shape.tag != "mesh":
                raise DescriptionError(f"URDF {src}: {where} {shape.tag} has a non-positive size {size.tolist()}",
                                       value=name)
            prims.append({"type": shape.tag, "size": size, "origin": T, "filename": shape.get("filename"),
                          "path": path})
        out[name] = prims
    return out
