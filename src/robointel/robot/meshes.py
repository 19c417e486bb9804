"""Where a URDF's mesh files are: ``package://``, ``file://`` and relative paths resolved, or a clear error.

A ``package://PKG/rest`` path is looked for in every directory of ``package_dirs`` and of the
``ROS_PACKAGE_PATH`` environment variable (as ``DIR/PKG/rest`` and ``DIR/rest``), then next to the
URDF and in each folder above it (as MoveIt's users lay descriptions out: ``.../PKG/urdf/x.urdf``
beside ``.../PKG/meshes``). A relative path is taken relative to the URDF's folder.
"""
from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from robointel.errors import DescriptionError


def search_dirs(urdf_path: Path | None, package_dirs: Sequence[str | Path] = ()) -> list[Path]:
    """The directories a ``package://`` path is looked for in, in order.

    Args:
        urdf_path: the URDF file (None: a URDF given as text).
        package_dirs: extra package directories, searched first.

    Returns:
        ``package_dirs``, then ``ROS_PACKAGE_PATH``'s entries, then the URDF's folder and every folder above it.
    """
    dirs = [Path(d) for d in package_dirs]
    dirs += [Path(d) for d in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if d]
    if urdf_path is not None:
        here = Path(urdf_path).resolve().parent
        dirs += [here, *here.parents]
    return dirs


def resolve_mesh(filename: str, urdf_path: Path | None, package_dirs: Sequence[str | Path] = (), *,
                 link: str = "") -> Path:
    """The file a URDF mesh reference names.

    Args:
        filename: the ``filename`` attribute of a ``<mesh>``.
        urdf_path: the URDF file (None: a URDF given as text; relative paths then need ``package_dirs``).
        package_dirs: extra package directories.
        link: the link whose geometry it is (for the message).

    Returns:
        The existing mesh file.

    Raises:
        DescriptionError: no such file; the message names the path and every place it was looked for.
    """
    where = f"link {link!r} " if link else ""
    src = f" of {urdf_path}" if urdf_path is not None else ""
    if filename.startswith("package://"):
        rel = filename[len("package://"):]
        pkg, _, rest = rel.partition("/")
        tried: list[Path] = []
        for d in search_dirs(urdf_path, package_dirs):
            for cand in (d / pkg / rest, d / rest):
                if cand.is_file():
                    return cand
                tried.append(cand)
        looked = ", ".join(str(t) for t in tried[:6]) + (f" and {len(tried) - 6} more" if len(tried) > 6 else "")
        raise DescriptionError(
            f"mesh {filename!r} of {where}in the URDF{src} not found; looked in package_dirs "
            f"{[str(d) for d in package_dirs]}, ROS_PACKAGE_PATH={os.environ.get('ROS_PACKAGE_PATH', '')!r} and "
            f"the URDF's folders ({looked}); pass package_dirs or set ROS_PACKAGE_PATH", value=filename)
    p = Path(filename[len("file://"):] if filename.startswith("file://") else filename)
    cands = [p] if p.is_absolute() else (
        [Path(urdf_path).parent / p] if urdf_path is not None else [Path(d) / p for d in package_dirs])
    for c in cands:
        if c.is_file():
            return c
    where_looked = ", ".join(str(c) for c in cands) or "nowhere (a URDF given as text: pass urdf_path or package_dirs)"
    raise DescriptionError(f"mesh {filename!r} of {where}in the URDF{src} not found; looked at {where_looked}",
                           value=filename)
