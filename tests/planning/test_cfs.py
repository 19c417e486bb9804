"""The general CFS solver (Algorithm 2) on small problems, against SLSQP."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InfeasibleProblem, InvalidInput
from robointel.planning.cfs import NonlinearConstraint, cfs
from robointel.planning.qp import DenseQP, SparseQP
from robointel.planning.sqp import slsqp


def outside_disk(c, r):
    """phi convex: complement of Gamma (the disk) is convex, case (7.5)."""
    c = np.asarray(c, float)
    return NonlinearConstraint(lambda z: np.array([np.sum((z - c) ** 2) - r ** 2]),
                               lambda z: (2 * (z - c))[None], kind="complement_convex")


def inside_disk(c, r):
    """phi concave: Gamma convex, case 1."""
    c = np.asarray(c, float)
    return NonlinearConstraint(lambda z: np.array([r ** 2 - np.sum((z - c) ** 2)]),
                               lambda z: (-2 * (z - c))[None], kind="convex")


def above_sine():
    """phi = z1 - sin(z0): neither convex nor concave; Hessian diag(sin z0, 0) >= -I, case (7.6)."""
    return NonlinearConstraint(lambda z: np.array([z[1] - np.sin(z[0])]),
                               lambda z: np.array([[-np.cos(z[0]), 1.0]]), kind="general", hess_lb=-1.0)


def goal_cost(goal):
    goal = np.asarray(goal, float)
    return 2 * np.eye(goal.size), -2 * goal  # ||z - goal||^2 up to a constant


CASES = {
    "complement_convex": ([outside_disk([0, 0], 1.0)], [0.3, 0.1], [1.5, 1.2]),
    "convex": ([inside_disk([0, 0], 1.0)], [2.0, 1.0], [0.0, 0.2]),
    "general": ([above_sine()], [1.2, -0.5], [-2.0, 1.5]),
    "two_obstacles": ([outside_disk([0, 0], 1.0), outside_disk([1.6, 0.3], 0.5)], [0.9, 0.2], [1.2, 1.5]),
}


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_cfs_agrees_with_slsqp_and_iterates_feasible(case, solver):
    cons, goal, z0 = CASES[case]
    H, f = goal_cost(goal)
    z0 = np.array(z0)
    assert all(np.all(c.fun(z0) >= 0) for c in cons)
    qp = DenseQP() if solver == "daqp" else SparseQP(eps_abs=1e-9, eps_rel=1e-9)
    res = cfs(H, f, constraints=cons, z0=z0, eps=1e-8, max_iter=200, keep_iterates=True, qp=qp)
    ref = slsqp(H, f, constraints=cons, z0=z0, tol=1e-10)  # 1e-12 can end in a line-search stall at the optimum
    assert res.status == "converged" and res.feasible
    # SciPy >= 1.16's SLSQP may stop with "Positive directional derivative for linesearch" at the optimum:
    # the peer is judged by its feasibility and the point it returns, not by that flag alone
    assert ref.success or ("linesearch" in ref.message and ref.max_violation < 1e-7)
    np.testing.assert_allclose(res.z, ref.z, atol=1e-4)
    # every iterate is feasible and the cost never increases (feasible reference)
    for z in res.iterates:
        for c in cons:
            assert np.all(c.fun(z) >= -1e-9)
    assert np.all(np.diff(res.costs) <= 1e-9)
    assert len(res.costs) == res.iterations + 1


def test_complement_convex_projects_goal_onto_obstacle():
    cons, goal, z0 = CASES["complement_convex"]
    H, f = goal_cost(goal)
    res = cfs(H, f, constraints=cons, z0=np.array(z0), eps=1e-8)
    assert res.converged and res.iterations < 100
    np.testing.assert_allclose(np.linalg.norm(res.z), 1.0, atol=1e-6)  # on the circle, toward the goal
    np.testing.assert_allclose(res.z / np.linalg.norm(res.z), np.array(goal) / np.linalg.norm(goal), atol=1e-4)


def test_linear_constraints_and_capped_iterations_return_best_feasible():
    cons, goal, z0 = CASES["general"]
    H, f = goal_cost(goal)
    A = np.array([[1.0, 0.0]])
    res = cfs(H, f, constraints=cons, A=A, l=[-1.0], u=[np.inf], z0=np.array([-0.5, 1.5]), max_iter=2)
    assert res.status == "max_iter"
    assert res.feasible and res.z[0] >= -1.0 - 1e-6
    assert res.costs[0] >= min(res.costs)  # best iterate never worse than the start
    full = cfs(H, f, constraints=cons, A=A, l=[-1.0], u=[np.inf], z0=np.array([-0.5, 1.5]), eps=1e-9, max_iter=300)
    ref = slsqp(H, f, constraints=cons, A=A, l=[-1.0], u=[np.inf], z0=np.array([-0.5, 1.5]), tol=1e-12)
    assert full.converged
    np.testing.assert_allclose(full.z, ref.z, atol=1e-4)


def test_infeasible_start_still_reaches_feasibility():
    cons = [outside_disk([0, 0], 1.0)]
    H, f = goal_cost([0.2, 0.0])
    res = cfs(H, f, constraints=cons, z0=np.array([0.5, 0.1]), eps=1e-9)
    assert res.feasible
    np.testing.assert_allclose(res.z, [1.0, 0.0], atol=1e-5)


def test_bad_input():
    H, f = goal_cost([0, 0])
    with pytest.raises(InvalidInput):
        cfs(H, [np.nan, 0.0])
    with pytest.raises(InvalidInput):
        cfs(H, f, z0=[0.0, np.inf])
    with pytest.raises(InfeasibleProblem):
        cfs(H, f, A=np.eye(2), l=[1.0, 0.0], u=[0.0, 1.0])
    with pytest.raises(InfeasibleProblem):  # contradictory rows: z0 >= 1 and z0 <= 0
        cfs(H, f, A=np.array([[1.0, 0.0], [1.0, 0.0]]), l=[1.0, -np.inf], u=[np.inf, 0.0])
    with pytest.raises(InvalidInput):
        NonlinearConstraint(lambda z: z, lambda z: np.eye(2), kind="general")


def test_ftol_stops_early_on_a_feasible_iterate():
    cons, goal, z0 = CASES["complement_convex"]
    H, f = goal_cost(goal)
    full = cfs(H, f, constraints=cons, z0=np.array(z0), eps=1e-10, max_iter=200)
    quick = cfs(H, f, constraints=cons, z0=np.array(z0), eps=1e-10, max_iter=200, ftol=1e-3)
    assert quick.converged and quick.feasible and quick.iterations < full.iterations
    assert quick.costs[-1] <= quick.costs[0]


def test_a_dense_qp_solved_through_the_cholesky_factor_is_the_same_qp():
    from robointel.planning.qp import cholesky_factor

    rng = np.random.default_rng(5)
    n, m = 30, 45
    B = rng.normal(size=(n, n))
    P = B @ B.T + np.eye(n)
    q, A = rng.normal(size=n), rng.normal(size=(m, n))
    l, u = np.full(m, -1e20), rng.uniform(0.1, 1.0, m)
    u[:10] = -0.2  # some rows active at the solution
    plain = DenseQP().solve(P, q, A, l, u, full_P=True)
    fac = DenseQP().solve(P, q, A, l, u, full_P=True, factor=cholesky_factor(P))
    assert plain.solved and fac.solved
    np.testing.assert_allclose(fac.x, plain.x, atol=1e-9)
    np.testing.assert_allclose(fac.y, plain.y, atol=1e-9)
    assert np.any(np.abs(plain.y) > 1e-6)
    assert cholesky_factor(-np.eye(3)) is None  # not positive definite: no factor
