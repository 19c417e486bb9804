"""Template fitting and classification by registration residual (6.17)-(6.19).

A target cloud is fitted to each template by a bounded per-axis scale and a heading (objects rest
upright on the table, at any heading) from the target's minimum-area footprint rectangle (or a
coarse yaw search), rigid CPD (with scale), then non-rigid CPD. The residual (6.17)-(6.19) is the
symmetric mean nearest-neighbour distance between the warped template and the target, weighted by
two shape terms from surface normals (local normal disagreement, global normal obliqueness); the
target's category is that of the template with the smallest score.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.learning.grasp.cpd import CPDResult, cpd_nonrigid, cpd_rigid, farthest_point_sample
from robointel.learning.grasp.cpd_warps import Warp
from robointel.learning.grasp.transfer import Grasp

__all__ = ["Template", "ComposedWarp", "Fit", "Classification", "fit_template", "classify",
           "confusion_matrix", "yaw_matrix", "normal_disagreement", "normal_obliqueness",
           "footprint_rectangle"]


@dataclass
class Template:
    """A taught object: its points, grasps, category and name.

    A taught object: ``points`` (M, 3) in its own frame (metres), taught ``grasps`` in that frame,
    its ``category``, ``name`` and ``mass`` (kg, weighed at teach time; None: unknown, the planner
    then assumes a density, see :func:`robointel.learning.grasp.hold.estimate_part`).
    """

    name: str
    category: str
    points: np.ndarray
    grasps: list[Grasp] = field(default_factory=list)
    mass: float | None = None

    def __post_init__(self) -> None:
        self.points = as_array(self.points, f"template {self.name} points", (None, 3))
        if len(self.points) < 4:
            raise InvalidInput(f"template {self.name} has {len(self.points)} points; need at least 4",
                               value=len(self.points))
        if self.mass is not None and not (np.isfinite(self.mass) and self.mass > 0):
            raise InvalidInput(f"template {self.name}: mass must be > 0 kg, got {self.mass}", value=self.mass)


@dataclass(frozen=True)
class ComposedWarp:
    """``T(x) = outer(inner(x))`` with Jacobian ``J_outer(inner(x)) J_inner(x)``."""

    inner: Warp
    outer: Warp

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        """``outer(inner(x))`` for points ``x`` (K, 3)."""
        return self.outer(self.inner(x))

    def jacobian(self, x: npt.ArrayLike) -> np.ndarray:
        """The chain rule at points ``x`` (K, 3): (K, 3, 3)."""
        x = np.atleast_2d(np.asarray(x, float))
        return np.einsum("kij,kjl->kil", self.outer.jacobian(self.inner(x)), self.inner.jacobian(x))


def yaw_matrix(a: float) -> np.ndarray:
    """Rotation by ``a`` (rad) about z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class _Init:
    R: np.ndarray
    t: np.ndarray

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        return np.asarray(x, float) @ self.R.T + self.t

    def jacobian(self, x: npt.ArrayLike) -> np.ndarray:
        return np.broadcast_to(self.R, (np.atleast_2d(x).shape[0], 3, 3)).copy()


@dataclass
class Fit:
    """A template fitted to a target: the warp, the classification score and its terms.

    A template fitted to a target: the full ``warp`` (template frame -> world), the ``residual``
    (the classification score, metres: ``distance * (1 + normal_weight * normals) * (1 + shape_weight *
    shape)``), the symmetric mean nearest-neighbour ``distance`` (6.17)-(6.19) (m), the ``normals``
    disagreement (see :func:`normal_disagreement`), the ``shape`` difference (absolute difference of
    the :func:`normal_obliqueness` of the warped template and of the target), the warped (subsampled)
    template ``warped`` and the CPD results.
    """

    template: Template
    warp: ComposedWarp
    residual: float
    warped: np.ndarray
    rigid: CPDResult
    nonrigid: CPDResult | None
    distance: float = float("nan")
    normals: float = float("nan")
    shape: float = float("nan")


def _sym_residual(A: np.ndarray, B: np.ndarray, treeB: cKDTree) -> float:
    da, _ = treeB.query(A)
    db, _ = cKDTree(A).query(B)
    return 0.5 * (float(da.mean()) + float(db.mean()))


def normal_disagreement(A: np.ndarray, B: np.ndarray, k: int = 10) -> float:
    """Normal disagreement of two clouds (sign-free), in [0, 1].

    Symmetric mean ``1 - |n_a . n_b|`` over nearest-neighbour pairs between clouds ``A`` (n, 3) and
    ``B`` (m, 3), normals by PCA of ``k`` neighbours (sign-free): 0 when the surfaces are parallel
    wherever they meet, up to 1. Shape information the point distance misses: a smooth warp can pull
    a can's flat lid into a cup's open top, or round a box, and land close to every point, but the
    surface directions then disagree.
    """
    from robointel.learning.grasp.quality import estimate_normals

    nA, nB = estimate_normals(A, k), estimate_normals(B, k)
    _, ia = cKDTree(B).query(A)
    _, ib = cKDTree(A).query(B)
    return 0.5 * (float((1 - np.abs((nA * nB[ia]).sum(1))).mean()) + float((1 - np.abs((nB * nA[ib]).sum(1))).mean()))


def normal_obliqueness(P: np.ndarray, k: int = 10) -> float:
    """Normal obliqueness of a cloud: mean |sin 2 phi| of its normals' elevation, in [0, 1].

    Mean ``|sin 2 phi|`` over the points of ``P`` (n, 3), ``phi`` the elevation of the PCA normal of
    ``k`` neighbours (sign-free): ``2 |n_z| sqrt(1 - n_z^2)``, 0 where the surface is horizontal (tops,
    lids) or vertical (the sides of upright boxes, cans, cups), 1 where it is inclined at 45 degrees.
    A global shape statistic, unlike :func:`normal_disagreement` blind to where the points are: a
    sphere gives 2/3 (``|n_z|`` is uniform over a sphere; 0.65 from PCA normals of 800 samples)
    whatever its size or heading, upright boxes and cylinders under 0.2 (only edges and rims count).
    A ball template squashed by a smooth warp onto a flat tuna can lands close to every point and its
    local normals follow, but it keeps rounded shoulders. Dimensionless, in [0, 1].
    """
    from robointel.learning.grasp.quality import estimate_normals

    z = np.abs(estimate_normals(as_array(P, "points", (None, 3)), k)[:, 2])
    return float(np.mean(2.0 * z * np.sqrt(np.clip(1.0 - z * z, 0.0, None))))


def footprint_rectangle(points: npt.ArrayLike, percentile: float = 2.0) -> tuple[float, np.ndarray]:
    """Minimum-area bounding rectangle of the horizontal footprint of ``points`` (n, 3) (m).

    Rotating calipers over the edges of the 2-D convex hull (scipy) of the x, y coordinates: the
    rectangle's heading ``angle`` (rad, in [0, pi/2)) is that of the hull edge giving the smallest
    area. Returns ``(angle, extents)``, ``extents`` (3,) the robust extents (``percentile`` to
    ``100 - percentile``) of the points along the rectangle's two axes and along z. Degenerate
    footprints (fewer than 3 distinct points, collinear) give angle 0.
    """
    from scipy.spatial import ConvexHull, QhullError

    P = as_array(points, "points", (None, 3))
    xy = P[:, :2] - P[:, :2].mean(0)
    angle = 0.0
    try:
        H = xy[ConvexHull(xy).vertices]
        e = np.roll(H, -1, axis=0) - H
        ang = np.mod(np.arctan2(e[:, 1], e[:, 0]), np.pi / 2)
        c, s = np.cos(ang), np.sin(ang)
        u = H @ np.stack([c, s])          # (h, edges): coordinates along each edge direction
        v = H @ np.stack([-s, c])
        area = np.ptp(u, axis=0) * np.ptp(v, axis=0)
        angle = float(ang[int(np.argmin(area))])
    except (QhullError, ValueError):
        pass
    Q = np.column_stack([xy @ yaw_matrix(-angle)[:2, :2].T, P[:, 2]])
    ext = np.diff(np.percentile(Q, [percentile, 100.0 - percentile], axis=0), axis=0)[0]
    ext[2] = np.ptp(P[:, 2])
    return angle, ext


def fit_template(target: npt.ArrayLike, template: Template, *, n_points: int = 200, yaw_steps: int = 12,
                 beta: float = 3.0,
                 lmbda: float = 200.0, w: float = 0.05, nonrigid: bool = True, max_iterations: int = 40,
                 tolerance: float = 1e-4, anisotropic: float = 1.5, rest_z: float | None = None,
                 normal_weight: float = 2.0, starts: int = 2,
                 footprint: bool = True, shape_weight: float = 0.5) -> Fit:
    """Fit a template to a target cloud: initial alignment, rigid then non-rigid CPD, score.

    The initial alignment (footprint rectangle or yaw search, below) is followed by rigid CPD
    (6.8)-(6.10) and non-rigid CPD (6.11)-(6.13); the score is the residual (6.17)-(6.19) times two
    shape terms. The choice of every default is recorded in ``docs/design/grasp.md`` ("Classification
    fit parameters").

    Args:
        target: The perceived cloud (n, 3), m, world frame.
        template: The template (points in its own frame, m).
        n_points: Farthest-point subsample size of both clouds.
        yaw_steps: Initial headings tried (a uniform grid over a full turn).
        beta: Non-rigid CPD kernel width (normalised units).
        lmbda: Non-rigid CPD regularisation lambda.
        w: CPD outlier weight.
        nonrigid: Run the non-rigid stage (else rigid only).
        max_iterations: EM iteration cap of each CPD stage.
        tolerance: Non-rigid CPD tolerance.
        anisotropic: (>= 1, 0 disables) the initial alignment scales the template along its own axes
            towards the target's robust extents, each axis within this factor of the isotropic
            RMS-radius scale (CPD's normalisation otherwise erases aspect ratios).
        rest_z: World z of the table (m; None = off): gravity-aware alignment for objects resting
            upright: the template's base on the table, its height scaled to the target's observed height,
            x and y scaled isotropically (``anisotropic`` then ignored).
        normal_weight: The score is the distance times ``1 + normal_weight * normal_disagreement``
            (0 = distance only, the dissertation's residual).
        starts: The registration runs from this many best initial alignments; the lowest score wins.
        footprint: (with ``anisotropic``, without ``rest_z``) four more starts turn the template's
            minimum-area footprint rectangle (:func:`footprint_rectangle`) onto the target's at the four
            quarter turns; the best of each pairing runs first.
        shape_weight: The score is also multiplied by ``1 + shape_weight * shape``, ``shape`` the
            absolute difference of the :func:`normal_obliqueness` of the warped template and the target.

    Returns:
        The best :class:`Fit` over the starts.

    Raises:
        InvalidInput: fewer than 4 target points, or (``rest_z``) a cloud not above its resting plane.
    """
    X = as_array(target, "target", (None, 3))
    if len(X) < 4:
        raise InvalidInput(f"target cloud has {len(X)} points; need at least 4", value=len(X))
    Xs = X[farthest_point_sample(X, n_points)] if len(X) > n_points else X
    Y = template.points
    Ys = Y[farthest_point_sample(Y, n_points)] if len(Y) > n_points else Y
    treeX = cKDTree(Xs)
    cy, cx = Ys.mean(0), Xs.mean(0)
    # scale guess from RMS radius so that the yaw search compares like with like
    sc = np.sqrt(((Xs - cx) ** 2).sum(1).mean() / ((Ys - cy) ** 2).sum(1).mean())
    if rest_z is not None:
        h_y = float(Ys[:, 2].max())
        h_x = float(Xs[:, 2].max()) - float(rest_z)
        if h_y <= 0 or h_x <= 0:
            raise InvalidInput("rest_z: template and target must reach above their resting planes",
                               value=(h_y, h_x))
        sxy = np.sqrt(((Xs[:, :2] - cx[:2]) ** 2).sum(1).mean() / ((Ys[:, :2] - cy[:2]) ** 2).sum(1).mean())
    inits = []
    for a in np.linspace(0, 2 * np.pi, yaw_steps, endpoint=False):
        R = yaw_matrix(a)
        A = sc * R
        if rest_z is not None:
            A = R @ np.diag([sxy, sxy, h_x / h_y])
            t = np.r_[cx[:2] - (A @ cy)[:2], rest_z]
            inits.append((_sym_residual(Ys @ A.T + t, Xs, treeX), A, t, f"yaw{np.degrees(a):.0f}"))
            continue
        if anisotropic:
            # per-axis scale in the template's own frame: its extents along x, y, z (after the yaw)
            # matched to the target's robust extents along the same world axes
            ey = np.ptp((Ys - cy) @ R.T, axis=0)
            ex = np.diff(np.percentile(Xs, [2.0, 98.0], axis=0), axis=0)[0]
            ex[2] = np.ptp(Xs[:, 2])
            A = R @ np.diag(sc * np.clip(ex / np.maximum(ey, 1e-6) / sc, 1.0 / anisotropic, anisotropic))
        Z = (Ys - cy) @ A.T + cx
        inits.append((_sym_residual(Z, Xs, treeX), A, cx - A @ cy, f"yaw{np.degrees(a):.0f}"))
    if footprint and anisotropic and rest_z is None:
        # footprint-aligned starts: the template's minimum-area footprint rectangle turned onto the
        # target's, all four quarter turns, each axis scaled to the target's extent along it
        ay, ey = footprint_rectangle(Ys)
        ax, ex = footprint_rectangle(Xs)
        for k in range(4):
            e = ex[[1, 0, 2]] if k % 2 else ex
            D = np.diag(sc * np.clip(e / np.maximum(ey, 1e-6) / sc, 1.0 / anisotropic, anisotropic))
            A = yaw_matrix(ax + k * np.pi / 2) @ D @ yaw_matrix(-ay)
            Z = (Ys - cy) @ A.T + cx
            inits.append((_sym_residual(Z, Xs, treeX), A, cx - A @ cy, f"fp{k}"))
    inits.sort(key=lambda c: c[0])
    if footprint and anisotropic and rest_z is None:
        # first the best footprint-aligned start of each parity (the template's long side along either
        # side of the target's rectangle), then the rest by their initial residual
        first = [next(c for c in inits if c[3] in ("fp0", "fp2")), next(c for c in inits if c[3] in ("fp1", "fp3"))]
        first.sort(key=lambda c: c[0])
        inits = (first + [c for c in inits if not c[3].startswith("fp")]
                 + [c for c in inits if c[3].startswith("fp") and not any(c is f for f in first)])
    ob_x = normal_obliqueness(Xs) if shape_weight else 0.0
    best: Fit | None = None
    for _, A, t, _tag in inits[:max(1, int(starts))]:
        init = _Init(A, t)
        Y0 = init(Ys)
        rig = cpd_rigid(Xs, Y0, w=w, tolerance=1e-3, max_iterations=max_iterations, method="fast")
        warp = ComposedWarp(init, rig.warp)
        warped = rig.TY
        nr = None
        if nonrigid:
            nr = cpd_nonrigid(Xs, warped, beta=beta, lmbda=lmbda, w=w, tolerance=tolerance,
                              max_iterations=max_iterations, method="lowrank")
            warp = ComposedWarp(warp, nr.warp)
            warped = nr.TY
        dist = _sym_residual(warped, Xs, treeX)
        nd = normal_disagreement(warped, Xs) if normal_weight else 0.0
        sh = abs(normal_obliqueness(warped) - ob_x) if shape_weight else 0.0
        fit = Fit(template, warp, dist * (1.0 + normal_weight * nd) * (1.0 + shape_weight * sh), warped, rig, nr,
                  dist, nd, sh)
        if best is None or fit.residual < best.residual:
            best = fit
    assert best is not None  # at least one start ran
    return best


@dataclass
class Classification:
    """Result of :func:`classify`: ``category``, best ``index``, all ``residuals`` (K,) and ``fits``."""

    category: str
    index: int
    residuals: np.ndarray
    fits: list[Fit]

    @property
    def best(self) -> Fit:
        """The winning template's fit."""
        return self.fits[self.index]


def classify(target: npt.ArrayLike, templates: Sequence[Template], **fit_kwargs: Any) -> Classification:
    """(6.17)-(6.19): fit every template and pick the one with the smallest residual.

    Args:
        target: The perceived cloud (n, 3), m, world frame.
        templates: The K classifying templates.
        **fit_kwargs: Keyword arguments of :func:`fit_template`.

    Returns:
        The category of the best-fitting template, its index, all residuals (K,) and the fits.

    Raises:
        InvalidInput: no templates, or a cloud :func:`fit_template` rejects.
    """
    if not templates:
        raise InvalidInput("classify needs at least one template", value=templates)
    fits = [fit_template(target, t, **fit_kwargs) for t in templates]
    res = np.array([f.residual for f in fits])
    i = int(np.argmin(res))
    return Classification(templates[i].category, i, res, fits)


def confusion_matrix(true: Sequence[str], predicted: Sequence[str],
                     labels: Sequence[str] | None = None) -> tuple[np.ndarray, list[str]]:
    """Confusion matrix (Fig. 6.7): rows = true category, columns = predicted.

    Args:
        true: True categories.
        predicted: Predicted categories, as many.
        labels: Row and column order (default: the sorted union).

    Returns:
        ``(C, labels)``: counts (L, L) and the labels.

    Raises:
        InvalidInput: the lengths differ.
    """
    if len(true) != len(predicted):
        raise InvalidInput(f"{len(true)} true labels but {len(predicted)} predictions",
                           value=(len(true), len(predicted)))
    labels = list(labels) if labels is not None else sorted(set(true) | set(predicted))
    ix = {l: i for i, l in enumerate(labels)}
    C = np.zeros((len(labels), len(labels)), dtype=int)
    for t, p in zip(true, predicted):
        C[ix[t], ix[p]] += 1
    return C, labels
