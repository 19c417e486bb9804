"""The insertion batch kind reproduces the benchmark's start list (``start_seed``) and noise seeds."""

import numpy as np

from robointel.batch import TaskSpec
from robointel.batch.kinds.insertion import insertion_trial
from robointel.learning.insertion import random_start_errors
from robointel.outcome import Failure


def test_start_seed_gives_the_benchmarks_kth_start():
    starts = random_start_errors(np.random.default_rng(7), 3)
    for k in (0, 2):
        out = insertion_trial(TaskSpec("insertion", k, {"policy": "constant_push", "start_seed": 7,
                                                        "time_limit": 0.05}))
        assert out.figures["tilt_rad"] == starts[k][1][1]
        assert out.figures["lateral_m"] == float(np.linalg.norm(starts[k][0]))
        assert not out.success and out.reason is Failure.TIMEOUT  # 50 ms: still above the hole
