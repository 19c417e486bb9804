import h5py
import numpy as np
import pytest

from robointel.errors import DataMissing, InvalidInput, NotFinite, ShapeError
from robointel.learning.demonstration import Demonstration, load_demonstrations, save_demonstrations


def _demo(n=50, seed=0, name=""):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    pose = np.tile(np.eye(4), (n, 1, 1))
    pose[:, :3, 3] = rng.normal(size=(n, 3)) * 0.01
    return Demonstration.create(t, pose, rng.normal(size=(n, 6)), np.repeat([0, 1], [n // 2, n - n // 2]),
                                action_names=("approach", "insert"), name=name, meta={"seed": seed})


def test_create_validates():
    d = _demo()
    assert len(d) == 50 and d.features().shape == (50, 18) and d.features(wrench=False).shape == (50, 12)
    np.testing.assert_allclose(d.phase_times(), [0.25])
    with pytest.raises(ShapeError):
        Demonstration.create(d.t, d.pose, d.wrench[:, :3])
    w = d.wrench.copy()
    w[3, 2] = np.nan
    with pytest.raises(NotFinite):
        Demonstration.create(d.t, d.pose, w)
    with pytest.raises(InvalidInput):
        Demonstration.create(d.t[::-1], d.pose, d.wrench)


def test_hdf5_roundtrip_and_append_keeps_others(tmp_path):
    path = tmp_path / "demos.h5"
    f = save_demonstrations(path, [_demo(seed=1), _demo(seed=2)])
    assert f.names() == ["demo_0000", "demo_0001"]
    with h5py.File(path, "r") as h:
        addr = h["demonstrations/demo_0000/wrench"].id.get_offset()
    f.append(_demo(seed=3, name="extra"))
    with h5py.File(path, "r") as h:
        assert h["demonstrations/demo_0000/wrench"].id.get_offset() == addr  # not rewritten
        assert h.attrs["schema"] == "robointel.demonstrations"
    back = load_demonstrations(path)
    assert [d.name for d in back] == ["demo_0000", "demo_0001", "extra"]
    ref = _demo(seed=2)
    np.testing.assert_array_equal(back[1].wrench, ref.wrench)
    np.testing.assert_array_equal(back[1].labels, ref.labels)
    assert back[1].action_names == ("approach", "insert") and back[1].meta == {"seed": 2}
    with pytest.raises(InvalidInput):
        f.append(_demo(), name="extra")
    with pytest.raises(DataMissing):
        f.load("nope")
