"""Human skeleton input for imitation (Ch. 3.2): Kinect v2 recordings and BVH files.

A :class:`Skeleton` holds joint positions over time in one *body-aligned* frame so that every
consumer (kinematic imitation on the LR Mate, dynamic imitation on the SCARA) reads the same
thing whatever the device was:

    x = the person's forward direction, y = the person's left, z = up   (metres, seconds)

A Kinect v2 camera frame (+x to the sensor's left, +y up, +z away from the sensor, person facing
the sensor) maps to it by ``KINECT_TO_BODY``; a BVH file (Y up, character facing +Z) by
``BVH_TO_BODY``.

Raw Kinect streams drop frames, mark joints as *inferred* or *not tracked*, and jump when a joint
is occluded (the notch at t = 4 s in Fig. 3.8b). :func:`clean` resamples to a uniform clock,
detects such samples (tracking state, Hampel outlier test on position) and bridges them by
shape-preserving interpolation over the good samples (offline) or a hold of the last good sample
(``causal=True``, what a live controller can do), then low-pass filters with a Butterworth filter
(zero-phase offline; causal online).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.ndimage import median_filter
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfiltfilt

from robointel._validate import as_array
from robointel.errors import DataMissing, InvalidInput, ShapeError

#: Kinect v2 joint order (JointType enumeration).
KINECT_JOINTS: tuple[str, ...] = (
    "SpineBase", "SpineMid", "Neck", "Head", "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft",
    "ShoulderRight", "ElbowRight", "WristRight", "HandRight", "HipLeft", "KneeLeft", "AnkleLeft",
    "FootLeft", "HipRight", "KneeRight", "AnkleRight", "FootRight", "SpineShoulder", "HandTipLeft",
    "ThumbLeft", "HandTipRight", "ThumbRight")

#: Kinect camera frame -> body frame (x forward, y left, z up) for a person facing the sensor.
KINECT_TO_BODY = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: BVH frame (Y up, character facing +Z, character's left = +X) -> body frame.
BVH_TO_BODY = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

#: Common BVH joint names (CMU / Mixamo style) -> Kinect names, so both read alike.
BVH_ALIASES: dict[str, str] = {
    "Hips": "SpineBase", "Spine": "SpineMid", "Spine1": "SpineShoulder", "Neck": "Neck", "Head": "Head",
    "LeftArm": "ShoulderLeft", "LeftForeArm": "ElbowLeft", "LeftHand": "HandLeft",
    "RightArm": "ShoulderRight", "RightForeArm": "ElbowRight", "RightHand": "HandRight",
    "LeftUpLeg": "HipLeft", "LeftLeg": "KneeLeft", "LeftFoot": "AnkleLeft",
    "RightUpLeg": "HipRight", "RightLeg": "KneeRight", "RightFoot": "AnkleRight",
}

NOT_TRACKED, INFERRED, TRACKED = 0, 1, 2


@dataclass
class Skeleton:
    """Joint positions over time.

    Attributes:
        t: (N,) sample times [s], increasing, starting at 0.
        positions: (N, J, 3) joint positions in the body-aligned frame [m].
        state: (N, J) tracking state per joint (0 not tracked, 1 inferred, 2 tracked).
        joint_names: J names (Kinect names where known).
        source: where it came from (file name, or "synthetic ..." for generated motion).
        bridged: (N, J) True where :func:`clean` replaced a sample (dropout, occlusion jump).
    """

    t: np.ndarray
    positions: np.ndarray
    state: np.ndarray
    joint_names: list[str]
    source: str = ""
    bridged: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.t = as_array(self.t, "t", (None,))
        self.positions = np.asarray(self.positions, dtype=float)
        n = len(self.t)
        if self.positions.ndim != 3 or self.positions.shape[0] != n or self.positions.shape[2] != 3:
            raise ShapeError(f"positions must have shape (N={n}, J, 3), got {self.positions.shape}")
        self.state = np.asarray(self.state, dtype=np.int8).reshape(n, -1)
        if self.state.shape[1] != self.positions.shape[1] or len(self.joint_names) != self.positions.shape[1]:
            raise ShapeError("state, positions and joint_names disagree on the number of joints")
        if n < 2 or np.any(np.diff(self.t) <= 0):
            raise InvalidInput("a skeleton needs at least 2 samples with strictly increasing times")

    @property
    def n(self) -> int:
        """Number of frames."""
        return len(self.t)

    @property
    def rate(self) -> float:
        """Median sample rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.t)))

    @property
    def duration(self) -> float:
        """Recording length, s."""
        return float(self.t[-1] - self.t[0])

    def index(self, name: str) -> int:
        """Column of joint ``name`` (Kinect names; BVH aliases accepted)."""
        name = BVH_ALIASES.get(name, name)
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise InvalidInput(f"skeleton from {self.source!r} has no joint {name!r}; joints: {self.joint_names}",
                               value=name) from None

    def joint(self, name: str) -> np.ndarray:
        """(N, 3) positions of one joint [m]."""
        return self.positions[:, self.index(name)]

    def arm(self, side: str = "right") -> dict[str, np.ndarray]:
        """(N, 3) positions of the hip centre, shoulder, elbow, wrist and hand of one arm."""
        if side not in ("right", "left"):
            raise InvalidInput(f"side must be 'right' or 'left', got {side!r}", value=side)
        s = "Right" if side == "right" else "Left"
        out = {"hip": self.joint("SpineBase"), "shoulder": self.joint("Shoulder" + s),
               "elbow": self.joint("Elbow" + s), "hand": self.joint("Hand" + s)}
        if "Wrist" + s in self.joint_names:
            out["wrist"] = self.joint("Wrist" + s)
        return out

    def active_side(self) -> str:
        """The arm whose hand moves more relative to the hip ('right' or 'left')."""
        spread = {}
        for side in ("right", "left"):
            try:
                a = self.arm(side)
            except InvalidInput:
                continue
            spread[side] = float(np.sum(np.var(a["hand"] - a["hip"], axis=0)))
        if not spread:
            raise InvalidInput(f"skeleton from {self.source!r} has no arm joints")
        return max(spread, key=lambda k: spread[k])


# ---------------------------------------------------------------------------------------- readers
def read_kinect_csv(path: str | Path) -> Skeleton:
    """Read a Kinect v2 recording.

    One line per frame, timestamp in 100 ns ticks, then 25 joints x (x, y, z [m, camera frame], tracking state); a
    trailing comma is allowed.

    Returns:
        Skeleton with t from 0 [s], positions rotated into the body frame (``KINECT_TO_BODY``).

    Raises:
        DataMissing: no such file.  InvalidInput: wrong number of fields, or no frames.
    """
    path = Path(path)
    if not path.exists():
        raise DataMissing(f"Kinect recording {path} not found", value=str(path))
    rows = []
    for k, line in enumerate(path.read_text().splitlines()):
        fields = [f for f in line.strip().split(",") if f.strip() != ""]
        if not fields:
            continue
        if len(fields) != 1 + 25 * 4:
            raise InvalidInput(f"{path}:{k + 1}: expected 101 fields (timestamp + 25 joints x 4), got {len(fields)}",
                               value=str(path))
        try:
            rows.append([float(f) for f in fields])
        except ValueError as exc:
            raise InvalidInput(f"{path}:{k + 1}: non-numeric field ({exc})", value=str(path)) from None
    if len(rows) < 2:
        raise InvalidInput(f"{path} has fewer than 2 frames", value=str(path))
    a = np.array(rows)
    t = (a[:, 0] - a[0, 0]) * 1e-7
    order = np.argsort(t, kind="stable")
    a, t = a[order], t[order]
    keep = np.concatenate([[True], np.diff(t) > 0])  # drop duplicated timestamps
    a, t = a[keep], t[keep]
    J = a[:, 1:].reshape(len(a), 25, 4)
    pos = J[:, :, :3] @ KINECT_TO_BODY.T
    state = np.rint(J[:, :, 3]).astype(np.int8)
    return Skeleton(t, pos, state, list(KINECT_JOINTS), source=path.name)


def _rot(axis: str, deg: np.ndarray) -> np.ndarray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i = "XYZ".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    R[..., i, i] = 1.0
    R[..., j, j] = c
    R[..., k, k] = c
    R[..., j, k] = -s
    R[..., k, j] = s
    return R


def read_bvh(source: str | Path, *, scale: float = 0.01) -> Skeleton:
    """Read a BVH motion file (path or the text itself) and compute every joint's position.

    Args:
        source: a ``.bvh`` path or BVH text.
        scale: file units to metres (BVH is commonly centimetres: 0.01).

    Returns:
        Skeleton in the body frame (``BVH_TO_BODY``), joint names mapped through ``BVH_ALIASES``
        (e.g. ``RightHand`` -> ``HandRight``), every joint marked tracked.

    Raises:
        DataMissing: path not found.  InvalidInput: malformed hierarchy or motion block.
    """
    text = str(source)
    if "HIERARCHY" not in text:
        p = Path(source)
        if not p.exists():
            raise DataMissing(f"BVH file {p} not found", value=str(p))
        text, name = p.read_text(), p.name
    else:
        name = "bvh text"
    tokens = text.split()
    try:
        m = tokens.index("MOTION")
    except ValueError:
        raise InvalidInput("BVH has no MOTION section") from None
    names: list[str] = []
    parents: list[int] = []
    offsets: list[Any] = []
    channels: list[list[str]] = []
    stack: list[int] = []
    i, last = 0, -1
    while i < m:
        tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            offsets.append(np.zeros(3))
            channels.append([])
            last = len(names) - 1
            i += 2
        elif tok == "End":  # End Site: a leaf without channels
            names.append(names[stack[-1]] + "_end")
            parents.append(stack[-1])
            offsets.append(np.zeros(3))
            channels.append([])
            last = len(names) - 1
            i += 2
        elif tok == "{":
            stack.append(last)
            i += 1
        elif tok == "}":
            stack.pop()
            i += 1
        elif tok == "OFFSET":
            offsets[stack[-1]] = np.array([float(x) for x in tokens[i + 1:i + 4]])
            i += 4
        elif tok == "CHANNELS":
            k = int(tokens[i + 1])
            channels[stack[-1]] = tokens[i + 2:i + 2 + k]
            i += 2 + k
        else:
            i += 1
    if not names:
        raise InvalidInput("BVH hierarchy has no joints")
    try:
        nframes = int(tokens[m + 2])
        dt = float(tokens[m + 5])
        data = np.array([float(x) for x in tokens[m + 6:]])
    except (ValueError, IndexError):
        raise InvalidInput("BVH MOTION block must read 'Frames: N' 'Frame Time: dt' then numbers") from None
    nch = sum(len(c) for c in channels)
    if nframes < 2 or dt <= 0 or data.size != nframes * nch:
        raise InvalidInput(f"BVH motion has {data.size} numbers, expected {nframes} frames x {nch} channels")
    data = data.reshape(nframes, nch)
    J = len(names)
    R = np.zeros((nframes, J, 3, 3))
    P = np.zeros((nframes, J, 3))
    col = 0
    for j in range(J):
        loc = np.zeros((nframes, 3)) + offsets[j]
        rot = np.broadcast_to(np.eye(3), (nframes, 3, 3)).copy()
        for ch in channels[j]:
            v = data[:, col]
            col += 1
            if ch.endswith("position"):
                loc[:, "XYZ".index(ch[0])] = v + (offsets[j]["XYZ".index(ch[0])] if parents[j] >= 0 else 0.0)
            else:
                rot = rot @ _rot(ch[0], v)
        if parents[j] < 0:
            R[:, j], P[:, j] = rot, loc
        else:
            pj = parents[j]
            R[:, j] = R[:, pj] @ rot
            P[:, j] = P[:, pj] + np.einsum("nij,nj->ni", R[:, pj], loc)
    keep = [j for j in range(J) if not names[j].endswith("_end")]
    pos = (P[:, keep] * scale) @ BVH_TO_BODY.T
    jn = [BVH_ALIASES.get(names[j], names[j]) for j in keep]
    t = np.arange(nframes) * dt
    return Skeleton(t, pos, np.full((nframes, len(keep)), TRACKED), jn, source=name)


def synthetic_wave_bvh(duration: float = 6.0, fps: float = 30.0, *, seed: int = 0, speed: float = 1.0) -> str:
    """BVH text of a SYNTHETIC arm-waving person (generated, not recorded).

    The right upper arm swings out and up at ~0.6 Hz while the forearm waves at ~1.1 Hz; the left arm hangs.

    Used by the demo stage and tests where no recording is available. Centimetres, Y up.
    ``speed`` scales every frequency.
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration * fps))
    t = np.arange(n) / fps * float(speed)
    ph = rng.uniform(0, 2 * np.pi, 2)
    # right upper arm: raise sideways (rotation about Z, negative raises the right arm outward)
    # and swing forward (about X)
    abduct = -(55 + 30 * np.sin(2 * np.pi * 0.6 * t + ph[0]))
    flex = -20 - 15 * np.sin(2 * np.pi * 0.3 * t)
    elbow = -(60 + 35 * np.sin(2 * np.pi * 1.1 * t + ph[1]))
    hips = np.stack([0.5 * np.sin(2 * np.pi * 0.2 * t), 95 + 0.3 * np.sin(2 * np.pi * 0.4 * t), np.zeros(n)], 1)
    lines = ["HIERARCHY", "ROOT Hips", "{", "  OFFSET 0 0 0",
             "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
             "  JOINT Spine", "  {", "    OFFSET 0 25 0", "    CHANNELS 3 Zrotation Xrotation Yrotation",
             "    JOINT Spine1", "    {", "      OFFSET 0 25 0", "      CHANNELS 3 Zrotation Xrotation Yrotation",
             "      JOINT Neck", "      {", "        OFFSET 0 10 0", "        CHANNELS 3 Zrotation Xrotation Yrotation",
             "        End Site", "        {", "          OFFSET 0 12 0", "        }", "      }",
             "      JOINT RightArm", "      {", "        OFFSET -18 0 0",
             "        CHANNELS 3 Zrotation Xrotation Yrotation",
             "        JOINT RightForeArm", "        {", "          OFFSET 0 -29 0",
             "          CHANNELS 3 Zrotation Xrotation Yrotation",
             "          JOINT RightHand", "          {", "            OFFSET 0 -26 0",
             "            CHANNELS 3 Zrotation Xrotation Yrotation",
             "            End Site", "            {", "              OFFSET 0 -8 0", "            }",
             "          }", "        }", "      }",
             "      JOINT LeftArm", "      {", "        OFFSET 18 0 0",
             "        CHANNELS 3 Zrotation Xrotation Yrotation",
             "        JOINT LeftForeArm", "        {", "          OFFSET 0 -29 0",
             "          CHANNELS 3 Zrotation Xrotation Yrotation",
             "          JOINT LeftHand", "          {", "            OFFSET 0 -26 0",
             "            CHANNELS 3 Zrotation Xrotation Yrotation",
             "            End Site", "            {", "              OFFSET 0 -8 0", "            }",
             "          }", "        }", "      }", "    }", "  }", "}",
             "MOTION", f"Frames: {n}", f"Frame Time: {1.0 / fps:.8f}"]
    # channels: Hips(6) Spine(3) Spine1(3) Neck(3) RightArm(3) RightForeArm(3) RightHand(3)
    #           LeftArm(3) LeftForeArm(3) LeftHand(3)
    for k in range(n):
        row = [*hips[k], 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
               abduct[k], flex[k], 0, 0, elbow[k], 0, 0, 0, 0,
               8, 0, 0, 0, -10, 0, 0, 0, 0]
        lines.append(" ".join(f"{v:.4f}" for v in row))
    return "\n".join(lines) + "\n"


def synthetic_wave(duration: float = 6.0, fps: float = 30.0, *, seed: int = 0,
                   dropout_at: float | None = 4.0, speed: float = 1.0) -> Skeleton:
    """A SYNTHETIC arm-waving skeleton (from :func:`synthetic_wave_bvh`) with Kinect-like faults.

    1 mm sensor noise and, at ``dropout_at`` seconds, a 0.2 s occlusion where the hand is marked not tracked and
    reported at the origin (like the notch in Fig. 3.8b).
    """
    sk = read_bvh(synthetic_wave_bvh(duration, fps, seed=seed, speed=speed))
    rng = np.random.default_rng(seed + 1)
    pos = sk.positions + rng.normal(0.0, 0.001, sk.positions.shape)
    state = sk.state.copy()
    if dropout_at is not None and dropout_at < sk.duration:
        k0 = int(np.searchsorted(sk.t, dropout_at))
        k1 = min(sk.n, k0 + max(1, int(round(0.2 * fps))))
        for name in ("HandRight", "ElbowRight"):
            j = sk.index(name)
            pos[k0:k1, j] = 0.0
            state[k0:k1, j] = NOT_TRACKED
    return replace(sk, positions=pos, state=state, source=f"synthetic arm wave ({duration:g} s, seed {seed})")


# ---------------------------------------------------------------------------------------- cleaning
def detect_bad(skel: Skeleton, *, window: int = 9, k: float = 4.0, floor: float = 0.03,
               inferred_floor: float = 0.015, causal: bool = False, max_speed: float = 5.0) -> np.ndarray:
    """(N, J) mask of samples not to trust.

    Offline: not tracked, or a Hampel outlier (distance from the running median over ``window``
    frames above ``max(k * 1.4826 * MAD, floor)`` metres; a tighter floor for *inferred* samples,
    which Kinect guesses during occlusion).
    Causal (``causal=True``, what a live system can do with past frames only): not tracked, or a
    jump from the last trusted sample faster than ``max_speed`` [m/s] (a centred median cannot be
    computed live, and a trailing one lags fast but real motion).
    """
    bad = skel.state <= NOT_TRACKED
    if causal:
        out = bad.copy()
        last_p = skel.positions[0].copy()
        last_t = np.full(skel.positions.shape[1], skel.t[0])
        have = ~bad[0]
        for i in range(1, skel.n):
            dt = np.maximum(skel.t[i] - last_t, 1e-3)
            jump = np.linalg.norm(skel.positions[i] - last_p, axis=1) / dt > max_speed
            out[i] |= have & jump
            ok = ~out[i]
            last_p[ok], last_t[ok] = skel.positions[i, ok], skel.t[i]
            have |= ok
        return out
    P = skel.positions.copy()
    P[bad] = np.nan
    # fill NaNs with the nearest good sample so the median is not dragged to the origin
    for j in range(P.shape[1]):
        good = ~bad[:, j]
        if good.sum() == 0:
            continue
        idx = np.where(good, np.arange(len(P)), -1)
        idx = np.maximum.accumulate(idx)
        first = int(np.argmax(good))
        idx[idx < 0] = first
        P[:, j] = P[idx, j]
    med = median_filter(P, size=(window, 1, 1), mode="nearest")
    dev = np.linalg.norm(P - med, axis=2)
    mad = median_filter(dev, size=(window, 1), mode="nearest")
    thr = np.maximum(k * 1.4826 * mad, np.where(skel.state == INFERRED, inferred_floor, floor))
    return bad | (dev > thr)


def clean(skel: Skeleton, *, cutoff_hz: float = 6.0, rate: float | None = None, causal: bool = False,
          order: int = 2, joints: Sequence[str] | None = None, smooth: bool = True) -> Skeleton:
    """Resample to a uniform clock, bridge dropouts/occlusion jumps, low-pass filter.

    Args:
        skel: raw skeleton.
        cutoff_hz: Butterworth cut-off [Hz] (human arm motion is below ~5 Hz).
        rate: output rate [Hz] (default: the recording's median rate; missing frames are filled).
        causal: False (offline): bridge by PCHIP over the good samples, zero-phase ``sosfiltfilt``.
            True (online): hold the last good sample, causal ``sosfilt`` (adds lag, like a live filter).
        order: Butterworth order.
        joints: only these joints (default all).
        smooth: False: bridge dropouts only, no low-pass (the recording's own samples elsewhere).

    Returns:
        A new Skeleton on the uniform grid with ``bridged`` marking replaced samples.
    """
    if cutoff_hz <= 0:
        raise InvalidInput(f"cutoff_hz must be positive, got {cutoff_hz}", value=cutoff_hz)
    rate = skel.rate if rate is None else float(rate)
    if not (0 < cutoff_hz < rate / 2):
        raise InvalidInput(f"cutoff_hz {cutoff_hz} must be below the Nyquist rate {rate / 2:.1f} Hz", value=cutoff_hz)
    cols = list(range(len(skel.joint_names))) if joints is None else [skel.index(n) for n in joints]
    bad = detect_bad(skel, causal=causal)
    n = int(np.floor(skel.duration * rate + 1e-9)) + 1
    tu = np.arange(n) / rate
    out = np.zeros((n, len(cols), 3))
    bridged = np.zeros((n, len(cols)), dtype=bool)
    # uniform grid samples that fall in a gap between frames (dropped frame) count as bridged
    gap = np.interp(tu, skel.t, np.arange(skel.n))
    for c, j in enumerate(cols):
        good = ~bad[:, j]
        if good.sum() < 2:
            raise InvalidInput(f"joint {skel.joint_names[j]} has fewer than 2 trustworthy samples", value=skel.source)
        tg, pg = skel.t[good], skel.positions[good, j]
        if causal:
            idx = np.searchsorted(tg, tu + 1e-9, side="right") - 1
            first = idx < 0
            idx = np.maximum(idx, 0)
            out[:, c] = pg[idx]
            out[first, c] = pg[0]
        else:
            out[:, c] = PchipInterpolator(tg, pg, axis=0, extrapolate=True)(tu)
        near = np.rint(gap).astype(int)
        bridged[:, c] = bad[near, j] | (np.abs(gap - near) > 0.25)
    sos = butter(order, cutoff_hz, fs=rate, output="sos")
    if smooth and causal:
        zi = sosfilt_zi(sos)
        flat = out.reshape(n, -1)
        filt = np.empty_like(flat)
        for m in range(flat.shape[1]):
            filt[:, m], _ = sosfilt(sos, flat[:, m], zi=zi * flat[0, m])
        out = filt.reshape(out.shape)
    elif smooth and n > 3 * (2 * order + 1):
        out = sosfiltfilt(sos, out, axis=0)
    state = np.where(bridged, INFERRED, TRACKED).astype(np.int8)
    return Skeleton(tu, out, state, [skel.joint_names[j] for j in cols],
                    source=skel.source + (" (cleaned, causal)" if causal else " (cleaned)"), bridged=bridged)


def load_skeleton(path: str | Path) -> Skeleton:
    """Read a recording by extension: ``.csv`` (Kinect v2) or ``.bvh``.

    Raises:
        InvalidInput: another extension, or a file that is not text (naming the file).
    """
    p = Path(path)
    if p.suffix.lower() not in (".bvh", ".csv"):
        raise InvalidInput(f"unknown skeleton format {p.suffix!r}; use a Kinect .csv or a .bvh file", value=str(p))
    try:
        return read_bvh(p) if p.suffix.lower() == ".bvh" else read_kinect_csv(p)
    except UnicodeDecodeError as exc:
        raise InvalidInput(f"{p} is not a text recording ({exc.reason} at byte {exc.start})", value=str(p)) from None
