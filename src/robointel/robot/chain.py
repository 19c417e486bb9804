"""The joint tree of a robot's Pinocchio model as plain arrays, for the compiled kernels.

``chain_arrays(model)`` returns ``(parent, place, axis, kind, qidx)``:

====  ==========  ============================================================================
idx   name        content
====  ==========  ============================================================================
0     parent      (nj,) parent joint of each joint (joint 0 is the fixed base)
1     place       (nj, 4, 4) joint placement in its parent joint frame
2     axis        (nj, 3) unit joint axis in its own frame
3     kind        (nj,) 0 revolute, 1 prismatic (unused for joint 0)
4     qidx        (nj,) configuration index of each joint (-1 for joint 0)
====  ==========  ============================================================================

These are the first five entries of the planner's packed world (see
:mod:`robointel.planning._collision_kernels`) and the input of the numeric IK.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robointel.errors import DescriptionError


def joint_kind(jm: object) -> tuple[np.ndarray, int]:
    """Unit axis (3,) in the joint frame and kind (0 revolute, 1 prismatic) of a 1-DoF Pinocchio joint model.

    Raises:
        DescriptionError: the joint has more than one coordinate.
    """
    if jm.nq != 1 or jm.nv != 1:  # type: ignore[attr-defined]
        raise DescriptionError(f"joint model {jm.shortname()} has {jm.nq} coordinates; robointel plans "  # type: ignore[attr-defined]
                               "1-DoF joints (revolute, continuous, prismatic)", value=jm.shortname())  # type: ignore[attr-defined]
    jd = jm.createData()  # type: ignore[attr-defined]
    jm.calc(jd, np.zeros(1))  # type: ignore[attr-defined]
    S = np.asarray(jd.S).reshape(6)
    if np.linalg.norm(S[3:]) > 0.5:
        return S[3:] / np.linalg.norm(S[3:]), 0
    return S[:3] / np.linalg.norm(S[:3]), 1


def chain_arrays(model: pin.Model) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The joint tree of ``model`` (1-DoF joints only) as the arrays described in the module docstring.

    Raises:
        DescriptionError: a joint with more than one coordinate (floating, planar, spherical), named.
    """
    nj = model.njoints
    parent = np.array([int(p) for p in model.parents], np.int64)
    place = np.array([model.jointPlacements[j].homogeneous for j in range(nj)])
    axis = np.zeros((nj, 3))
    kind = np.zeros(nj, np.int64)
    qidx = np.full(nj, -1, np.int64)
    for j in range(1, nj):
        jm = model.joints[j]
        try:
            axis[j], kind[j] = joint_kind(jm)
        except DescriptionError as exc:
            raise DescriptionError(f"joint {model.names[j]!r}: {exc}", value=model.names[j]) from None
        qidx[j] = jm.idx_q
    return parent, place, axis, kind, qidx
