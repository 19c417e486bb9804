"""The robot's URDF as MuJoCo reads it: compiler options that keep it as written, meshes found, inertias checked.

What MuJoCo reads from the URDF: the kinematic tree, the inertias exactly as written (no inertia
balancing, ``fusestatic="false"`` so no body is merged; only when a link's principal moments break or touch
the triangle inequality A + B >= C, which MuJoCo refuses, is MuJoCo's own ``balanceinertia`` switched on,
with a warning naming the links: MuJoCo then balances those that break it, whose inertia differs from the
robot core's), joint limits, ``<dynamics damping>`` as
joint damping and ``<dynamics friction>`` as ``frictionloss`` (Coulomb friction). Collision geoms are the
URDF ``<collision>`` primitives and the meshes MuJoCo can read; visual geoms are dropped.
"""
from __future__ import annotations

import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from robointel.errors import DescriptionError

if TYPE_CHECKING:  # pragma: no cover
    from robointel.robot import Robot


def robot_spec(robot: Robot) -> mujoco.MjSpec:
    """The robot alone as a MuJoCo spec, parsed from :func:`mujoco_urdf` (balanced only where MuJoCo must).

    Args:
        robot: a :class:`robointel.robot.Robot`.

    Returns:
        The spec; ``compiler.balanceinertia`` is on (with a warning naming the links) when
        :func:`unbalanced_bodies` finds any.

    Raises:
        DescriptionError: MuJoCo cannot read the URDF (its parser's message is kept).
    """
    try:
        spec = mujoco.MjSpec.from_string(mujoco_urdf(robot))
    except DescriptionError:
        raise
    except Exception as exc:  # mujoco raises ValueError with its parser message
        raise DescriptionError(f"MuJoCo could not read the URDF of {robot.name!r}: {exc}", value=robot.name) from None
    unbalanced = unbalanced_bodies(spec)
    if unbalanced:  # MuJoCo refuses them: it balances those that break A + B >= C rather than fail
        spec.compiler.balanceinertia = True
        warnings.warn(f"{len(unbalanced)} link(s) of {robot.name!r} have principal inertias at or past A + B >= C "
                      f"({', '.join(unbalanced)}); MuJoCo balances those that break it (balanceinertia), so its "
                      "inertia of them differs from the robot core's", stacklevel=3)
    return spec


def mujoco_urdf(robot: Robot) -> str:
    """``robot.urdf`` with the MuJoCo compiler options that keep the model exactly as written.

    ``package://`` mesh paths are resolved next to the URDF file when possible; mesh geoms MuJoCo
    cannot read (e.g. .dae) are dropped from the collision model with a warning.

    Raises:
        DescriptionError: the text has no ``<robot>`` element.
    """
    text = robot.urdf
    opts = ('<mujoco><compiler fusestatic="false" discardvisual="true" balanceinertia="false" '
            'strippath="false" angle="radian" boundmass="0" boundinertia="0"/></mujoco>')
    text = re.sub(r"<mujoco>.*?</mujoco>", "", text, flags=re.S)
    m = re.search(r"<robot\b[^>]*>", text)
    if m is None:
        raise DescriptionError("the robot URDF has no <robot> element", value=robot.name)
    text = text[: m.end()] + opts + text[m.end():]
    if "<mesh" in text:
        text = _resolve_meshes(text, getattr(robot, "urdf_path", None))
    return text


def _resolve_meshes(text: str, urdf_path: str | Path | None) -> str:
    root = ET.fromstring(text)
    base = Path(urdf_path).resolve().parent if urdf_path else Path.cwd()
    dropped = []
    for link in root.iter("link"):
        for tag in ("collision", "visual"):
            for el in list(link.findall(tag)):
                mesh = el.find("geometry/mesh")
                if mesh is None:
                    continue
                fn = mesh.get("filename", "")
                path = _find_mesh(fn, base)
                if tag == "visual":
                    link.remove(el)
                elif path is None or path.suffix.lower() not in (".stl", ".obj", ".msh"):
                    link.remove(el)
                    dropped.append(fn)
                else:
                    mesh.set("filename", str(path))
    if dropped:
        warnings.warn(f"MuJoCo cannot read {len(dropped)} collision mesh(es) (e.g. {dropped[0]}); they are left "
                      "out of the simulated collision model (inertias are unchanged)", stacklevel=5)
    return ET.tostring(root, encoding="unicode")


def _find_mesh(fn: str, base: Path) -> Path | None:
    if fn.startswith("package://"):
        rel = fn[len("package://"):]
        for d in [base, *base.parents]:
            p = d / rel
            if p.exists():
                return p
            p = d / rel.split("/", 1)[-1]
            if p.exists():
                return p
        return None
    if fn.startswith("file://"):
        fn = fn[len("file://"):]
    p = Path(fn)
    p = p if p.is_absolute() else base / p
    return p if p.exists() else None


def unbalanced_bodies(spec: mujoco.MjSpec, *, rtol: float = 1e-9) -> list[str]:
    """Bodies whose explicit inertia breaks or touches the triangle inequality of principal moments (A + B >= C).

    MuJoCo's compiler refuses a link at the limit whose inertia is not diagonal (its eigen decomposition
    lands a rounding error below), so a link within ``rtol`` of the limit counts too.

    Args:
        spec: The spec parsed from the URDF.
        rtol: Relative margin on the inequality.

    Returns:
        Their names, in tree order.
    """
    out = []
    for b in spec.bodies:
        full = np.asarray(b.fullinertia, float)
        if not b.explicitinertial or not np.all(np.isfinite(full)):
            continue
        I = np.array([[full[0], full[3], full[4]], [full[3], full[1], full[5]], [full[4], full[5], full[2]]])
        a, bb, c = np.sort(np.linalg.eigvalsh(I))
        if a + bb < c * (1.0 + rtol):
            out.append(str(b.name))
    return out
