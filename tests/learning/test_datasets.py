import numpy as np

from robointel.learning.datasets import lasa_names, load_ft, load_lasa


def test_lasa_ships_26_shapes_of_7_demos():
    names = lasa_names()
    assert len(names) == 26 and len(lasa_names(include_multi=True)) == 30
    s = load_lasa("GShape")
    assert s.pos.shape == (7, 1000, 2) and s.vel.shape == (7, 1000, 2)
    np.testing.assert_allclose(s.pos[:, -1], 0.0, atol=1e-9)  # every LASA demonstration ends at the origin
    # the velocity is the time derivative of the position
    v = np.gradient(s.pos[0], s.t[0], axis=0)
    assert np.median(np.abs(v - s.vel[0])) < 0.05 * np.abs(s.vel[0]).max()


def test_uci_ft_episodes(shared_data):
    shared_data("ft", "lp1.data.txt")
    sizes = {p: load_ft(p).X.shape[0] for p in ("lp1", "lp2", "lp3", "lp4", "lp5")}
    assert sum(sizes.values()) == 463
    e = load_ft("lp1")
    assert e.X.shape[1:] == (15, 6) and "normal" in e.classes and len(e.y) == e.X.shape[0]


def test_ft_features_and_svm_beat_the_majority_class(shared_data):
    import pytest
    from sklearn.model_selection import StratifiedKFold, cross_val_score
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    from robointel.errors import InvalidInput
    from robointel.learning.ft_features import ft_episode_features

    shared_data("ft", "lp1.data.txt")
    e = load_ft("lp1")
    F = ft_episode_features(e.X)
    assert F.shape == (len(e.X), 8 * 6 + 15 * 6) and np.isfinite(F).all()
    with pytest.raises(InvalidInput):
        ft_episode_features(e.X[:, :, :5])
    acc = cross_val_score(make_pipeline(StandardScaler(), SVC(C=10.0)), F, e.y,
                          cv=StratifiedKFold(4, shuffle=True, random_state=0)).mean()
    majority = np.bincount(e.y).max() / len(e.y)
    assert acc > majority + 0.3, (acc, majority)
