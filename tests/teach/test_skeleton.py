"""Skeleton input: Kinect v2 reader, BVH reader, dropout bridging and filtering."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import DataMissing, InvalidInput
from robointel.teach.skeleton import (
    KINECT_JOINTS,
    NOT_TRACKED,
    clean,
    detect_bad,
    load_skeleton,
    read_bvh,
    read_kinect_csv,
    synthetic_wave,
    synthetic_wave_bvh,
)

RECORDINGS = ["Ges01_wavehand", "Ges02_balancinghands", "Ges03_drawlines", "Ges04_comehere",
              "Ges05_demopoint", "Ges06_chickenwing", "joints"]


@pytest.mark.parametrize("name", RECORDINGS)
def test_kinect_reader_body_frame(shared_data, name):
    sk = read_kinect_csv(shared_data("kinect", f"{name}.csv"))
    assert sk.positions.shape == (sk.n, 25, 3) and sk.joint_names == list(KINECT_JOINTS)
    assert 25 < sk.rate < 35 and np.all(np.diff(sk.t) > 0)
    # body frame: the head is above the hip centre, shoulders left/right of the spine
    assert np.all(sk.joint("Head")[:, 2] > sk.joint("SpineBase")[:, 2])
    assert np.median(sk.joint("ShoulderLeft")[:, 1] - sk.joint("ShoulderRight")[:, 1]) > 0.2
    # segment lengths of a real arm (m)
    upper = np.linalg.norm(sk.joint("ElbowRight") - sk.joint("ShoulderRight"), axis=1)
    assert 0.15 < np.median(upper) < 0.40


def test_dropout_and_occlusion_are_bridged(shared_data):
    sk = read_kinect_csv(shared_data("kinect", "Ges01_wavehand.csv"))
    ref = clean(sk)
    j = sk.index("HandRight")
    k = int(np.searchsorted(sk.t, 4.0))
    pos, state = sk.positions.copy(), sk.state.copy()
    pos[k:k + 4, j] = 0.0                 # not tracked: Kinect reports the origin
    state[k:k + 4, j] = NOT_TRACKED
    pos[k + 20, j] += [0.0, 0.4, 0.0]     # an occlusion jump that claims to be tracked
    from dataclasses import replace
    bad = replace(sk, positions=pos, state=state)
    mask = detect_bad(bad)
    assert mask[k:k + 4, j].all() and mask[k + 20, j]
    c = clean(bad)
    jj = c.index("HandRight")
    # no jump passes: the cleaned hand stays near the clean recording and moves at human speed
    err = np.linalg.norm(c.positions[:, jj] - ref.positions[:, jj], axis=1)
    assert err.max() < 0.08
    speed = np.linalg.norm(np.diff(c.positions[:, jj], axis=0), axis=1) * c.rate
    assert speed.max() < 4.0
    assert c.bridged[:, jj].sum() >= 5


def test_causal_clean_uses_no_future(shared_data):
    sk = read_kinect_csv(shared_data("kinect", "Ges01_wavehand.csv"))
    from dataclasses import replace
    full = clean(sk, causal=True, rate=30.0)
    half = clean(replace(sk, t=sk.t[:80], positions=sk.positions[:80], state=sk.state[:80]), causal=True, rate=30.0)
    n = half.n
    np.testing.assert_allclose(full.positions[:n], half.positions[:n], atol=1e-12)


def test_uniform_resampling_fills_dropped_frames(shared_data):
    sk = read_kinect_csv(shared_data("kinect", "Ges03_drawlines.csv"))
    c = clean(sk)
    assert np.allclose(np.diff(c.t), 1 / sk.rate)
    assert c.n > sk.n  # the recording has dropped frames (dt = 67 ms)


def test_bvh_roundtrip_geometry():
    sk = read_bvh(synthetic_wave_bvh(duration=2.0, fps=30.0))
    assert sk.n == 60 and "HandRight" in sk.joint_names and "SpineBase" in sk.joint_names
    # bone lengths from the OFFSETs (cm -> m) are preserved by the forward kinematics
    upper = np.linalg.norm(sk.joint("ElbowRight") - sk.joint("ShoulderRight"), axis=1)
    fore = np.linalg.norm(sk.joint("HandRight") - sk.joint("ElbowRight"), axis=1)
    np.testing.assert_allclose(upper, 0.29, atol=1e-9)
    np.testing.assert_allclose(fore, 0.26, atol=1e-9)
    # body frame: the right shoulder is on the right (negative y), the head is up
    assert np.all(sk.joint("ShoulderRight")[:, 1] < sk.joint("ShoulderLeft")[:, 1])
    assert sk.active_side() == "right"


def test_bvh_file_and_synthetic_faults(tmp_path):
    p = tmp_path / "wave.bvh"
    p.write_text(synthetic_wave_bvh(1.0))
    assert load_skeleton(p).n == 30
    sk = synthetic_wave(6.0)
    assert "synthetic" in sk.source
    assert (sk.state == NOT_TRACKED).any()
    c = clean(sk)
    assert np.linalg.norm(c.joint("HandRight"), axis=1).min() > 0.5  # the dropout to the origin is gone


def test_bad_input():
    with pytest.raises(DataMissing):
        read_kinect_csv("/nonexistent/rec.csv")
    with pytest.raises(InvalidInput):
        read_bvh("HIERARCHY ROOT Hips { OFFSET 0 0 0 CHANNELS 3 Xposition Yposition Zposition } "
                 "MOTION Frames: 2 Frame Time: 0.1 1 2 3")
    with pytest.raises(InvalidInput):
        clean(synthetic_wave(1.0), cutoff_hz=40.0)
    with pytest.raises(InvalidInput):
        load_skeleton("rec.txt")
