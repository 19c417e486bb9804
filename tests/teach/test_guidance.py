"""Guidance with collision avoidance (Ch. 4): QP (4.11), equality (4.10), baselines (4.1)-(4.3),
blend (4.12)-(4.13), faults and singularities. Kinematic closed loops (no physics) here; the
MuJoCo scenarios are in test_guidance_scenarios.py."""
import numpy as np
import pytest
from scipy.optimize import minimize

from robointel.errors import InvalidInput, SafetyStop, ShapeError
from robointel.geometry import Cylinder, Sphere
from robointel.geometry.distance import sphere_distances
from robointel.teach.guidance import METHODS, GuidanceConfig, GuidanceController, blend_weight, repulsive_speed
from robointel.teach.scenarios import table_4_1_obstacles

Q0 = np.array([0.0, 0.3, -0.3, 0.0, -1.2, 0.0])


def test_blend_weight_corrected_4_13():
    assert blend_weight(0.0) == pytest.approx(1.0)
    assert blend_weight(0.15) == pytest.approx((1 + np.exp(-6)) / (1 + np.exp(6)))
    assert blend_weight(0.15) < 2 * np.exp(-6)
    d = np.linspace(-0.05, 0.5, 200)
    lam = blend_weight(d)
    assert np.all(np.diff(lam) <= 1e-15) and lam.max() <= 1 and lam.min() >= 0
    assert repulsive_speed(0.0, v_max=0.3) == pytest.approx(0.3 / (1 + np.exp(-6)))


def test_free_guidance_follows_the_lead(lrmate):
    ctl = GuidanceController(lrmate, [], GuidanceConfig(filter_hz=0))
    f = np.array([4.0, -2.0, 1.5])
    s = ctl.step(Q0, np.r_[f, 0.0, 0.0, 0.0])
    V = s.v_lead
    nf = np.linalg.norm(f)
    np.testing.assert_allclose(V[:3], 0.07 * (nf - 1.0) * f / nf)  # (3.11) with the 1 N deadband
    big = ctl.step(Q0, [40.0, 0, 0, 0, 0, 0])  # saturated at max_speed
    assert np.linalg.norm(big.v_lead[:3]) == pytest.approx(0.5)
    np.testing.assert_allclose(s.v_cmd, V, atol=1e-4)
    assert s.status == "ok" and not s.held and s.distance == np.inf


def _random_scene(rng, robot, q, k):
    """k obstacles (spheres and cylinders) placed 1-10 cm from random robot spheres."""
    from robointel.geometry.distance import sphere_distances as sdist

    C, _ = robot.spheres.kinematics(q)
    mov = np.flatnonzero(robot.spheres.movable)
    obs = []
    for _ in range(k):
        i = rng.choice(mov)
        u = rng.normal(size=3); u /= np.linalg.norm(u)
        gap = rng.uniform(0.01, 0.10)
        if rng.random() < 0.5:
            r = rng.uniform(0.02, 0.08)
            obs.append(Sphere(C[i] + u * (robot.spheres.radii[i] + r + gap), r))
        else:
            r = 0.035
            c = C[i] + u * (robot.spheres.radii[i] + r + gap)
            a = np.cross(u, rng.normal(size=3)); a /= np.linalg.norm(a)
            obs.append(Cylinder(c - 0.3 * a, c + 0.3 * a, r))
    if np.min(sdist(robot, q, obs).d) <= 0:
        return None
    return obs


@pytest.mark.parametrize("seed", range(6))
def test_qp_always_feasible_zero_satisfies_and_optimal(lrmate, seed):
    """(4.11) is feasible at every state (dq = 0 satisfies every row and bound) and DAQP's
    answer is the optimum (checked against SLSQP) with several simultaneous obstacles."""
    rng = np.random.default_rng(seed)
    checked = 0
    while checked < 4:
        q = lrmate.random_configuration(rng)
        obs = _random_scene(rng, lrmate, q, k=int(rng.integers(2, 5)))
        if obs is None:
            continue
        ctl = GuidanceController(lrmate, obs, GuidanceConfig(filter_hz=0, d0=0.3))
        w = np.r_[rng.normal(0, 30, 3), rng.normal(0, 1, 3)]
        s = ctl.step(q, w)
        assert not s.held and np.all(np.isfinite(s.qd))
        if ctl.last_qp is None or s.active < 2:
            continue
        H, f, A, lb, ub, x = ctl.last_qp
        assert A.shape[0] == s.active >= 2  # one row per active obstacle
        # zero is feasible: all rows 0 >= 0 and lb <= 0 <= ub
        assert np.all(lb <= 0) and np.all(ub >= 0)
        # the solution is feasible and optimal
        assert np.all(A @ x >= -1e-7)
        assert np.all(x >= lb - 1e-9) and np.all(x <= ub + 1e-9)
        ref = minimize(lambda z: 0.5 * z @ H @ z + f @ z, np.zeros(len(x)), jac=lambda z: H @ z + f,
                       constraints=[{"type": "ineq", "fun": lambda z: A @ z, "jac": lambda z: A}],
                       bounds=list(zip(lb, ub)), method="SLSQP", options={"ftol": 1e-14, "maxiter": 500})
        obj = lambda z: 0.5 * z @ H @ z + f @ z  # noqa: E731
        assert obj(x) <= obj(ref.x) + 1e-9
        checked += 1


def test_qp_feasible_even_in_penetration(lrmate):
    """Inside an obstacle (d < 0) the rows are still u^T J dq >= 0: zero stays feasible."""
    C, _ = lrmate.spheres.kinematics(Q0)
    i = np.flatnonzero(lrmate.spheres.movable)[-3]
    obs = [Sphere(C[i] + [0.0, 0.0, 0.05], 0.05), Sphere(C[i] + [0.0, 0.06, 0.0], 0.05)]
    ctl = GuidanceController(lrmate, obs, GuidanceConfig(filter_hz=0))
    s = ctl.step(Q0, [0.0, 0.0, 40.0, 0.0, 0.0, 0.0])
    assert s.distance < 0 and s.active == 2 and not s.held
    H, f, A, lb, ub, x = ctl.last_qp
    assert np.all(A @ x >= -1e-7)


def _push(lrmate, obs, method, force, q0, steps=2500, **cfg):
    ctl = GuidanceController(lrmate, obs, GuidanceConfig(method=method, filter_hz=0, **cfg))
    q = q0.copy()
    dmin, dev = np.inf, []
    for _ in range(steps):
        s = ctl.step(q, force)
        q = q + s.qd * 1e-3
        dmin = min(dmin, float(np.min(sphere_distances(lrmate, q, obs, movable_only=True).d)))
        dev.append(s.deviation)
    return dmin, float(np.mean(dev)), q


def test_operator_cannot_push_into_obstacle(lrmate):
    """Pushing straight down onto an obstacle under the wrist with 40 N (far beyond the speed
    limit): the QP command stops the robot short of it and keeps it out."""
    T = lrmate.fk(Q0)
    obs = [Cylinder(T[:3, 3] + [0.0, -0.4, -0.15], T[:3, 3] + [0.0, 0.4, -0.15], 0.035)]
    dmin, _, q = _push(lrmate, obs, "qp", np.array([0, 0, -40.0, 0, 0, 0]), Q0)
    assert dmin > 0.0
    # the free controller would have hit it within 0.3 s
    ctl = GuidanceController(lrmate, [], GuidanceConfig(filter_hz=0))
    qq, dfree = Q0.copy(), np.inf
    for _ in range(300):
        qq = qq + ctl.step(qq, [0, 0, -40.0, 0, 0, 0]).qd * 1e-3
        dfree = min(dfree, float(np.min(sphere_distances(lrmate, qq, obs, movable_only=True).d)))
    assert dfree < 0


def test_several_obstacles_at_once(lrmate):
    """Two bars either side of the wrist and the operator pushing diagonally into both."""
    T = lrmate.fk(Q0)
    p = T[:3, 3]
    obs = [Cylinder(p + [-0.4, 0.0, -0.23], p + [0.4, 0.0, -0.23], 0.035),
           Cylinder(p + [0.0, -0.4, 0.25], p + [0.0, 0.4, 0.25], 0.035),
           Sphere(p + [0.18, 0.0, 0.0], 0.04)]
    for f in ([0, 0, -40.0], [20.0, 0, 30.0], [30.0, 0, -30.0]):
        dmin, _, _ = _push(lrmate, obs, "qp", np.r_[f, 0, 0, 0], Q0, steps=1500)
        assert dmin > 0.0


@pytest.mark.parametrize("method", METHODS)
def test_methods_run_and_stay_bounded(lrmate, method):
    obs = list(table_4_1_obstacles().values())
    ctl = GuidanceController(lrmate, obs, GuidanceConfig(method=method, filter_hz=0))
    rng = np.random.default_rng(3)
    for _ in range(50):
        q = lrmate.random_configuration(rng)
        s = ctl.step(q, rng.normal(0, 20, 6))
        assert np.all(np.isfinite(s.qd))
        assert np.all(np.abs(s.qd) <= lrmate.velocity_limit * (1 + 1e-9))


def test_equality_keeps_closest_point_distance(lrmate):
    """(4.10): with lambda ~ 1 the closest point neither approaches nor leaves."""
    T = lrmate.fk(Q0)
    obs = [Sphere(T[:3, 3] + [0.0, 0.0, -0.09], 0.03)]
    ctl = GuidanceController(lrmate, obs, GuidanceConfig(method="equality", filter_hz=0))
    ctl.step(Q0, [0, 5.0, -20.0, 0, 0, 0])
    H, f, A, lb, ub, x = ctl.last_qp
    np.testing.assert_allclose(A @ x, 0.0, atol=1e-8)


def test_qp_deviates_less_than_repulsive(lrmate):
    T = lrmate.fk(Q0)
    obs = [Cylinder(T[:3, 3] + [0.0, -0.4, -0.15], T[:3, 3] + [0.0, 0.4, -0.15], 0.035)]
    force = np.array([15.0, 0.0, -5.0, 0, 0, 0])
    d_qp, dev_qp, _ = _push(lrmate, obs, "qp", force, Q0, steps=1500)
    d_rep, dev_rep, _ = _push(lrmate, obs, "repulsive", force, Q0, steps=1500)
    assert d_qp > 0
    assert dev_qp < dev_rep


# ------------------------------------------------------------------ faults and singularities
def test_nan_reading_holds_and_says_why(lrmate):
    ctl = GuidanceController(lrmate, table_4_1_obstacles().values(), GuidanceConfig(recover_samples=5))
    ok = ctl.step(Q0, [5.0, 0, 0, 0, 0, 0])
    assert not ok.held
    s = ctl.step(Q0, [np.nan, 0, 0, 0, 0, 0])
    assert s.held and np.all(s.qd == 0) and "NaN" in s.status
    for _ in range(5):
        s = ctl.step(Q0, [5.0, 0, 0, 0, 0, 0])
        assert s.held and "recovering" in s.status
    s = ctl.step(Q0, [5.0, 0, 0, 0, 0, 0])
    assert not s.held


def test_spike_and_out_of_range_hold(lrmate):
    ctl = GuidanceController(lrmate, [], GuidanceConfig(recover_samples=3))
    ctl.step(Q0, [5.0, 0, 0, 0, 0, 0])
    s = ctl.step(Q0, [5.0, 0, 90.0, 0, 0, 0])  # 90 N jump in 1 ms
    assert s.held and "spike" in s.status and np.all(s.qd == 0)
    ctl.reset()
    s = ctl.step(Q0, [500.0, 0, 0, 0, 0, 0])
    assert s.held and "range" in s.status
    s = ctl.step(Q0, [0.0, 0, 0, 0, 0, np.inf])
    assert s.held


def test_raise_on_fault(lrmate):
    ctl = GuidanceController(lrmate, [], GuidanceConfig(raise_on_fault=True))
    with pytest.raises(SafetyStop, match="NaN"):
        ctl.step(Q0, [np.nan] * 6)
    with pytest.raises(SafetyStop):
        ctl.step([np.nan] * 6, [0.0] * 6)


def test_bad_shapes_and_config(lrmate):
    ctl = GuidanceController(lrmate, [])
    with pytest.raises(ShapeError):
        ctl.step(Q0[:5], np.zeros(6))
    with pytest.raises(ShapeError):
        ctl.step(Q0, np.zeros(3))
    with pytest.raises(InvalidInput):
        GuidanceConfig(method="magic")
    with pytest.raises(InvalidInput):
        GuidanceConfig(d0=-1)
    with pytest.raises(InvalidInput):
        GuidanceController(lrmate, ["not an obstacle"])


@pytest.mark.parametrize("joint,value", [(4, 0.0), (2, np.arctan2(0.035, 0.42) * -1.0)])
def test_command_bounded_near_singularities(lrmate, joint, value):
    """Wrist (J5 = 0) and elbow (arm stretched) singularities: damped, finite, bounded."""
    q = Q0.copy()
    q[joint] = value
    ctl = GuidanceController(lrmate, [], GuidanceConfig(filter_hz=0, velocity_scale=100.0))
    c = ctl.config
    for w in ([0, 0, 0, 5.0, 0, 0], [0, 0, 0, 0, 0, 5.0], [30.0, 0, 0, 0, 0, 0], [0, 30.0, 30.0, 0, 0, 0]):
        s = ctl.step(q, w)
        ctl.reset()
        assert np.all(np.isfinite(s.qd))
        # ||dq|| <= ||W^1/2 V|| / (2 lambda)
        Vw = np.sqrt(np.r_[1, 1, 1, [c.rot_weight] * 3]) * s.v_lead
        assert np.linalg.norm(s.qd) <= np.linalg.norm(Vw) / (2 * np.sqrt(c.singular_damping ** 2 * 0.99)) + 1e-6


def test_resume_after_fault_ramps_up(lrmate):
    """After a hold the filtered lead restarts from rest: no velocity step when motion resumes."""
    ctl = GuidanceController(lrmate, [], GuidanceConfig(recover_samples=3, filter_hz=4.0))
    w = np.array([10.0, 0, 0, 0, 0, 0])
    for _ in range(2000):
        steady = ctl.step(Q0, w)
    ctl.step(Q0, [np.nan] * 6)
    out = [ctl.step(Q0, w) for _ in range(10)]
    first = next(s for s in out if not s.held)
    assert np.linalg.norm(first.qd) < 0.05 * np.linalg.norm(steady.qd)
    speeds = [np.linalg.norm(s.qd) for s in out]
    assert np.all(np.diff(speeds) >= -1e-12)


def test_solver_failure_holds(lrmate, monkeypatch):
    """If DAQP ever reports no optimum, the command is zero and the status says why."""
    import robointel.teach.guidance as G

    T = lrmate.fk(Q0)
    obs = [Sphere(T[:3, 3] + [0.0, 0.0, -0.12], 0.03)]
    ctl = GuidanceController(lrmate, obs, GuidanceConfig(filter_hz=0))
    monkeypatch.setattr(G.daqp, "solve", lambda *a, **k: (np.full(6, np.nan), 0.0, -3, {}))
    s = ctl.step(Q0, [0, 0, -30.0, 0, 0, 0])
    assert s.held and np.all(s.qd == 0) and "solver" in s.status
