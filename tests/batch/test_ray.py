"""The Ray engine on a real local Ray (``ray.init(num_cpus=2)``), run inside a network namespace that
holds only the loopback interface (Ray would otherwise bind the machine's routable address)."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("ray", reason="the Ray engine needs the batch extra: pip install 'robointel[batch]'")

HERE = Path(__file__).resolve().parent
SRC = str(HERE.parents[1] / "src")


def _netns_ok() -> str:
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return "unshare/ip not found"
    r = subprocess.run(["unshare", "--net", "sh", "-c", "ip link set lo up"], capture_output=True, text=True)
    return "" if r.returncode == 0 else f"cannot create a network namespace (needs root): {r.stderr.strip()}"


def _in_netns(script: str, root: Path) -> dict:
    """Run ``script`` ROOT inside ``unshare --net`` with only ``lo`` up; return its RESULT JSON."""
    why = _netns_ok()
    if why:
        pytest.skip(why)
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "RAY_USAGE_STATS_ENABLED": "0"}
    cmd = f"ip link set lo up && exec {sys.executable} {HERE / script} {root}"
    r = subprocess.run(["unshare", "--net", "sh", "-c", cmd], capture_output=True, text=True, env=env, timeout=900)
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("RESULT ")), None)
    assert r.returncode == 0 and line, f"{script} failed:\n{r.stdout[-3000:]}\n{r.stderr[-5000:]}"
    return json.loads(line[len("RESULT "):])


@pytest.fixture(scope="module")
def ray_results(tmp_path_factory):
    return _in_netns("ray_scenarios.py", tmp_path_factory.mktemp("ray"))


def test_join_a_cluster_through_ray_client(tmp_path):
    r = _in_netns("ray_client_scenario.py", tmp_path)
    assert r["done"] == 6 and r["engines"] == ["ray"] and r["same_as_inprocess"]
    assert all(not w.endswith(f":{r['driver_pid']}") for w in r["workers"])  # ran in the cluster's workers


def test_ray_ran_on_loopback_only(ray_results):
    assert ray_results["node_ip"] == "127.0.0.1"


def test_a_task_past_its_budget_is_a_timeout_row_on_ray(ray_results):
    t = ray_results["timeout"]
    assert t["reasons"] == ["none", "timeout", "none"]
    assert 0.9 <= t["slow_wall_s"] < 10.0  # interrupted at its 1 s budget, not after its 30 s of work


def test_local_ray_workers_run_at_niceness_zero(ray_results):
    assert ray_results["worker_nice"] == [0]


def test_killed_worker_task_is_retried_and_stored_once(ray_results):
    k = ray_results["kill"]
    assert sorted(k["raw_counts"]) == k["expected_keys"]  # nothing lost
    assert set(k["raw_counts"].values()) == {1}  # nothing duplicated, even across files
    assert k["done"] == len(k["expected_keys"]) and k["errors"] == 0
    assert k["victim_reason"] in ("none", "missed")  # a real outcome from the retry, not a fault row
    assert not k["victim_worker"].endswith(f":{k['killed_pid']}")  # the retry ran in another worker
    assert k["same_as_inprocess"]


def test_a_task_out_of_retries_is_a_fault_row(ray_results):
    r = ray_results["no_retry"]
    assert r["n"] == 3 and r["errors"] == 1
    assert r["victim_reason"] == "fault" and r["victim_traceback"]  # Ray's error text is kept
    assert r["others"] == ["none", "none"]
    assert "exceeds the cluster's 2 CPUs" in ray_results["too_many_cpus"]


def test_ray_and_inprocess_give_identical_outcomes(ray_results):
    i = ray_results["identical"]
    assert i["n_ray"] == i["n_inprocess"] == 10  # a grasp trial among them: its figures to the last bit
    assert i["equal"], i["differ"]
    assert i["engines"] == ["ray"]


def test_interrupted_ray_driver_resumes_to_the_same_dataset(ray_results):
    r = ray_results["resume"]
    assert r["interrupted"] and 7 <= r["stored_at_interrupt"] < 24
    assert r["skipped"] == r["stored_at_interrupt"] and r["done"] == 24 - r["skipped"]
    assert r["equal"] and r["n"] == 24 and r["max_raw_count"] == 1


def test_ray_starts_the_longest_tasks_first():
    from robointel.batch import TaskSpec
    from robointel.batch.ray_engine import longest_first

    specs = [TaskSpec("insertion", 0, {}), TaskSpec("synthetic", 1, {"work_s": 0.5}), TaskSpec("grasp", 2, {}),
             TaskSpec("synthetic", 3, {"work_s": "bad"}), TaskSpec("insertion", 4, {}), TaskSpec("no_such_kind", 5, {})]
    order = [s.seed for s in longest_first(specs)]
    assert order == [2, 0, 4, 3, 5, 1]  # grasp ~10 s, insertion ~1.5 s, no hint (bad or unknown) 1 s, then 0.5 s
