"""Dynamic imitation on a 2-link SCARA (Ch. 3.2, (3.2)-(3.9)).

A human arm seen by the Kinect (:mod:`.angles`) drives the SCARA (``Robot.load("scara2")``) by
computed torque around discrete LQ tracking (:mod:`robointel.control.lq`); the Kinect's latency is compensated by a
predictor (:mod:`.predictors`, :mod:`.ar_predictor`), the predicted signal is crossfaded
(:mod:`.crossfade`) and made torque-feasible (:mod:`.feasible`) before the LQ; :mod:`.simulation`
runs it all in MuJoCo with the settings of :mod:`.settings`; :mod:`.plot` draws Fig. 3.8.
"""
from robointel.control.lq import ComputedTorqueLQ, double_integrator, lq_gain
from robointel.teach.scara.angles import (
    arm_angles,
    arm_plane,
    human_reference,
    received_frames,
    recorded_angles,
)
from robointel.teach.scara.ar_predictor import ARPredictor, fit_predictor, training_predictor
from robointel.teach.scara.crossfade import Transition, smoothstep
from robointel.teach.scara.feasible import FeasibleReference, accel_limits
from robointel.teach.scara.metrics import delay_aligned_rms, delayed_copy_rms, required_torques
from robointel.teach.scara.plot import plot_scara
from robointel.teach.scara.predictors import HoldPredictor, KalmanPredictor, LinePredictor, Predictor
from robointel.teach.scara.settings import (
    BLEND_FRAMES,
    LIVE_CUTOFF_HZ,
    PAPER_RMS,
    PAPER_RMS_COMPENSATED,
    SMOOTH_HZ,
    ScaraSettings,
)
from robointel.teach.scara.simulation import ScaraResult, simulate_scara

__all__ = [
    "BLEND_FRAMES", "LIVE_CUTOFF_HZ", "PAPER_RMS", "PAPER_RMS_COMPENSATED", "SMOOTH_HZ",
    "ARPredictor", "ComputedTorqueLQ", "FeasibleReference", "HoldPredictor", "KalmanPredictor", "LinePredictor",
    "Predictor",
    "ScaraResult", "ScaraSettings", "Transition",
    "accel_limits", "arm_angles", "arm_plane", "delay_aligned_rms", "delayed_copy_rms", "double_integrator",
    "fit_predictor", "human_reference", "lq_gain", "plot_scara", "received_frames", "recorded_angles",
    "required_torques", "simulate_scara", "smoothstep",
    "training_predictor",
]
