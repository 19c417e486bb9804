"""Human arm -> SCARA joint angles (Ch. 3.2): the arm's plane, shoulder and elbow angles.

The human arm seen by the Kinect gives the desired SCARA angles q1d, q2d: q1d = the upper arm's
angle in the plane the arm moves in (from the hanging-down direction), q2d = the elbow's flexion
angle (by default the true 3-D angle between upper arm and forearm; the projected in-plane angle,
``elbow="planar"``, wraps past +-pi when the arm leaves the plane).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.teach.scara.settings import LIVE_CUTOFF_HZ
from robointel.teach.skeleton import Skeleton, clean, detect_bad


def arm_plane(skel: Skeleton, side: str) -> np.ndarray:
    """Unit normal of the plane the arm moves in.

    The least-variance direction of the upper-arm and forearm vectors (PCA), oriented to point
    forward/left/up (positive largest component).

    Args:
        skel: skeleton with the arm's shoulder, elbow and hand.
        side: "left" or "right".

    Returns:
        (3,) unit normal in the camera frame.
    """
    a = skel.arm(side)
    V = np.vstack([a["elbow"] - a["shoulder"], a["hand"] - a["elbow"]])
    _, _, vt = np.linalg.svd(V, full_matrices=False)
    n = vt[2]
    return n if n[np.argmax(np.abs(n))] > 0 else -n


def arm_angles(skel: Skeleton, side: str | None = None, *, normal: npt.ArrayLike | None = None,
               elbow: str = "flexion") -> np.ndarray:
    """SCARA joint targets from a skeleton.

    q1 = the upper arm's angle in the arm's plane, measured from the in-plane 'down' direction,
    unwrapped over time. ``elbow="planar"``: q2 = the projected forearm's angle relative to the
    projected upper arm, unwrapped over time (it can swing past -pi/pi when the arm leaves the
    plane). ``elbow="flexion"``: q2 = the elbow's true 3-D flexion angle (0 = straight, in
    [0, pi)), signed by the recording's dominant in-plane bending direction; it never wraps.

    Args:
        skel: skeleton (raw or cleaned).
        side: "left" or "right" (default: the more active arm).
        normal: (3,) the arm plane's normal (default :func:`arm_plane`).
        elbow: "flexion" or "planar".

    Returns:
        (N, 2) angles [rad].

    Raises:
        InvalidInput: unknown ``elbow``.
    """
    if elbow not in ("planar", "flexion"):
        raise InvalidInput(f"elbow must be 'planar' or 'flexion', got {elbow!r}", value=elbow)
    side = side or skel.active_side()
    if normal is None:
        n = arm_plane(skel, side)
    else:
        n = as_array(normal, "normal", (3,))
        n = n / np.linalg.norm(n)
    down = np.array([0.0, 0.0, -1.0])
    d = down - n * (n @ down)
    if np.linalg.norm(d) < 0.3:  # arm plane nearly horizontal: measure from 'forward'
        d = np.array([1.0, 0.0, 0.0]) - n * n[0]
    d /= np.linalg.norm(d)
    u = np.cross(n, d)
    a = skel.arm(side)
    e, h = a["elbow"] - a["shoulder"], a["hand"] - a["elbow"]
    q1 = np.unwrap(np.arctan2(e @ u, e @ d))
    q2 = np.arctan2(h @ u, h @ d) - np.arctan2(e @ u, e @ d)
    q2 = (q2 + np.pi) % (2 * np.pi) - np.pi
    if elbow == "flexion":
        c = np.einsum("ij,ij->i", e, h) / (np.linalg.norm(e, axis=1) * np.linalg.norm(h, axis=1))
        sign = 1.0 if np.median(q2) >= 0 else -1.0
        return np.stack([q1, sign * np.arccos(np.clip(c, -1.0, 1.0))], axis=1)
    return np.stack([q1, np.unwrap(q2)], axis=1)


def _arm_joints(side: str) -> list[str]:
    return ["SpineBase", *[f"{j}{'Right' if side == 'right' else 'Left'}" for j in ("Shoulder", "Elbow", "Hand")]]


def human_reference(skel: Skeleton, side: str | None = None, *, live_cutoff_hz: float = LIVE_CUTOFF_HZ,
                    elbow: str = "flexion") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The true and the live human angles of a recording on one uniform clock, in the SCARA's convention.

    Args:
        skel: raw skeleton.
        side: "left" or "right" (default: the more active arm).
        live_cutoff_hz: causal low-pass of the live signal [Hz].
        elbow: "flexion" or "planar".

    Returns:
        t (N,) [s], true angles (N, 2) [rad] (zero-phase cleaned), live angles (N, 2) [rad]
        (dropouts held, causal Butterworth low-pass at ``live_cutoff_hz``).
    """
    side = side or skel.active_side()
    joints = _arm_joints(side)
    truth = clean(skel, joints=joints)
    live = clean(skel, joints=joints, causal=True, cutoff_hz=min(live_cutoff_hz, 0.45 * skel.rate))
    normal = arm_plane(truth, side)
    q_true = arm_angles(truth, side, normal=normal, elbow=elbow)
    q_live = arm_angles(live, side, normal=normal, elbow=elbow)
    if np.median(q_true[:, 1]) * np.median(q_live[:, 1]) < 0:  # same bending sign for both (flexion)
        q_live[:, 1] *= -1.0
    # the SCARA base has no 'down': put the recording's mean shoulder angle at the middle of J1's
    # range (a calibration constant of the mapping, like the LR Mate's workspace scaling)
    off = np.array([np.mean(q_true[:, 0]), 0.0])
    return truth.t, q_true - off, q_live - off


def recorded_angles(skel: Skeleton, side: str | None = None, *,
                    elbow: str = "flexion") -> tuple[np.ndarray, np.ndarray]:
    """The human angles as recorded: dropouts bridged, not smoothed, in the SCARA's convention.

    The arm plane, elbow sign and J1 offset are those of the true angles of
    :func:`human_reference`, so the two signals differ only by the smoothing.

    Args:
        skel: raw skeleton.
        side: "left" or "right" (default: the more active arm).
        elbow: "flexion" or "planar".

    Returns:
        t (N,) [s] (the uniform frame clock of :func:`human_reference`), angles (N, 2) [rad].
    """
    side = side or skel.active_side()
    joints = _arm_joints(side)
    truth = clean(skel, joints=joints)
    raw = clean(skel, joints=joints, smooth=False)
    normal = arm_plane(truth, side)
    q_true = arm_angles(truth, side, normal=normal, elbow=elbow)
    q_raw = arm_angles(raw, side, normal=normal, elbow=elbow)
    if np.median(q_true[:, 1]) * np.median(q_raw[:, 1]) < 0:  # same bending sign (flexion)
        q_raw[:, 1] *= -1.0
    return raw.t, q_raw - np.array([np.mean(q_true[:, 0]), 0.0])


def received_frames(skel: Skeleton, side: str | None = None, *,
                    elbow: str = "flexion") -> tuple[np.ndarray, np.ndarray]:
    """The human angles of the frames as a live system receives them, on the sensor's own clock.

    No resampling and no low-pass: each frame keeps its capture time and its angles. A frame in
    which one of the arm's joints is not to be trusted by what a live system can tell from the
    frames before it (``detect_bad(causal=True)``: not tracked, or a jump faster than a hand
    moves) is dropped, so a dropout is a gap between frames. The arm plane, elbow sign and J1
    offset are those of :func:`human_reference`.

    Args:
        skel: raw skeleton.
        side: "left" or "right" (default: the more active arm).
        elbow: "flexion" or "planar".

    Returns:
        t (K,) capture times [s] (increasing), angles (K, 2) [rad].

    Raises:
        InvalidInput: fewer than 2 usable frames.
    """
    side = side or skel.active_side()
    joints = _arm_joints(side)
    truth = clean(skel, joints=joints)
    normal = arm_plane(truth, side)
    q_true = arm_angles(truth, side, normal=normal, elbow=elbow)
    cols = [skel.index(j) for j in joints]
    good = ~detect_bad(skel, causal=True)[:, cols].any(axis=1)
    if good.sum() < 2:
        raise InvalidInput(f"{skel.source!r}: fewer than 2 usable frames", value=int(good.sum()))
    frames = Skeleton(skel.t[good], skel.positions[good][:, cols], skel.state[good][:, cols], joints,
                      source=skel.source + " (received frames)")
    q = arm_angles(frames, side, normal=normal, elbow=elbow)
    if np.median(q_true[:, 1]) * np.median(q[:, 1]) < 0:  # same bending sign (flexion)
        q[:, 1] *= -1.0
    return frames.t, q - np.array([np.mean(q_true[:, 0]), 0.0])
