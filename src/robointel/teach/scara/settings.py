"""Settings of a SCARA dynamic-imitation run (Ch. 3.2) and the dissertation's figures.

The choices behind the defaults (crossfade length, reference model, live low-pass, follower gains)
are measured in ``docs/design/teaching.md`` ("SCARA dynamic imitation").
"""
from __future__ import annotations

from dataclasses import dataclass

from robointel.errors import InvalidInput

#: The dissertation's RMS joint errors (q1, q2) [rad] on the SCARA, without / with compensation.
PAPER_RMS = (0.153, 0.185)
PAPER_RMS_COMPENSATED = (0.0103, 0.0305)
#: Natural frequency [Hz] of the second-order reference model for the compensated run; 0: none,
#: the lag-free crossfade instead.
SMOOTH_HZ = 0.0
#: Crossfade length in frame periods.
BLEND_FRAMES = 1.0
#: Cut-off [Hz] of the causal low-pass on the live Kinect frames.
LIVE_CUTOFF_HZ = 12.0

SHAPINGS = ("blend", "model", "follower", "none")
CLOCKS = ("grid", "frames")


@dataclass(frozen=True)
class ScaraSettings:
    """How a recording is imitated on the SCARA (see :func:`~robointel.teach.scara.simulate_scara`).

    Frames captured at t_k reach the controller at t_k + ``latency``. Without compensation the
    reference is the newest received frame; with it, a predictor's estimate of the angles now;
    with ``delay`` set, the predictor's estimate of the angles at t - ``delay`` (the delayed
    tracking of the dissertation's system: its whole delay is ``delay``).

    Shaping of that estimate into (q_r, qd_r, qdd_r) for the LQ (3.7)-(3.9):

    - ``"blend"`` (default): at each frame arrival the reference crossfades, with a quintic
      smoothstep over ``blend_time``, from the reference as it was to the new frame's prediction;
      both estimate the same instant, so the crossfade adds no lag, and q_r, qd_r, qdd_r are
      consistent (analytic derivatives). Without compensation it interpolates the delayed frames.
    - ``smooth_hz`` > 0 (shaping "model"): a critically damped second-order reference model
      (qdd_r = wn^2 (q_est - q_r) - 2 wn qd_r); it lags by about 2 / wn.
    - ``"follower"``: the jerk-limited follower (``ruckig``) of the estimate, the estimate being a
      Kalman filter's (uncompensated: at t - latency); it lags by about 1 / ``follow_gain``.
    - ``"none"`` (or ``follower=False``): the estimate as it is, qdd_r = 0.

    Attributes:
        latency: sensor latency [s], in [0, 2).
        compensate: predict across the latency.
        side: "left" or "right" arm (None: the more active one).
        dt: control period [s] (the MuJoCo step).
        shaping: "blend", "model", "follower" or "none" (see above).
        blend_time: crossfade length [s] (None: ``BLEND_FRAMES`` frame periods).
        smooth_hz: natural frequency of the reference model [Hz] (0: none; > 0 selects "model").
        follower: True/False select "follower"/"none" (None: ``shaping`` decides).
        offline: replay of a stored recording, known in advance: the reference is the cleaned
            recording itself at time t (``latency``/``compensate`` are ignored). With the
            follower off the LQ gets the recording's exact q, qd, qdd; with it, its jerk-limited
            version.
        predictor_psd: acceleration spectral density of the default Kalman predictor [rad^2/s^3].
        max_accel: (2,) acceleration limits of the follower [rad/s^2].
        jerk_factor: jerk limits of the follower = ``jerk_factor`` x ``max_accel`` [1/s].
        follow_gain: position feedback gain of the follower [1/s].
        elbow: the human elbow angle, "planar" or "flexion" (see ``arm_angles``).
        live_cutoff_hz: causal low-pass on the live frames [Hz].
        clock: "grid": the frames resampled to the recording's median rate and cleaned live
            (:func:`human_reference`); "frames": the frames as received, each at its own capture
            time, untrusted ones dropped, no low-pass (:func:`received_frames`).
        delay: aim the reference at the human angles at t - ``delay`` [s] (None: the newest
            frame as received, or now with ``compensate``); ``delay`` >= ``latency`` makes it an
            interpolation where the frames allow, and bridges the frame's age otherwise.
        feasible: pass the shaped reference through a torque-feasible ruckig follower
            (``FeasibleReference``) before the LQ: True, False, or a dict of its keyword arguments.
            None: on for live ``"blend"`` runs, off offline and for the other shapings.

    Raises:
        InvalidInput: latency, smooth_hz or shaping out of range (on construction).
    """

    latency: float = 0.1
    compensate: bool = False
    side: str | None = None
    dt: float = 0.001
    shaping: str = "blend"
    blend_time: float | None = None
    smooth_hz: float = 0.0
    follower: bool | None = None
    offline: bool = False
    predictor_psd: float = 10.0
    max_accel: tuple[float, float] = (60.0, 120.0)
    jerk_factor: float = 20.0
    follow_gain: float = 12.0
    elbow: str = "flexion"
    live_cutoff_hz: float = LIVE_CUTOFF_HZ
    feasible: bool | dict | None = None
    clock: str = "grid"
    delay: float | None = None

    def __post_init__(self) -> None:
        if not (0.0 <= self.latency < 2.0):
            raise InvalidInput(f"latency must be in [0, 2) s, got {self.latency}", value=self.latency)
        if self.smooth_hz < 0 or self.smooth_hz * self.dt > 0.05:
            raise InvalidInput(f"smooth_hz must be in [0, {0.05 / self.dt:g}] Hz at dt = {self.dt} s, "
                               f"got {self.smooth_hz}", value=self.smooth_hz)
        if self.shaping not in SHAPINGS:
            raise InvalidInput(f"shaping must be 'blend', 'follower' or 'none', got {self.shaping!r}",
                               value=self.shaping)
        if self.clock not in CLOCKS:
            raise InvalidInput(f"clock must be 'grid' or 'frames', got {self.clock!r}", value=self.clock)
        if self.delay is not None and not (0.0 <= self.delay < 2.0):
            raise InvalidInput(f"delay must be in [0, 2) s or None, got {self.delay}", value=self.delay)
        if self.delay is not None and self.compensate:
            raise InvalidInput("delay and compensate exclude each other: aim at t - delay, or predict t",
                               value=self.delay)

    @classmethod
    def delayed_tracking(cls, delay: float = 0.1, **fields: object) -> ScaraSettings:
        """The dissertation's system: the whole loop (vision + robot) is ``delay`` late.

        The frames as received (``clock="frames"``: their own capture times, no resampling, no
        low-pass), each usable ``delay`` after its capture; the reference is aimed at the human
        angles at t - ``delay`` (the frame's age, 0 to one frame period, bridged by the predictor,
        by default the constant-rate Kalman filter), crossfaded, made torque-feasible and tracked
        by the computed-torque LQ with the reference's own rate and acceleration as feed-forward.

        Args:
            delay: the system's delay [s] (measurement latency = aimed delay).
            **fields: other fields of :class:`ScaraSettings` (e.g. ``latency`` below ``delay``: a
                faster sensor, the rest of the delay spent interpolating between frames).

        Returns:
            The settings.
        """
        kw: dict = {"latency": delay, "delay": delay, "clock": "frames", **fields}
        return cls(**kw)

    @property
    def effective_shaping(self) -> str:
        """The shaping in force: ``follower`` and ``smooth_hz`` override ``shaping``."""
        shaping = self.shaping
        if self.follower is not None:
            shaping = "follower" if self.follower else "none"
        if self.smooth_hz > 0:
            shaping = "model"
        return shaping
