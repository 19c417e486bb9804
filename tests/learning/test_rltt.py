import numpy as np
import pytest

from robointel.errors import InvalidInput
from robointel.learning import insertion as I
from robointel.learning.peer_checks import gmr_agreement
from robointel.learning.rltt import learn_insertion


@pytest.fixture(scope="module")
def learned():
    task = I.PegHole()
    rng = np.random.default_rng(11)
    scene = I.HDDScene(task)
    demos = [I.demonstrate(task, rng, scene=scene) for _ in range(4)]
    return task, demos, learn_insertion(demos, n_labelled=2)


def test_pipeline_sync_decompose_train(learned):
    task, demos, lr = learned
    assert len(lr.aligned) == 4 and all(a.shape == lr.aligned[0].shape for a in lr.aligned)
    assert lr.boundary_errors.shape == (2, 3)
    for d, lab in zip(demos, lr.labels):
        assert lab.shape == d.labels.shape and np.all(np.diff(lab) >= 0)
    Xt = (lr.skill.X_ - lr.skill.x_mean_) / lr.skill.x_scale_
    assert gmr_agreement(lr.skill.gmr, Xt[::20]) < 1e-9
    assert set(lr.timings) == {"sync", "decompose", "train", "total"}
    with pytest.raises(InvalidInput):
        learn_insertion(demos, n_labelled=4)
