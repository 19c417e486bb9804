"""The exact mesh clearance: exact below the threshold, a lower bound above it, over every pair; the levers bound."""
from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from robointel.io.mbm import load_mbm_problems
from robointel.planning.exact_geometry import MeshGeometry, contact_distance
from robointel.planning.part_spheres import LEAVES, mesh_triangles, triangle_spheres
from robointel.robot import Robot


def _every_pair(mg: MeshGeometry, q: np.ndarray, cap: float) -> float:
    """The exact mesh distance (negative in contact) minimised over every (part, obstacle) pair, capped."""
    robot = mg.robot
    pin.framesForwardKinematics(robot.model, robot.data, q)
    best = cap
    req = coal.DistanceRequest()
    for part in mg.parts:
        T = robot.data.oMf[part.frame].homogeneous @ part.placement
        Tp = coal.Transform3s(T[:3, :3], T[:3, 3])
        for _, g, To in mg.obstacles:
            best = min(best, contact_distance(part.mesh, Tp, g, To, req))
    return best


def test_clearance_is_exact_below_the_threshold_and_a_lower_bound_above(shared_data):
    root = shared_data("mbm", "ur5")
    pset = load_mbm_problems(root / "problems.json")
    robot = Robot.load(root / "ur5.urdf")
    rng = np.random.default_rng(2)
    near = below = 0
    for fam in ("bookshelf_thin", "table_under_pick", "cage"):
        p = pset.select(families=[fam])[0]
        mg = MeshGeometry(robot, p.obstacles)
        for q in np.asarray(p.goals[0], float) + rng.normal(0.0, 0.05, (8, 6)):
            ref = _every_pair(mg, q, 0.101)
            for thresh in (0.0, 0.02):
                d, link, obs = mg.clearance(q, cap=0.101, thresh=thresh)
                if ref < thresh:  # the verdict and the distance itself
                    assert abs(d - ref) <= 1e-9
                    below += 1
                else:  # a lower bound that keeps the verdict
                    assert thresh <= d <= ref + 1e-9
                assert (link != "") == (d < 0.101)
                near += d < 0.101
    assert near >= 8 and below >= 2
    assert mg.pair_distances(q, np.zeros(0, np.int64), thresh=0.0).shape == (0,)  # no pair asked: none measured


def test_mesh_levers_bound_every_vertex_displacement(shared_data):
    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    mg = MeshGeometry(robot, [])
    rng = np.random.default_rng(0)

    ids = [i for i, p in enumerate(mg.parts) if hasattr(p.mesh, "vertices")]  # meshes (primitives have no vertices)
    parts = [mg.parts[i] for i in ids]

    def placements(q: np.ndarray) -> list[np.ndarray]:
        pin.framesForwardKinematics(robot.model, robot.data, q)
        return [robot.data.oMf[p.frame].homogeneous @ p.placement for p in parts]

    verts = [np.asarray(p.mesh.vertices()) for p in parts]
    worst = 0.0
    for _ in range(60):
        q0 = robot.random_configuration(rng)
        dq = rng.normal(0.0, 0.05, robot.nq)
        for i, v, a, b in zip(ids, verts, placements(q0), placements(q0 + dq)):
            moved = np.linalg.norm(v @ (a[:3, :3] - b[:3, :3]).T + (a[:3, 3] - b[:3, 3]), axis=1).max()
            worst = max(worst, moved / float(mg.part_lever[i] @ np.abs(dq)))
    assert 0.3 < worst <= 1.0  # each part's own bound, and not a vacuous one


def test_compiled_frame_placements_are_pinocchios(shared_data):
    from robointel.geometry import Box

    r = Robot.load(shared_data("mbm", "fetch", "fetch.urdf"))  # a prismatic torso below the arm
    mg = MeshGeometry(r, [Box(center=np.array([0.8, 0.0, 0.5]), size=np.array([0.2, 0.2, 0.2]))])
    rng = np.random.default_rng(2)
    for _ in range(20):
        q = rng.uniform(np.maximum(r.lower, -3.0), np.minimum(r.upper, 3.0))
        pin.framesForwardKinematics(r.model, r.data, q)
        want = np.array([r.data.oMf[f].homogeneous for f in mg._frames])
        np.testing.assert_allclose(mg._frame_placements(q), want, rtol=0, atol=1e-12)


def test_pair_clear_is_a_proof_and_refutes_only_below_its_margin(shared_data):
    """A pair said clear at a margin is at least that far apart on the meshes; one refused is closer than it."""
    root = shared_data("mbm", "ur5")
    pset = load_mbm_problems(root / "problems.json")
    robot = Robot.load(root / "ur5.urdf")
    rng = np.random.default_rng(5)
    req = coal.DistanceRequest()
    said = {True: 0, False: 0}
    for fam in ("bookshelf_small", "table_pick"):
        p = pset.select(families=[fam])[1]
        mg = MeshGeometry(robot, p.obstacles)
        nobs = len(mg.obstacles)
        for q in np.asarray(p.goals[0], float) + rng.normal(0.0, 0.04, (6, 6)):
            Tl = mg.link_placements(q)
            pin.framesForwardKinematics(robot.model, robot.data, q)
            for i in range(len(mg.pair_lever)):
                part, (_, g, To) = mg.parts[i // nobs], mg.obstacles[i % nobs]
                T = robot.data.oMf[part.frame].homogeneous @ part.placement
                exact = contact_distance(part.mesh, coal.Transform3s(T[:3, :3], T[:3, 3]), g, To, req)
                if exact > 0.05:
                    continue
                for margin in (0.0, 0.002, 0.01, 0.03):
                    ok = mg.pair_clear(Tl, i, margin)
                    assert (exact >= margin - 1e-6) if ok else (exact < margin + 1e-6), (i, margin, exact)
                    said[ok] += 1
    assert said[True] >= 10 and said[False] >= 10  # both answers seen


def test_cell_spheres_hold_every_triangle_of_a_mesh(shared_data):
    """Each mesh part's cell spheres: every triangle lies whole in one of them (its three vertices do)."""
    root = shared_data("mbm", "ur5")
    mg = MeshGeometry(Robot.load(root / "ur5.urdf"), [])
    part = max(mg.parts, key=lambda p: getattr(p.mesh, "num_tris", 0))
    V, F = mesh_triangles(part.mesh)
    C, R = triangle_spheres(V, F)
    assert len(F) > 1000 and 1 < len(R) <= LEAVES
    inside = np.linalg.norm(V[F][:, :, None, :] - C[None, None], axis=3) <= R[None, None]  # (T, 3, k)
    assert inside.all(axis=1).any(axis=1).all()
    assert triangle_spheres(V, F[:0])[1].shape == (0,)


def test_part_bounds_never_exceed_the_mesh_distance(shared_data):
    """The compiled broad phase (bounding and cell spheres to each primitive) is a lower bound of coal's distance."""
    from robointel.geometry.obstacles import Box, Capsule, Cylinder, Sphere

    root = shared_data("mbm", "ur5")
    robot = Robot.load(root / "ur5.urdf")
    rng = np.random.default_rng(11)
    q0 = np.array([0.0, -1.2, 1.4, -1.8, -1.57, 0.0])
    pin.framesForwardKinematics(robot.model, robot.data, q0)
    tip = robot.data.oMf[robot.model.getFrameId(robot.link_names[-1])].translation
    R = pin.rpy.rpyToMatrix(0.3, -0.5, 0.9)
    obstacles = [Box(center=tip + [0.12, 0.0, 0.0], size=np.array([0.05, 0.3, 0.2]), rotation=R),
                 Cylinder(a=tip + [-0.1, 0.1, -0.2], b=tip + [-0.1, 0.1, 0.2], radius=0.03),
                 Capsule(a=tip + [0.0, -0.15, -0.1], b=tip + [0.1, -0.15, 0.1], radius=0.02),
                 Sphere(center=tip + [0.0, 0.0, 0.15], radius=0.04)]
    mg = MeshGeometry(robot, obstacles)
    req = coal.DistanceRequest()
    nobs = len(mg.obstacles)
    pp, oo = np.divmod(np.arange(len(mg.parts) * nobs), nobs)
    near = 0
    for q in q0 + rng.normal(0.0, 0.15, (12, 6)):
        Tl = mg.link_placements(q)
        bound = np.empty(len(pp))
        mg._bounds(Tl, pp, oo, bound)
        pin.framesForwardKinematics(robot.model, robot.data, q)
        for n, (p, o) in enumerate(zip(pp, oo)):
            part, (_, g, To) = mg.parts[p], mg.obstacles[o]
            T = robot.data.oMf[part.frame].homogeneous @ part.placement
            exact = contact_distance(part.mesh, coal.Transform3s(T[:3, :3], T[:3, 3]), g, To, req)
            assert bound[n] <= exact + 1e-7, (p, o, bound[n], exact)
            near += exact < 0.05 and bound[n] > exact - 0.03
    assert near >= 10  # and close to it where it matters
