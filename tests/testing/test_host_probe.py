"""The host probe of the streaming benchmarks: its figures, its sleepers' end, the stall coincidence."""
import os
import time

from robointel.testing.host_probe import HostProbe, _on_every, cpu_times, steal_share


def test_the_probe_reports_the_host_and_leaves_no_process():
    with HostProbe(seconds_max=600.0) as hp:
        time.sleep(0.6)
    pids = [p.pid for p in hp._procs]
    s = hp.summary()
    assert s["cpus"] == os.cpu_count() and s["probe_sleepers"] == len(os.sched_getaffinity(0)) == len(pids)
    assert 0.0 <= s["steal_share"] <= 1.0 and set(s["steal_share_per_cpu"]) == {f"cpu{i}" for i in range(s["cpus"])}
    assert len(s["load_avg"]) == 2 and len(s["load_avg"][0]) == 3
    assert s["probe_late_max_ms"] is not None and s["probe_late_max_ms"] >= 0.0
    assert sum(s["probe_stalls_per_cpu"].values()) == s["probe_stalls"] >= len(s["probe_stall_at_s"])
    assert all(p.returncode is not None for p in hp._procs)  # each sleeper ended and was reaped
    assert not any(os.path.exists(f"/proc/{pid}") for pid in pids)


def test_coincidence_and_stalls_on_every_cpu():
    hp = HostProbe()
    hp.result = {"_stalls": [(10.0, 15.0), (20.0, 3.0)]}  # a 15 ms and a 3 ms stall
    assert hp.coincident([10.005, 10.03, 19.99, 15.0], window_s=0.02) == 3
    assert hp.coincident([10.2], window_s=0.02) == 0
    assert _on_every([[(10.0, 15.0), (20.0, 3.0)], [(10.01, 2.0)]]) == 1
    assert _on_every([[(10.0, 15.0)], [(10.01, 2.0)], [(30.0, 5.0)]]) == 0


def test_steal_share_from_two_samples():
    a = {"cpu": (10, 1000), "cpu0": (5, 500)}
    b = {"cpu": (60, 2000), "cpu0": (5, 1500)}
    assert steal_share(a, b) == {"cpu": 0.05, "cpu0": 0.0}
    now = cpu_times()
    assert "cpu" in now and all(total >= steal >= 0 for steal, total in now.values())
