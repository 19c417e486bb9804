"""Grasp quality (6.20) on a point cloud, and the parallel-jaw gripper model.

Contacts come from a line search along the grasp axis: the cloud points within ``axis_radius`` of the
axis line are projected on it; each jaw, closing from its side, meets the outermost point on its side.
Surface normals are estimated from the cloud (PCA of the k nearest neighbours). The grasp map stacks,
for each contact, the edges of a linearised friction cone (point contact with friction ``mu``) and a
soft-finger torsion pair (``mu_t``), as wrenches about the grasp centre with torques divided by a
characteristic length. Quality = isotropy index sigma_min / sigma_max of that 6 x 12 map (6.20).

Negative quality marks grasps that cannot work (Table 6.1 of the dissertation, plus a friction check):

* -1 ``off-axis``: (almost) no cloud points near the axis within the jaws' opening,
* -2 ``sparse``: too few points around a contact to estimate its normal,
* -3 ``too wide``: the contacts are farther apart than the gripper opens,
* -4 ``slip``: a contact normal is outside the friction cone about the closing axis,
* -5 ``unseen``: (only when an ``observed`` cloud is given) a contact is farther than
  ``observed_radius`` from every observed point: the jaw would close on a part of the cloud that only
  a completion (e.g. the warped template) put there. On a fork the jaws otherwise closed on the warped
  template's wider handle, 9 mm beside the real one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.learning.grasp.transfer import Grasp

__all__ = ["ParallelGripper", "NARROW_GRIPPER", "WIDE_GRIPPER", "choose_gripper",
           "GraspQuality", "grasp_quality", "estimate_normals", "grasp_map",
           "isotropy"]

OFF_AXIS, SPARSE, TOO_WIDE, SLIP, UNSEEN = -1.0, -2.0, -3.0, -4.0, -5.0


@dataclass(frozen=True)
class ParallelGripper:
    """A parallel-jaw gripper in the grasp frame (defaults: the 48 mm SMC LEHF20K2-48).

    :data:`WIDE_GRIPPER` is an 85 mm one (Robotiq 2F-85 class). Grasp frame: origin between the
    finger pads, y = closing axis, z = approach. The fingertips reach ``tip_depth`` past the centre
    along z. Sizes in metres, ``mass`` in kg, ``grip_force`` (N) the
    force limit of each finger's drive in the MuJoCo trials, ``clearance`` (m) the room each open pad
    must keep from the part on the way in (perception's 5 mm voxels, the arm's tracking): the jaws
    grip parts up to :attr:`grip_range`'s upper end, not their full stroke.
    """

    max_width: float = 0.048
    finger_length: float = 0.045
    finger_breadth: float = 0.018
    finger_thickness: float = 0.008
    tip_depth: float = 0.005
    palm_height: float = 0.03
    palm_breadth: float = 0.04
    flange_offset: float = 0.07  # flange to palm face along the approach
    mass: float = 0.4
    grip_force: float = 20.0
    name: str = "narrow_48mm"
    clearance: float = 0.0025

    @property
    def grip_range(self) -> tuple[float, float]:
        """Widths (m) of parts the jaws can take: (0, ``max_width - 2 clearance``)."""
        return 0.0, self.max_width - 2 * self.clearance

    def boxes(self, opening: float | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
        """(centre, full size) of the two fingers and the palm in the grasp frame at ``opening``."""
        w = self.max_width if opening is None else float(opening)
        zc = self.tip_depth - self.finger_length / 2
        f = np.array([self.finger_breadth, self.finger_thickness, self.finger_length])
        out = [(np.array([0.0, s * (w / 2 + self.finger_thickness / 2), zc]), f) for s in (1, -1)]
        palm_z = self.tip_depth - self.finger_length - self.palm_height / 2
        out.append((np.array([0.0, 0.0, palm_z]),
                    np.array([self.palm_breadth, self.max_width + 2 * self.finger_thickness, self.palm_height])))
        return out

    def tool_transform(self) -> np.ndarray:
        """4x4 pose of the grasp frame in the LR Mate flange frame (flange x = approach)."""
        T = np.eye(4)
        # grasp z = flange x, grasp y = flange y, grasp x = flange -z
        T[:3, :3] = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
        T[:3, 3] = [self.flange_offset + self.palm_height + self.finger_length - self.tip_depth, 0.0, 0.0]
        return T

    def collides(self, grasp: Grasp, cloud: npt.ArrayLike, *, opening: float | None = None, margin: float = 0.001,
                 table_z: float | None = None) -> bool:
        """Whether the gripper at ``grasp`` collides with the cloud or the table.

        True when any cloud point is inside a finger or the palm (grown by ``margin``), or a box
        reaches below the table plane ``z = table_z`` (world frame).
        """
        local = (np.asarray(cloud, float) - grasp.centre) @ grasp.rotation
        for c, size in self.boxes(opening):
            h = size / 2 + margin
            if np.any(np.all(np.abs(local - c) <= h, axis=1)):
                return True
            if table_z is not None:
                signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
                corners = signs * (size / 2) + c
                world = corners @ grasp.rotation.T + grasp.centre
                if world[:, 2].min() < table_z + margin:
                    return True
        return False


#: The 48 mm gripper (SMC LEHF20K2-48 class), the default everywhere.
NARROW_GRIPPER = ParallelGripper()
#: An 85 mm stroke gripper (Robotiq 2F-85 class: 85 mm stroke, 22 mm wide pads, 20-235 N grip force,
#: 0.9 kg); its body is longer and wider than the 48 mm one's. Grip force set to 40 N per finger (in
#: the 2F-85's range): it holds the heavier wide parts (cans, boxes, balls up to ~0.6 kg) in the shake.
WIDE_GRIPPER = ParallelGripper(max_width=0.085, finger_length=0.05, finger_breadth=0.022, finger_thickness=0.01,
                               tip_depth=0.005, palm_height=0.04, palm_breadth=0.06, flange_offset=0.07, mass=0.9,
                               grip_force=40.0, name="wide_85mm")


def choose_gripper(widths: list[float], grippers: list[ParallelGripper],
                   margin: float | None = None) -> ParallelGripper:
    """The gripper for a part, chosen by the contact widths of its transferred grasps.

    The narrowest of ``grippers`` that takes the smallest known width (within its
    :attr:`~ParallelGripper.grip_range`, or its stroke less ``margin`` when given); the narrowest when
    no width is known; the widest when none fits.

    Args:
        widths: contact widths of the transferred grasps (m), any length, NaN allowed.
        grippers: candidate grippers, at least one.
        margin: stroke left beyond the width (m; None: each gripper's ``2 * clearance``).

    Returns:
        The chosen gripper.

    Raises:
        InvalidInput: ``grippers`` is empty.
    """
    if not grippers:
        raise InvalidInput("choose_gripper needs at least one gripper", value=grippers)
    by_stroke = sorted(grippers, key=lambda g: g.max_width)
    known = [float(w) for w in widths if np.isfinite(w)]
    if not known:
        return by_stroke[0]
    w = min(known)
    top = (lambda g: g.grip_range[1]) if margin is None else (lambda g: g.max_width - margin)
    return next((g for g in by_stroke if w <= top(g)), by_stroke[-1])


@dataclass
class GraspQuality:
    """Result of :func:`grasp_quality`.

    Result of :func:`grasp_quality`: ``quality`` (isotropy in [0, 1], or a negative code),
    ``reason``, the two ``contacts`` (2, 3), outward ``normals`` (2, 3), ``width`` (m) and the
    re-centred grasp (centre at the contacts' midpoint).
    """

    quality: float
    reason: str
    contacts: np.ndarray = field(default_factory=lambda: np.full((2, 3), np.nan))
    normals: np.ndarray = field(default_factory=lambda: np.full((2, 3), np.nan))
    width: float = float("nan")
    grasp: Grasp | None = None


def estimate_normals(cloud: npt.ArrayLike, k: int = 12, *, viewpoint: npt.ArrayLike | None = None,
                     tree: cKDTree | None = None) -> np.ndarray:
    """Unit normals by PCA of the nearest neighbours.

    Unit normals (n, 3) by PCA of the ``k`` nearest neighbours, oriented away from the centroid
    (or toward ``viewpoint``).
    """
    P = as_array(cloud, "cloud", (None, 3))
    if len(P) < 3:
        raise InvalidInput(f"need at least 3 points to estimate normals, got {len(P)}", value=P.shape)
    k = min(k, len(P))
    tree = tree or cKDTree(P)
    _, idx = tree.query(P, k=k)
    nb = P[idx] - P[idx].mean(axis=1, keepdims=True)
    C = np.einsum("nki,nkj->nij", nb, nb)
    _, V = np.linalg.eigh(C)
    n = V[:, :, 0]
    ref = P - (P.mean(0) if viewpoint is None else as_array(viewpoint, "viewpoint", (3,)))
    if viewpoint is not None:
        ref = -ref
    n *= np.where(np.sum(n * ref, axis=1) < 0, -1.0, 1.0)[:, None]
    return n


def grasp_map(contacts: np.ndarray, normals: np.ndarray, centre: np.ndarray, *, mu: float = 0.5,
              mu_t: float = 0.3, edges: int = 4, length: float | None = None) -> np.ndarray:
    """The grasp map G of (6.20): friction-cone edges and soft-finger torsion.

    The grasp map G (6, 2 (edges + 2)): friction-cone edge forces and soft-finger torsion about
    ``centre``; torques divided by ``length`` (default half the contact distance) to be unit-free.
    ``normals`` point out of the object; contact forces push along -normal.
    """
    contacts = np.asarray(contacts, float)
    normals = np.asarray(normals, float)
    L = length or max(0.5 * float(np.linalg.norm(contacts[0] - contacts[1])), 1e-3)
    ang = 2 * np.pi * np.arange(edges) / edges
    blocks = []
    for c, n in zip(contacts, normals):
        f_n = -n / np.linalg.norm(n)
        t1 = np.cross(f_n, [1.0, 0, 0])
        if np.linalg.norm(t1) < 1e-6:
            t1 = np.cross(f_n, [0, 1.0, 0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(f_n, t1)
        F = (f_n + mu * (np.cos(ang)[:, None] * t1 + np.sin(ang)[:, None] * t2)) / np.sqrt(1 + mu * mu)
        r = (c - centre) / L
        blocks.append(np.c_[F, np.cross(r, F)])
        blocks.append(np.c_[np.zeros((2, 3)), np.outer([1.0, -1.0], mu_t * f_n)])
    return np.vstack(blocks).T


def isotropy(G: np.ndarray) -> float:
    """(6.20): sigma_min / sigma_max of the grasp map."""
    s = np.linalg.svd(G, compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def _rim_normal(contact: np.ndarray, mean: np.ndarray, face: np.ndarray, closing: np.ndarray,
                radius: float) -> np.ndarray:
    """Outward rim normal of a thin part seen face-on, at a jaw contact.

    Outward normal of the rim of a thin part (a fork's or knife's handle lying on the table) at a
    jaw contact, when the cloud shows only the part's face.

    A depth camera above a handle 2-3 mm thick sees its top face; after 5 mm voxels the PCA normal of
    the contact's neighbourhood (``face``, unit (3,)) is the face normal, square to the closing axis,
    so the jaw would read as sliding off (SLIP). The jaw, closing along ``closing`` (unit (3,), pointing
    out of the object at this contact), does not touch that face: it meets the rim at the face's
    boundary, whose outward normal lies in the face plane, away from the one-sided neighbourhood.
    Estimated as the in-plane part of ``contact - mean`` (m; ``mean`` the neighbourhood centroid).
    Used only when the face normal is more than 60 deg from the closing axis (a jaw sliding along the
    face) and the contact is a boundary: the in-plane offset is at least a quarter of ``radius`` (m)
    and points outward along the closing axis; otherwise ``face`` is returned unchanged (and the
    friction-cone check of (6.20) decides, e.g. SLIP for a slanted face).
    """
    d = contact - mean
    d = d - (d @ face) * face
    nd = float(np.linalg.norm(d))
    if nd < 0.25 * radius or d @ closing <= 0:
        return face
    return d / nd


def grasp_quality(cloud: npt.ArrayLike, grasp: Grasp, *, gripper: ParallelGripper | None = None, mu: float = 0.5,
                  axis_radius: float = 0.006, normal_radius: float = 0.010, min_neighbors: int = 5,
                  tree: cKDTree | None = None, observed: cKDTree | None = None,
                  observed_radius: float = 0.005, edge_normals: bool = False,
                  pad_reach: float | None = None, table_z: float | None = None) -> GraspQuality:
    """(6.20) grasp isotropy of ``grasp`` on ``cloud`` (n, 3), negative for infeasible grasps.

    Args:
        cloud: object points (n, 3), metres.
        grasp: the grasp frame.
        gripper: jaw model (max opening; default :data:`NARROW_GRIPPER`).
        mu: friction coefficient of the contacts' cones.
        axis_radius: points within this distance of the axis line count for the line search.
        normal_radius: neighbourhood for the contact normals.
        min_neighbors: points needed within ``normal_radius`` of a contact (else SPARSE).
        tree: KD-tree of ``cloud`` (built when None).
        observed_radius: see ``observed`` (m).
        table_z: table plane height (world, m): points within 4 mm above it are not seen.
        observed: KD-tree of the points actually perceived (when ``cloud`` is completed by a model);
            contacts must lie within ``observed_radius`` (m) of them.
        pad_reach: contacts must lie at least this far (m) inside the finger pads along the approach,
            i.e. no deeper than ``gripper.tip_depth - pad_reach`` past the grasp centre (None: the
            whole ``axis_radius`` cylinder, the earlier test and the default, which the teaching
            sampler and the benchmark's gripper-fit test keep). The line-search cylinder reaches
            ``axis_radius`` (6 mm) past the centre, beyond the 5 mm fingertips: grasps planned 5 mm above
            a fork's or knife's handle read as touching it, and the jaws closed on nothing. With
            ``pad_reach`` and ``edge_normals``, no rim or pad normals are used when the part is more
            than 1 mm wider (along the closing axis, up to ``axis_radius`` past the fingertips) past
            the fingertips than at the contacts: its side slopes out under the seen face and the jaws
            would close on its upper slope and squeeze it down and out; the cloud normals decide.
        edge_normals: contact normals at the rim of a thin part seen face-on (see :func:`_rim_normal`);
            off by default (full object models, e.g. teaching, have their side faces sampled). Only
            when no cloud point lies in the jaws' path up to ``axis_radius`` past the fingertips (above
            ``table_z + 0.004`` when ``table_z``, world m, is given): a cup's wall seen from above
            continues below its top ring, which is no rim to grip (cups 20/20 -> 19/20 without this).
            A contact whose cloud normal is tilted 30-60 deg from the closing axis (a rounded handle's
            side, seen obliquely and smeared by 5 mm voxels and a 10 mm normal neighbourhood) takes
            the flat pad's normal (the closing axis) when that tilt is about the pad's breadth axis
            (normal within 15 deg of the closing-approach plane): a flat jaw closing on a part meets
            it at the part's extreme point inside the pad, where the pad is the supporting plane; the
            part is not wider past the fingertips (``pad_reach`` check) and does not continue there.
            A taper along the breadth (the medium clamp's wedge-shaped end) keeps its normal and is
            SLIP: squeezed, it slid out of the jaws toward its narrow end.
    """
    P = as_array(cloud, "cloud", (None, 3))
    gripper = NARROW_GRIPPER if gripper is None else gripper
    if len(P) < min_neighbors:
        return GraspQuality(SPARSE, "sparse")
    y = grasp.axis
    rel = P - grasp.centre
    s = rel @ y
    off = np.linalg.norm(rel - s[:, None] * y, axis=1)
    near = off < axis_radius
    half = gripper.max_width / 2
    if np.any(near & (np.abs(s) > half) & (np.abs(s) <= half + gripper.finger_thickness)):
        return GraspQuality(TOO_WIDE, "too wide")  # a jaw would land on the object
    near &= np.abs(s) <= half
    t = rel @ grasp.approach
    beyond = np.zeros(len(P), bool)
    if pad_reach is not None or edge_normals:
        # points past the fingertips (up to axis_radius deeper), in the jaws' path across the breadth
        beyond = (np.abs(rel @ grasp.rotation[:, 0]) < axis_radius) & (np.abs(s) <= half) & \
            (t > gripper.tip_depth) & (t < gripper.tip_depth + axis_radius)
    if pad_reach is not None:  # the pads end at the fingertips: nothing beyond them is gripped
        near &= t <= gripper.tip_depth - pad_reach
    if np.count_nonzero(near) < 2:
        return GraspQuality(OFF_AXIS, "off-axis")
    # each jaw, closing from its side, meets the outermost point within the opening
    idx = np.flatnonzero(near)
    ip = idx[np.argmax(s[idx])]
    ineg = idx[np.argmin(s[idx])]
    # rim and pad normals (below) assume the part's side under the seen face is square to it; the
    # part being wider past the fingertips than where the pads touch it says the side slopes out: the
    # jaws would close on its upper slope and squeeze it down and out (a fork's rounded handle under
    # jaws set too high). The cloud normals then decide.
    wider = pad_reach is not None and bool(np.any(beyond & ((s > s[ip] + 0.001) | (s < s[ineg] - 0.001))))
    contacts = P[[ip, ineg]]
    width = float(s[ip] - s[ineg])
    mid = grasp.centre + 0.5 * (s[ip] + s[ineg]) * y
    regrasp = Grasp(mid, grasp.rotation, width, grasp.name)
    if width > gripper.max_width:
        return GraspQuality(TOO_WIDE, "too wide", contacts, width=width, grasp=regrasp)
    if observed is not None and np.max(observed.query(contacts)[0]) > observed_radius:
        return GraspQuality(UNSEEN, "unseen", contacts, width=width, grasp=regrasp)
    tree = tree or cKDTree(P)
    normals = np.zeros((2, 3))
    cos_lim = 1.0 / np.sqrt(1.0 + mu * mu)
    # a rim lies within the pads only when the part does not continue past the fingertips (a cup's
    # wall seen from above does: its top ring is no rim to grip); below ``table_z + 0.004`` nothing is
    # seen (the perception's table cut), so points there do not count
    deeper = False
    if edge_normals:
        past = beyond if table_z is None else beyond & (P[:, 2] > table_z + 0.004)
        deeper = bool(np.any(past)) or wider
    for i, (c, sign) in enumerate(zip(contacts, (1.0, -1.0))):
        nb = tree.query_ball_point(c, normal_radius)
        if len(nb) < min_neighbors:
            return GraspQuality(SPARSE, "sparse", contacts, width=width, grasp=regrasp)
        mean = P[nb].mean(0)
        Q = P[nb] - mean
        _, V = np.linalg.eigh(Q.T @ Q)
        n = V[:, 0]
        n = n if n @ y * sign >= 0 else -n
        if edge_normals and not deeper and n @ y * sign < cos_lim:
            if abs(n @ y) < 0.5:  # a face the jaw slides along: it meets the face's rim
                n = _rim_normal(c, mean, n, y * sign, normal_radius)
            elif abs(n @ grasp.rotation[:, 0]) < 0.26:
                # a side rounded about the breadth axis, seen obliquely: the flat pad is the
                # supporting plane at the part's extreme point (a taper along the breadth keeps its
                # normal: squeezed, a wedge slides out toward its narrow end)
                n = y * sign
        normals[i] = n
    if normals[0] @ y < cos_lim or -(normals[1] @ y) < cos_lim:
        return GraspQuality(SLIP, "slip", contacts, normals, width, regrasp)
    q = isotropy(grasp_map(contacts, normals, mid, mu=mu))
    return GraspQuality(q, "ok", contacts, normals, width, regrasp)
