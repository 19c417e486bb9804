"""Feel the part's face, then align and insert: the strategy a person uses at a tight chamferless fit.

Without a chamfer a 20 um fit admits about 0.1 deg of tilt within the first millimetres below the rim,
and once two points touch the peg wedges (see docs/design/skills.md). A person does not find the hole's axis
by pushing into the hole: they first rest the peg's ball tip on the flat face beside the hole, slide it
round a small circle under a light push and feel how the hand rises and falls (the face's slope in the
hand's frame: proprioception), lift off, turn the peg square to the face, go back over the hole and push
in, keeping the peg square and yielding sideways to what they feel. The hole is drilled square to its
face: the felt face normal is the hole axis. When the felt positions do not lie on one plane (the ball
rolled over an edge, lost the face, or hardly moved: :meth:`FeltStrategy.trusted`), the person feels
the face again on the other side of the hole before trusting a normal. The same stage machine runs the scripted person
(:func:`demonstrate_felt`, on the hand-held device) and the robot (:class:`FeltStrategy` as an
insertion policy); the robot's rotation command comes from the skill learned from the person
(:class:`~robointel.learning.insertion.felt_skill.FeltSkill`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput

#: stages of the strategy, in order (``cross``: over the hole to feel the face on the other side)
STAGES = ("aside", "touch", "feel", "cross", "lift", "align", "return", "insert")
#: a learned rotation: remaining tilt (2,) rad -> rotation rate (2,) rad/s
RotationModel = Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]]
#: axial damping (N s/m) that turns a commanded axial speed into a push at a stall (the robot's axial damper)
AXIAL_DAMPING = 1000.0


@dataclass(frozen=True)
class PlaneFit:
    """A plane fitted to the ball-centre positions felt while sliding on a face, with its quality.

    Attributes:
        normal: (3,) unit normal, out of the face (against the tool axis).
        rms: RMS distance (m) of the kept positions from the plane.
        kept: Fraction of the positions kept (the rest: moments of lost contact or rolling over an edge).
        n: Number of positions kept.
        spread: Smaller in-plane standard deviation (m) of the kept positions (a line gives no plane).
        point: (3,) mean of the kept positions (m): a point of the plane (the ball centre resting on the face).
    """

    normal: npt.NDArray[np.float64]
    rms: float
    kept: float
    n: int
    spread: float
    point: npt.NDArray[np.float64]


def fit_face(points: npt.NDArray[np.float64]) -> PlaneFit:
    """The plane through the ball-centre positions felt while sliding on a face, and how well they lie on it.

    A total-least-squares plane (SVD), refitted three times without the positions more than four median
    absolute deviations off the plane (a moment of lost contact).

    Args:
        points: (n, 3) ball-centre positions (m), n >= 3, not all on a line.

    Returns:
        The fit; its normal points against the tool axis (+z of the frame the points are in): out of the face.

    Raises:
        InvalidInput: fewer than 3 points.
    """
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 3:
        raise InvalidInput(f"face_normal needs (n >= 3, 3) points, got {P.shape}", value=P.shape)
    n_all = len(P)
    for _ in range(3):
        m = P.mean(0)
        n = np.linalg.svd(P - m, full_matrices=False)[2][2]
        res = np.abs((P - m) @ n)
        keep = res < 4 * (np.median(res) + 1e-7)
        if keep.sum() < 3:
            break
        P = P[keep]
    m = P.mean(0)
    _, sv, vt = np.linalg.svd(P - m, full_matrices=False)
    n = vt[2]
    rms = float(np.sqrt(np.mean(((P - m) @ n) ** 2)))
    n = -n if n[2] > 0 else n
    return PlaneFit(n, rms, len(P) / n_all, len(P), float(sv[1] / np.sqrt(len(P))), m)


def face_normal(points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Unit normal (3,) of the plane through the ball-centre positions felt while sliding on a face.

    Args:
        points: (n, 3) ball-centre positions (m), n >= 3, not all on a line.

    Returns:
        :func:`fit_face`'s normal: out of the face.

    Raises:
        InvalidInput: fewer than 3 points.
    """
    return fit_face(points).normal


@dataclass
class FeltStrategy:
    """The feel-align-insert stage machine as an insertion policy (wrench and proprioception -> tool twist).

    Called every ``dt`` with the felt wrench (6,) [N; N m] in the tool frame and the tool pose (4, 4)
    relative to the pose at the first call (proprioception: no world frame, no hole axis); returns the
    tool twist [vx, vy, vz, wx, wy] (m/s, rad/s) of the ball tip's centre, in the tool frame. Positions
    are tracked with a proportional speed law (``k_pos``, saturated) on the felt position, so the
    command does not depend on how well the arm follows it. The rotation while aligning and inserting is
    :meth:`rotation` of the remaining tilt: the person's reflex here, the learned skill in
    :class:`~robointel.learning.insertion.felt_skill.FeltSkill`.

    Attributes:
        centre: Distance (m) from the F/T sensor to the ball tip's centre along the tool axis.
        aside: Lateral move (m) from the start onto the face beside the hole.
        circle_radius: Radius (m) of the felt circle.
        circle_hz: Frequency (Hz) of the felt circle (half a turn spiralling out, one turn at the radius).
        feel_push: Axial speed (m/s) while feeling: a push of ``AXIAL_DAMPING`` x this (N); the touch goes
            down at 4 x this.
        touch_force: Axial force (N) that ends the touch.
        lift: Lift (m) off the face before turning.
        k_align: Rotation rate per tilt (1/s) of the person's reflex.
        w_max: Largest rotation rate (rad/s).
        align_tol: Remaining tilt (rad) that ends the alignment.
        v_insert: Axial speed (m/s) while inserting.
        v_mouth: Axial speed (m/s) while the ball tip centres in the mouth: from the first push felt there
            (``touch_force``) or the ball centre going below where it rested on the face, whichever is first,
            until it is ``mouth_depth`` below (a lighter push and a slower arrival on the rim's edge).
        mouth_depth: Depth (m) of the ball centre below its resting height on the face that ends the mouth.
        k_force: Lateral admittance (m/s per N) while inserting.
        speed: Free-air speed (m/s).
        k_pos: Position gain (1/s).
        stage_timeout: Longest alignment or return (s).
        return_tol: Distance (m) from the start point that ends the return (the start is off the hole anyway).
        dt: Call period (s).
        max_rms: Largest RMS distance (m) of the felt positions from their plane for a trusted fit.
        min_kept: Smallest fraction of the felt positions on the plane for a trusted fit.
        min_spread: Smallest in-plane spread of the felt positions, as a fraction of ``circle_radius``.
        refeel: Feel the face again on the other side of the hole when the first fit is not trusted.
        rotation_model: Remaining tilt (2,) -> rotation rate (2,) replacing the reflex (the learned skill).
    """

    centre: float
    aside: float = 0.0187
    circle_radius: float = 0.0015
    circle_hz: float = 0.75
    feel_push: float = 0.0015
    touch_force: float = 1.0
    lift: float = 0.0015
    k_align: float = 3.0
    w_max: float = 0.08
    align_tol: float = float(np.radians(0.03))
    v_insert: float = 0.010
    v_mouth: float = 0.006
    mouth_depth: float = 0.014
    k_force: float = 1e-3
    speed: float = 0.03
    k_pos: float = 5.0
    stage_timeout: float = 2.0
    return_tol: float = 1e-3
    dt: float = 0.01
    max_rms: float = 2e-6
    min_kept: float = 0.7
    min_spread: float = 0.1
    refeel: bool = True
    rotation_model: RotationModel | None = None
    proprioceptive: bool = field(default=True, init=False)

    def __post_init__(self) -> None:
        if not (0 < self.circle_radius < 0.005 and 0.01 < self.aside < 0.03 and self.dt > 0):
            raise InvalidInput("FeltStrategy: circle_radius in (0, 5 mm), aside in (10, 30 mm), dt > 0 needed",
                               value=(self.circle_radius, self.aside, self.dt))
        if not (self.max_rms > 0 and 0 < self.min_kept <= 1 and self.min_spread >= 0):
            raise InvalidInput("FeltStrategy: max_rms > 0, min_kept in (0, 1], min_spread >= 0 needed",
                               value=(self.max_rms, self.min_kept, self.min_spread))
        self.reset()

    def reset(self) -> None:
        """Start a new insertion (first stage, nothing felt)."""
        self.stage = STAGES[0]
        self.t = 0.0
        self._t_stage = 0.0
        self._points: list[npt.NDArray[np.float64]] = []
        self.normal: npt.NDArray[np.float64] | None = None
        self._c0: npt.NDArray[np.float64] | None = None
        self._side = 1.0
        self._face = np.zeros(3)
        self._rim = False
        self.fits: list[PlaneFit] = []
        self._hold = np.zeros(3)
        self.tilt_error = np.zeros(2)

    def rotation(self, tilt_error: npt.NDArray[np.float64], wrench: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Rotation rate (2,) [wx, wy] (rad/s, tool frame) for the remaining tilt: the person's reflex.

        Args:
            tilt_error: (2,) [x, y] of z x (-n) with n the felt face normal in the tool frame (rad, small angles).
            wrench: (6,) felt wrench (unused by the reflex).

        Returns:
            k_align x tilt_error, saturated at ``w_max`` (or ``rotation_model(tilt_error)`` when set).
        """
        if self.rotation_model is not None:
            return np.asarray(self.rotation_model(np.asarray(tilt_error, float)), float)
        w = self.k_align * np.asarray(tilt_error, float)
        s = float(np.linalg.norm(w))
        return w * (self.w_max / s) if s > self.w_max else w

    def _goto(self, c: npt.NDArray[np.float64], goal: npt.NDArray[np.float64], R: npt.NDArray[np.float64],
              vmax: float) -> tuple[npt.NDArray[np.float64], float]:
        e = goal - c
        d = float(np.linalg.norm(e))
        v = self.k_pos * e
        s = float(np.linalg.norm(v))
        return R.T @ (v * (vmax / s) if s > vmax else v), d

    def _next(self, stage: str) -> None:
        self.stage, self._t_stage = stage, self.t

    def trusted(self, fit: PlaneFit) -> bool:
        """Whether a plane fit is good enough to align to.

        Args:
            fit: The plane fit of one feel.

        Returns:
            RMS residual below ``max_rms``, at least ``min_kept`` of the positions and 20 of them on the plane,
            in-plane spread above ``min_spread`` x ``circle_radius``.
        """
        return (fit.rms < self.max_rms and fit.kept >= self.min_kept and fit.n >= 20
                and fit.spread > self.min_spread * self.circle_radius)

    def _felt(self, c: npt.NDArray[np.float64]) -> None:
        """End of a feel: fit the plane, feel again on the other side if it is not trusted, else lift."""
        if len(self._points) >= 3:
            self.fits.append(fit_face(np.array(self._points)))
        self._points = []
        if self.refeel and self._side > 0 and not (self.fits and self.trusted(self.fits[-1])):
            self._side = -1.0
            self._next("cross")
            return
        good = [f for f in self.fits if self.trusted(f)]
        best = good[-1] if good else min(self.fits, key=lambda f: f.rms) if self.fits else None
        self.normal = best.normal if best is not None else np.array([0.0, 0.0, -1.0])
        self._face = best.point if best is not None else c.copy()
        self._hold = c + self.normal * self.lift
        self._next("lift")

    def __call__(self, wrench: npt.NDArray[np.float64], T_rel: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Tool twist (5,) [m/s, rad/s] for the felt wrench (6,) and the (4, 4) pose relative to the start."""
        w = np.asarray(wrench, float)
        R = T_rel[:3, :3]
        c = T_rel[:3, 3] + R[:, 2] * self.centre
        if self._c0 is None:
            self._c0 = c.copy()
        self.t += self.dt
        st = self.t - self._t_stage
        push = -float(w[2])
        tw = np.zeros(5)
        goal = self._c0 + np.array([self._side * self.aside, 0.0, 0.0])  # on the face beside the hole
        if self.stage in ("aside", "cross"):
            tw[:3], d = self._goto(c, goal, R, self.speed)
            if d < 5e-4 or (self.stage == "cross" and np.linalg.norm((R.T @ (goal - c))[:2]) < 5e-4):
                self._next("touch")  # after crossing: over the target is enough, the touch goes down
        elif self.stage == "touch":
            # down onto the face, holding the aside target: the equilibrium does not run on past it
            tw[:2] = self._goto(c, goal, R, self.speed)[0][:2]
            tw[2] = 4.0 * self.feel_push
            if push > self.touch_force:
                self._next("feel")
        elif self.stage == "feel":
            # a circle centred on the aside target, its radius growing over the first half turn
            om = 2 * np.pi * self.circle_hz
            ph = om * st
            rad = self.circle_radius * min(1.0, 2.0 * self.circle_hz * st)
            goal_xy = (R.T @ goal)[:2] + rad * np.array([np.cos(ph), np.sin(ph)])
            pos = (R.T @ c)[:2]
            tw[:2] = om * rad * np.array([-np.sin(ph), np.cos(ph)]) + 2 * self.k_pos * (goal_xy - pos)
            tw[2] = self.feel_push
            if st > 0.15 and push > 0.7 * AXIAL_DAMPING * self.feel_push:
                self._points.append(c.copy())
            if st > 1.5 / self.circle_hz + 0.15:
                self._felt(c)
        else:
            assert self.normal is not None
            n_tool = R.T @ self.normal
            self.tilt_error = np.cross([0.0, 0.0, 1.0], -n_tool)[:2]
            tw[3:] = self.rotation(self.tilt_error, w)
            if self.stage == "lift":
                tw[:3], _ = self._goto(c, self._hold, R, self.speed / 3)
                if st > 0.3:
                    self._next("align")
            elif self.stage == "align":
                tw[:3], _ = self._goto(c, self._hold, R, self.speed / 3)
                if np.linalg.norm(self.tilt_error) < self.align_tol or st > self.stage_timeout:
                    self._next("return")
            elif self.stage == "return":
                tw[:3], d = self._goto(c, self._c0, R, self.speed)
                if d < self.return_tol or st > self.stage_timeout:
                    self._next("insert")
            else:
                tw[:2] = self.k_force * w[:2]
                self._rim = self._rim or push > self.touch_force
                h = float((c - self._face) @ self.normal)  # ball centre above its resting height on the face
                in_mouth = (self._rim or h < 0) and h > -self.mouth_depth
                tw[2] = min(self.v_mouth, self.v_insert) if in_mouth else self.v_insert
        return tw
