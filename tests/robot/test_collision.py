"""Collision spheres (Fig. 4.2): coverage of the link geometry, editing, self-collision pairs."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.robot import SphereModel


def _sample_primitive(prim, rng, n=400):
    """Uniform samples inside a box/cylinder primitive, in the link frame."""
    kind, size, T = prim["type"], prim["size"], prim["origin"]
    if kind == "box":
        p = (rng.random((n, 3)) - 0.5) * size
    elif kind == "cylinder":
        r, L = size
        ang = rng.uniform(0, 2 * np.pi, n)
        rad = r * np.sqrt(rng.random(n))
        p = np.stack([rad * np.cos(ang), rad * np.sin(ang), (rng.random(n) - 0.5) * L], 1)
    else:
        pytest.skip(f"no sampler for {kind}")
    return p @ T[:3, :3].T + T[:3, 3]


@pytest.mark.parametrize("count", [None, 2, 5])
def test_spheres_cover_link_geometry(lrmate, count):
    model = SphereModel.from_robot(lrmate, count=count)
    rng = np.random.default_rng(0)
    for link, prims in lrmate.collision_primitives().items():
        idx = [i for i, l in enumerate(model.links) if l == link]
        for prim in prims:
            pts = _sample_primitive(prim, rng)
            d = np.linalg.norm(pts[:, None, :] - model.centers[idx][None], axis=2) - model.radii[idx][None]
            assert np.all(d.min(1) <= 1e-12), f"{link}: a point of its geometry is outside every sphere"


def test_inflate_and_count(lrmate):
    base = SphereModel.from_robot(lrmate)
    fat = SphereModel.from_robot(lrmate, inflate=0.01)
    assert np.allclose(fat.radii, base.radii + 0.01)
    n_prims = sum(len(p) for p in lrmate.collision_primitives().values())
    assert len(SphereModel.from_robot(lrmate, count=3)) == 3 * n_prims


def test_edit_and_round_trip(lrmate):
    m = SphereModel.from_robot(lrmate)
    n = len(m)
    m.add("link_6", [0.05, 0, 0], 0.04)
    assert len(m) == n + 1 and m.links[-1] == "link_6"
    P = m.positions(np.zeros(6))
    assert np.allclose(P[-1], lrmate.frame_pose(np.zeros(6), "link_6")[:3, 3] + [0.05, 0, 0])
    m2 = SphereModel.from_dict(m.to_dict(), lrmate)
    assert np.allclose(m2.centers, m.centers) and np.allclose(m2.radii, m.radii) and m2.links == m.links
    m.remove(n)
    assert len(m) == n
    with pytest.raises(InvalidInput):
        m.remove(999)
    with pytest.raises(InvalidInput):
        m.add("no_such_link", [0, 0, 0], 0.1)


def test_self_collision_pairs_exclude_adjacent_links(lrmate):
    m = lrmate.spheres
    parents = [int(p) for p in lrmate.model.parents]
    for i, k in m.self_pairs:
        a, b = m.joints[i], m.joints[k]
        assert a != b and parents[a] != b and parents[b] != a
    # at the zero pose no listed pair overlaps; folding the elbow fully back brings the
    # forearm into the upper arm / base
    assert m.self_distances(np.zeros(6)).min() > 0
    q = np.array([0, 0, 0, 0, 0, 0.0])
    q[2] = lrmate.upper[2]
    q[1] = lrmate.lower[1]
    assert m.self_distances(q).min() < 0


def test_movable_mask(lrmate):
    m = lrmate.spheres
    assert not m.movable[[i for i, l in enumerate(m.links) if l == "base_link"]].any()
    assert m.movable[[i for i, l in enumerate(m.links) if l == "link_1"]].all()
