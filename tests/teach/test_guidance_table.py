"""Guidance never drives the arm into the table: an operator pulling the handle down through the
table top is held at the guard (table, floor, self-collision checked before each command)."""
from __future__ import annotations

from robointel.teach import scenarios as S
from robointel.teach.collision_guard import CollisionGuard


def test_operator_pulling_into_the_table_is_held(monkeypatch, lrmate):
    # scenario III's pillar far away; the operator's hand goes 0.15 m below the table top (z = 0)
    monkeypatch.setitem(S._PATHS, 3, ([0.55, -0.20, 0.30], [0.60, -0.25, -0.15], [0.55, -0.2, 0.40]))
    res = S.run_scenario(3, "qp", physics=True, duration=4.5, identify=False)
    assert res.extra["guard_holds"] > 0 and "table" in res.extra["guard_reason"]
    assert "link_" in res.extra["guard_reason"]
    assert res.tcp[:, 2].min() > 0.0                      # the TCP never went under the table top
    CollisionGuard(lrmate).check_many(res.q[::10])        # no sphere ever in the table, floor or the arm itself
