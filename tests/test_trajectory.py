"""The one joint trajectory type and its files."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.io.trajectory import load_trajectory, save_trajectory
from robointel.trajectory import Trajectory


def test_trajectory_validation_and_resample(tmp_path):
    t = np.array([0.0, 1.0, 2.0])
    q = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 0.0]])
    qd = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    tr = Trajectory(t, q, qd, np.zeros_like(q), ["a", "b"])
    d = tr.resample(0.001)
    assert d.t[-1] == pytest.approx(2.0) and len(d.t) == 2001
    np.testing.assert_allclose(d.q[::1000], q, atol=1e-12)
    with pytest.raises(InvalidInput):
        Trajectory([0.0, 0.0, 1.0], q, qd, qd)
    with pytest.raises(NotFinite):
        Trajectory(t, q * np.nan, qd, qd)
    with pytest.raises(ShapeError):
        Trajectory(t, q, qd[:2], qd)
    with pytest.raises(InvalidInput):
        save_trajectory(tr, tmp_path / "x.csv")
    with pytest.raises(InvalidInput):
        load_trajectory(tmp_path / "missing.npz")


@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_file_round_trip_keeps_names_meta_and_the_interpolant(tmp_path, suffix):
    t = np.array([0.0, 0.4, 1.0])
    q = np.array([[0.0, 1.0], [0.3, 0.5], [1.0, 0.0]])
    qd = np.array([[0.0, 0.0], [1.2, -1.0], [0.0, 0.0]])
    tr = Trajectory(t, q, qd, np.zeros_like(q), ["j1", "j2"], {"scene": "x", "n": 3})
    back = load_trajectory(save_trajectory(tr, tmp_path / f"traj{suffix}"))
    assert back.joint_names == ["j1", "j2"] and back.meta == {"scene": "x", "n": 3}
    ts = np.linspace(0, 1, 37)
    for a, b in zip(tr.sample(ts), back.sample(ts)):
        np.testing.assert_allclose(a, b, atol=1e-12)
    # the Hermite interpolant passes through the knots with the given velocities
    np.testing.assert_allclose(tr.sample(t)[0], q, atol=1e-12)
    np.testing.assert_allclose(tr.sample(t)[1], qd, atol=1e-12)
