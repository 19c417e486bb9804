"""One honest planner (docs/guides/cli.md): the plan's verdict is what --execute does; any arm; the viewer."""
import re
import subprocess
import time
import urllib.request

import yaml

SELF = {"name": "fold", "robot": "lrmate200id7l", "steps": 30, "operational_time": 6.0, "d_min": 0.02,
        "obstacles": [{"type": "box", "name": "box", "center": [0.65, 0.0, 0.63], "size": [0.08, 0.08, 0.08]}],
        "waypoints": [{"name": "a", "q_deg": [-40, 20, 10, 0, -60, 0]},
                      {"name": "b", "q_deg": [40, 20, 10, 0, -60, 0]}]}
UNDER = {"name": "no_table", "robot": "lrmate200id7l", "table": False, "dt": 0.1, "steps": 10,
         "waypoints": [{"name": "home", "q_deg": [0, 0, -20, 0, -70, 0]},
                       {"name": "under", "q_deg": [0, 86, 0, 0, -29, 0]}]}


def _verdict(stdout):
    return next(ln for ln in stdout.splitlines() if ln.startswith("verdict: "))


def test_the_plan_verdict_is_what_execute_does(robointel, tmp_path):
    for scene, accepted in ((SELF, True), (UNDER, False)):
        p = tmp_path / f"{scene['name']}.yaml"
        p.write_text(yaml.safe_dump(scene))
        plan = robointel("plan", "scene", str(p), "--no-plots", "--out", str(tmp_path / "t.npz"))
        ex = robointel("plan", "scene", str(p), "--no-plots", "--out", str(tmp_path / "x.npz"), "--execute")
        if accepted:
            assert plan.returncode == 0 and "--execute accepts" in _verdict(plan.stdout), plan.stdout + plan.stderr
            assert ex.returncode == 0 and "MuJoCo: RMS tracking error" in ex.stdout, ex.stdout + ex.stderr
        else:
            why = _verdict(plan.stdout).split("refuses this trajectory: ", 1)[1]
            assert plan.returncode == 1 and "'table'" in why
            assert ex.returncode == 2 and ex.stderr.strip() == f"error: {why}" and "MuJoCo" not in ex.stdout


def test_any_urdf_start_to_goal_then_the_player(robointel, robointel_command, shared_data, tmp_path):
    urdf = shared_data("mbm", "ur5", "ur5.urdf")
    out = tmp_path / "ur5.npz"
    r = robointel("plan", "motion", "--urdf", str(urdf), "--start", "q_deg:0,-90,90,-90,-90,0", "--goal",
                  "q_deg:60,-60,60,-90,-90,0", "--out", str(out), "--execute")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "--execute accepts" in _verdict(r.stdout) and "MuJoCo" in r.stdout  # built with balanced inertias
    view = subprocess.Popen([*robointel_command, "view", str(out), "--robot", str(urdf), "--port", "0", "--for", "60"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = ""
        t0 = time.monotonic()
        while not url and time.monotonic() - t0 < 120:
            m = re.search(r"open (http://127\.0\.0\.1:\d+)", view.stdout.readline())
            url = m.group(1) if m else ""
        assert url, "no URL printed"
        assert urllib.request.urlopen(url, timeout=10).status == 200
    finally:
        view.terminate()
        out_text, _ = view.communicate(timeout=30)
    assert view.returncode == 0 and "stopped after" in out_text
