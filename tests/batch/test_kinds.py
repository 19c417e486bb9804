import pytest

from robointel.batch import TaskSpec, execute, kinds
from robointel.batch.kinds.grasp import _failure as grasp_failure
from robointel.outcome import Failure


def test_every_builtin_kind_is_registered():
    assert {"synthetic", "grasp", "insertion", "grinding", "guidance", "planning"} <= set(kinds())


def test_insertion_trial_is_a_pure_function_of_the_spec():
    spec = TaskSpec("insertion", 4, {"controller": "impedance"})
    a = execute(spec.to_dict())
    b = execute(spec.to_dict())  # the cached cell is reset by each run: the same outcome again
    assert a["traceback"] == "", a["traceback"]
    assert a["category"] == "impedance/constant_push"
    assert (a["success"], a["reason"], a["detail"], a["figures"]) == (b["success"], b["reason"], b["detail"],
                                                                    b["figures"])
    f = a["figures"]
    assert 0.0 <= f["tilt_rad"] <= 0.0873 and f["lateral_m"] <= 2.9e-3  # the start error drawn from the seed
    if a["success"]:
        assert a["reason"] == "none" and abs(f["depth_error_m"]) <= 1e-3  # seated: tip within 1 mm of the bottom
    else:
        assert a["reason"] in {"force_limit", "timeout", "wedged", "missed"}


def test_insertion_bad_params_become_error_rows():
    row = execute(TaskSpec("insertion", 0, {"controller": "hybrid"}).to_dict())
    assert not row["success"] and row["reason"] == "error" and "controller must be one of" in row["detail"]


def test_guidance_kinematic_scenario():
    row = execute(TaskSpec("guidance", 0, {"scenario": 1, "physics": False, "duration": 1.0}).to_dict())
    assert row["traceback"] == "", row["traceback"]
    assert row["category"] == "scenario 1"
    assert row["figures"]["duration_s"] == pytest.approx(1.0, abs=0.01)
    assert row["success"] == (row["figures"]["robot_obstacle_contacts"] == 0
                              and row["figures"]["max_penetration_m"] <= 0.0)


@pytest.mark.parametrize("reason,failure", [
    ("no feasible grasp (ik)", Failure.NO_GRASP), ("nothing perceived", Failure.NO_GRASP),
    ("nothing perceived after attempt 1 (attempt 1: slipped (...))", Failure.NO_GRASP),
    ("approach or lift unreachable", Failure.IK), ("dropped: fingers closed on nothing", Failure.MISSED),
    ("dropped: slipped during shake (moved 0.040 m in hand, grip 0.030 m)", Failure.SLIP),
])
def test_grasp_reasons_map_to_the_shared_enum(reason, failure):
    assert grasp_failure(reason) is failure


def _threads_trial(spec):
    import numba
    import threadpoolctl

    from robointel.outcome import TrialOutcome

    blas = max(x["num_threads"] for x in threadpoolctl.threadpool_info())
    return TrialOutcome(True, figures={"blas_threads": blas, "numba_threads": numba.get_num_threads()})


def test_a_task_runs_with_one_thread_per_library():
    import numba

    from robointel.batch import register_kind

    register_kind("test-threads", _threads_trial, replace=True)
    before = numba.get_num_threads()
    row = execute(TaskSpec("test-threads", 0).to_dict())
    assert row["figures"] == {"blas_threads": 1.0, "numba_threads": 1.0}
    assert numba.get_num_threads() == before  # the driver's setting is restored
