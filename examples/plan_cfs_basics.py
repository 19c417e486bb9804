"""The general CFS solver (Algorithm 2) on a 2-D problem, beside SLSQP.

    python examples/plan_cfs_basics.py

Get as close as possible to a goal inside a disk, next to another disk:
phi_i(z) = ||z - c_i||^2 - r_i^2 >= 0 is convex, so its
complement (the disk) is convex: CFS case (7.5), a half space per disk at every iterate.
"""
import numpy as np

from robointel.planning import NonlinearConstraint, cfs, slsqp


def outside(c, r):
    c = np.asarray(c, float)
    return NonlinearConstraint(lambda z: np.array([np.sum((z - c) ** 2) - r ** 2]),
                               lambda z: (2 * (z - c))[None], kind="complement_convex", name=f"disk {c}")


goal = np.array([0.9, 0.2])  # inside the first disk: the optimum lies on its boundary
H, f = 2 * np.eye(2), -2 * goal  # J(z) = ||z - goal||^2 (+ const)
cons = [outside([0.0, 0.0], 1.0), outside([1.6, 0.3], 0.5)]
z0 = np.array([1.2, 1.5])  # a feasible start
ours = cfs(H, f, constraints=cons, z0=z0, eps=1e-8, keep_iterates=True)
peer = slsqp(H, f, constraints=cons, z0=z0, tol=1e-12)
print(f"CFS   z = {ours.z.round(5)}  {ours.iterations} iterations, {ours.seconds * 1e3:.2f} ms, status {ours.status}")
print(f"SLSQP z = {peer.z.round(5)}  {peer.iterations} iterations, {peer.seconds * 1e3:.2f} ms")
print("every CFS iterate feasible:", all(min(c.fun(z)[0] for c in cons) >= -1e-9 for z in ours.iterates))
