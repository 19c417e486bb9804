"""Table 4.1 scenarios: obstacles, the simulated operator, a MuJoCo run with the F/T sensor in the
loop, the Fig. 4.6b plot, the ``robointel guide`` command and the demo stage."""
import json
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from robointel.errors import InvalidInput
from robointel.outcome import Failure
from robointel.teach.scenarios import (
    BASE_HEIGHT,
    SimulatedOperator,
    plot_scenario,
    run_scenario,
    scenario,
    table_4_1_obstacles,
)


def test_table_4_1_obstacles_in_root_frame():
    obs = table_4_1_obstacles()
    np.testing.assert_allclose(obs[1].a, [0.48, -0.5, 0.013 + BASE_HEIGHT])
    np.testing.assert_allclose(obs[2].b, [0.71, 0.5, 0.546 + BASE_HEIGHT])
    np.testing.assert_allclose(obs[3].a, [0.23, 0.43, 0.0], atol=1e-12)  # the pillar stands on the plane
    assert all(o.radius == pytest.approx(0.035) for o in obs.values())
    with pytest.raises(InvalidInput):
        scenario(4)


def test_operator_path_and_force_saturation():
    op = SimulatedOperator(np.array([[0.4, 0, 0.5], [0.6, 0, 0.5], [0.5, 0, 0.5]]), speed=0.1, dwell=0.5)
    T1 = op.legs[0].duration
    np.testing.assert_allclose(op.target(0.0), [0.4, 0, 0.5])
    np.testing.assert_allclose(op.target(T1 + 0.25), [0.6, 0, 0.5])
    np.testing.assert_allclose(op.target(op.duration), [0.5, 0, 0.5], atol=1e-12)
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.5]
    w = op.wrench(T1, T, np.zeros(3), np.eye(3))
    assert np.linalg.norm(w[:3]) == pytest.approx(op.max_force)


@pytest.mark.parametrize("s", [1, 2, 3])
def test_intended_path_would_hit_without_avoidance(lrmate, s):
    """Guided with no avoidance (free compliance), the operator drives the arm into the obstacle;
    with the QP the same operator never brings it closer than 0 (kinematic loop, until 1 s after
    the free arm hit)."""
    from robointel.geometry.distance import sphere_distances
    from robointel.teach.guidance import GuidanceController
    from robointel.teach.scenarios import _start_configuration

    sc = scenario(s)
    op = SimulatedOperator(sc.waypoints, speed=sc.speed, dwell=sc.dwell)
    ctl = GuidanceController(lrmate, [])
    q = _start_configuration(lrmate, sc.waypoints[0])
    R0 = lrmate.fk(q)[:3, :3]
    qd = np.zeros(6)
    t_hit = None
    for i in range(int(op.duration * 1000)):
        T = lrmate.fk(q)
        qd = ctl.step(q, op.wrench(i * 1e-3, T, ctl.tcp_jacobian(q)[:3] @ qd, R0)).qd
        q = q + qd * 1e-3
        if i % 10 == 0 and np.min(sphere_distances(lrmate, q, [sc.obstacle], movable_only=True).d) < 0:
            t_hit = i * 1e-3
            break
    assert t_hit is not None, f"scenario {s}: the free path should hit the obstacle"
    res = run_scenario(s, "qp", physics=False, robot=lrmate, duration=t_hit + 1.0)
    assert res.metrics()["max_penetration_m"] == 0.0 and np.nanmin(res.distance) > 0


def test_scenario_ii_in_mujoco_operator_cannot_push_in(tmp_path, lrmate):
    """The operator pushes up into the bar on purpose (30 N saturated hand): the arm stays off it
    on the MuJoCo collision geometry, no F/T fault, payload identified within 1%."""
    res = run_scenario(2, "qp", duration=4.0, robot=lrmate)
    m = res.metrics()
    assert m["max_penetration_m"] == 0.0 and m["robot_obstacle_contacts"] == 0
    assert 0.0 < m["min_distance_m"] < 0.15
    assert res.outcome.success and res.outcome.figures["min_distance_m"] == m["min_distance_m"]
    assert replace(res, contacts=3).outcome.reason is Failure.COLLISION
    assert m["held_steps"] == 0
    assert abs(res.extra["identified_mass"] - 0.6) / 0.6 < 0.01
    assert m["active_fraction"] > 0.3
    png = plot_scenario(res, tmp_path / "s2.png")
    assert png.stat().st_size > 10_000


def test_guide_command_writes_plot_and_json(tmp_path):
    from robointel.cli import app

    r = CliRunner().invoke(app, ["guide", "--scenario", "3", "--method", "repulsive", "--no-physics",
                                 "--duration", "0.5", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "guidance_s3_repulsive.png").exists()
    data = json.loads((tmp_path / "guidance_s3_repulsive.json").read_text())
    assert data["scenario"] == 3 and "mean_velocity_deviation" in data
    bad = CliRunner().invoke(app, ["guide", "--method", "magic", "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "method" in bad.output
    bad = CliRunner().invoke(app, ["guide", "--scenario", "7", "--no-physics", "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "scenario" in bad.output


def test_guidance_demo_stage_quick(tmp_path):
    from robointel.commands import guidance
    from robointel.report.demo import run_demo

    index = run_demo([guidance.demo_stage], tmp_path, quick=True)
    html = index.read_text()
    assert "Guidance with collision avoidance" in html and "max penetration" in html
    assert "data:image/png;base64" in html and "class='err'" not in html
