"""CPD against pycpd (same parameters) and its own invariants."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robointel.errors import InvalidInput, ShapeError
from robointel.learning.grasp.cpd import (
    cpd_affine,
    cpd_nonrigid,
    cpd_rigid,
    farthest_point_sample,
    mean_nn_residual,
    register,
)

try:  # the peer (peers extra): only the comparisons with it skip without it
    import pycpd
except ImportError:  # pragma: no cover - peers extra missing
    pycpd = None

needs_pycpd = pytest.mark.skipif(pycpd is None, reason="pycpd (peers extra) is not installed")


def _pair(shared_data, name):
    X = np.loadtxt(shared_data("cpd", f"{name}_target.txt"))
    Y = np.loadtxt(shared_data("cpd", f"{name}_source.txt"))
    return X, Y


@needs_pycpd
@pytest.mark.parametrize("name", ["fish", "bunny"])
def test_nonrigid_matches_pycpd(shared_data, name):
    X, Y = _pair(shared_data, name)
    ref = pycpd.DeformableRegistration(X=X, Y=Y, alpha=2.0, beta=2.0)
    TY, _ = ref.register()
    ours = cpd_nonrigid(X, Y, beta=2.0, lmbda=2.0, normalize=False, method="exact")
    assert ours.iterations == ref.iteration
    assert np.abs(ours.TY - TY).max() < 1e-6
    assert np.abs(ours.warp(Y) - TY).max() < 1e-6


@needs_pycpd
@pytest.mark.parametrize("name", ["fish", "bunny"])
def test_rigid_affine_match_pycpd(shared_data, name):
    X, Y = _pair(shared_data, name)
    TY, _ = pycpd.RigidRegistration(X=X, Y=Y, max_iterations=25).register()
    r = cpd_rigid(X, Y, normalize=False, max_iterations=25)
    assert np.abs(r.TY - TY).max() < 1e-6
    assert np.isclose(np.linalg.det(r.warp.R), 1.0)
    TY, _ = pycpd.AffineRegistration(X=X, Y=Y, max_iterations=25).register()
    a = cpd_affine(X, Y, normalize=False, max_iterations=25)
    assert np.abs(a.TY - TY).max() < 1e-6


def test_rigid_recovers_known_motion_any_units():
    rng = np.random.default_rng(1)
    Y = rng.normal(size=(200, 3)) * np.array([0.1, 0.05, 0.02])
    th = 0.4
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    X = 1000.0 * (Y @ R.T + np.array([0.3, -0.2, 0.1]))  # millimetres and offset
    r = cpd_rigid(X, Y, tolerance=1e-10, max_iterations=300)
    assert np.allclose(r.warp.R, R, atol=1e-5)
    assert np.isclose(r.warp.s, 1000.0, rtol=1e-5)
    assert np.abs(r.TY - X).max() < 1e-3


def test_lowrank_close_to_exact_and_warp_jacobian(shared_data):
    X = np.loadtxt(shared_data("cpd", "bunny-x.txt"))[::16]
    Y = np.loadtxt(shared_data("cpd", "bunny-y.txt"))[::16]
    ex = cpd_nonrigid(X, Y, beta=2.0, lmbda=50.0, normalize=False, method="exact", max_iterations=20, tolerance=0)
    lr = cpd_nonrigid(X, Y, beta=2.0, lmbda=50.0, normalize=False, method="lowrank", max_iterations=20, tolerance=0)
    assert lr.iterations == ex.iterations == 20
    assert np.abs(lr.TY - ex.TY).max() < 1e-3 * np.ptp(X)
    assert np.abs(lr.warp(Y) - lr.TY).max() < 1e-8
    # Jacobian of the warp against central differences, at points that are not template points
    rng = np.random.default_rng(0)
    P = rng.normal(size=(6, 3)) * 0.3
    for res in (ex, lr):
        J = res.warp.jacobian(P)
        h = 1e-6
        Jn = np.stack([(res.warp(P + h * e) - res.warp(P - h * e)) / (2 * h) for e in np.eye(3)], -1)
        assert np.abs(J - Jn).max() < 1e-6


def test_fast_large_cloud_reduces_residual():
    rng = np.random.default_rng(2)
    u = rng.uniform(-1, 1, size=(8000, 2))
    Y = np.c_[u, 0.2 * np.sin(2 * u[:, 0])]
    X = np.c_[u * 1.1, 0.2 * np.sin(2 * u[:, 0] + 0.5) + 0.1 * u[:, 1] ** 2] + 0.002 * rng.normal(size=(8000, 3))
    X = X[rng.permutation(8000)[:7000]]
    res = cpd_nonrigid(X, Y, beta=2.0, lmbda=3.0, method="fast", max_points=800)
    assert res.TY.shape == Y.shape
    assert mean_nn_residual(res.TY, X) < 0.5 * mean_nn_residual(Y, X)


def test_identical_clouds_sigma2_collapse_is_clean():
    rng = np.random.default_rng(3)
    Y = rng.normal(size=(50, 3))
    for kind in ("rigid", "affine", "nonrigid"):
        r = register(Y.copy(), Y, kind, max_iterations=200, tolerance=1e-12)
        assert np.all(np.isfinite(r.TY))
        assert np.abs(r.TY - Y).max() < 1e-4


def test_bad_input_errors():
    Y = np.zeros((5, 3))
    with pytest.raises(InvalidInput, match="empty"):
        cpd_nonrigid(np.zeros((0, 3)), np.ones((4, 3)))
    with pytest.raises(ShapeError):
        cpd_nonrigid(np.ones((4, 2)), np.ones((4, 3)))
    with pytest.raises(InvalidInput, match="degenerate"):
        cpd_nonrigid(np.random.default_rng(0).normal(size=(10, 3)), Y)
    with pytest.raises(InvalidInput, match="NaN"):
        cpd_rigid(np.full((4, 3), np.nan), np.ones((4, 3)))
    with pytest.raises(InvalidInput):
        cpd_nonrigid(np.eye(3), np.eye(3) * 2, w=1.0)
    with pytest.raises(InvalidInput):
        cpd_nonrigid(np.eye(3), np.eye(3) * 2, beta=0.0)
    with pytest.raises(InvalidInput):
        register(np.eye(3), np.eye(3), "projective")


def test_farthest_point_sample_spreads():
    P = np.random.default_rng(0).uniform(size=(500, 3))
    idx = farthest_point_sample(P, 20)
    assert len(set(idx.tolist())) == 20


_ESTEP_DIGEST = """
import hashlib, numpy as np, numba
from robointel.learning.grasp.cpd_estep import _FastEstep
rng = np.random.default_rng(0)
X, Y = rng.normal(size=(3000, 3)), rng.normal(size=(400, 3))
digests = []
for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
    numba.set_num_threads(threads)
    out = _FastEstep(X, 400)(Y, 0.3, 0.1)
    digests.append(hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in out[:3])).hexdigest())
print(" ".join(digests))
"""


def test_fast_estep_same_bits_compiled_or_cached_on_any_thread_count(tmp_path):
    """The fused E-step gives the same bits whether numba just compiled it or loaded it from its cache,
    and on 1 or 2 threads: a grasp trial is a function of its spec, not of the process's history."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path),
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[3] / "src"),
                                          os.environ.get("PYTHONPATH", "")])}
    runs = [subprocess.run([sys.executable, "-c", _ESTEP_DIGEST], env=env, capture_output=True, text=True,
                           timeout=600) for _ in range(2)]  # the first compiles into tmp_path, the second loads
    assert all(r.returncode == 0 for r in runs), [r.stderr[-2000:] for r in runs]
    assert any(tmp_path.rglob("*.nbc"))  # the second run had a cache to load
    fresh, cached = (r.stdout.split() for r in runs)
    assert len(fresh) == 2 and fresh[0] == fresh[1]  # 1 and 2 threads
    assert cached == fresh
