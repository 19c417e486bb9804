import gmr as gmr_peer
import numpy as np
import pytest

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.learning.gmr import GaussianMixtureRegression, held_out_r2, regularize_covariances


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    X = rng.uniform(-3, 3, (600, 2))
    Y = np.stack([np.sin(X[:, 0]) * X[:, 1], np.cos(X[:, 1])], 1) + 0.05 * rng.normal(size=(600, 2))
    return X, Y


def test_matches_gmr_package_on_same_mixture(data):
    X, Y = data
    m = GaussianMixtureRegression(6, random_state=1).fit(X, Y)
    peer = gmr_peer.GMM(6, priors=m.priors_, means=m.means_, covariances=m.covariances_)
    Xt = np.random.default_rng(2).uniform(-4, 4, (300, 2))
    assert np.abs(m.predict(Xt) - peer.predict([0, 1], Xt)).max() < 1e-9
    mean, cov = m.predict(Xt[:10], return_cov=True)
    for i in range(10):
        mvn = peer.condition([0, 1], Xt[i]).to_mvn()
        assert np.abs(mvn.mean - mean[i]).max() < 1e-9
        assert np.abs(mvn.covariance - cov[i]).max() < 1e-9
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_regression_quality_and_kmeans_init(data):
    X, Y = data
    m = GaussianMixtureRegression(8).fit(X, Y)
    assert m.gmm_.init_params == "kmeans" and m.gmm_.converged_
    rmse = np.sqrt(np.mean((m.predict(X) - Y) ** 2))
    assert rmse < 0.5 * Y.std()


def test_singular_covariance_is_regularised():
    # y is an exact linear function of x: the joint covariance is singular
    x = np.linspace(0, 1, 50)
    m = GaussianMixtureRegression.from_mixture([1.0], [[0.5, 1.0]], [[[1.0, 2.0], [2.0, 4.0]]], 1)
    np.testing.assert_allclose(m.predict(x[:, None])[:, 0], 2 * x, atol=1e-6)
    c = regularize_covariances(np.zeros((1, 3, 3)))
    assert np.all(np.linalg.eigvalsh(c) > 0)
    fitted = GaussianMixtureRegression(2).fit(x[:, None], 2 * x[:, None] + 1)  # degenerate data: no crash
    np.testing.assert_allclose(fitted.predict([[0.25]]), [[1.5]], atol=1e-3)


def test_bad_input(data):
    X, Y = data
    with pytest.raises(InvalidInput):
        GaussianMixtureRegression(10).fit(X[:5], Y[:5])
    with pytest.raises(ShapeError):
        GaussianMixtureRegression(2).fit(X, Y[:-1])
    Xn = X.copy()
    Xn[0, 0] = np.nan
    with pytest.raises(NotFinite):
        GaussianMixtureRegression(2).fit(Xn, Y)
    m = GaussianMixtureRegression(2).fit(X, Y)
    with pytest.raises(ShapeError):
        m.predict(np.zeros((3, 3)))
    with pytest.raises(InvalidInput):
        GaussianMixtureRegression(2).predict(X)


def test_held_out_r2_over_groups(data):
    X, Y = data
    G = np.repeat(np.arange(6), 100)
    r2 = held_out_r2(X, Y, G, n_components=8, folds=3)
    assert r2.shape == (2,) and np.all(r2 > 0.8)  # a smooth map, held-out groups of the same range
    noise = np.random.default_rng(1).normal(size=(600, 1))  # an output the input does not predict
    assert held_out_r2(X, noise, G, n_components=4)[0] < 0.1
    # the two baselines differ only in the mean the held-out errors are compared with
    r_test = held_out_r2(X, Y, G, n_components=8, folds=3, sst_about="test", x_eps=1e-12)
    assert np.all(np.abs(r_test - r2) < 0.05)
    # one group: no held-out check (the caller's fill); an output that never varies: the caller's value or the ratio
    assert np.all(np.isinf(held_out_r2(X, Y, np.zeros(600), n_components=2)))
    assert np.all(np.isnan(held_out_r2(X, Y, np.zeros(600), n_components=2, single_group=np.nan)))
    Yc = np.column_stack([Y[:, 0], np.full(600, 2.0)])
    assert held_out_r2(X, Yc, G, n_components=4)[1] == 0.0
    with pytest.raises(InvalidInput):
        held_out_r2(X, Y, G, n_components=2, sst_about="median")
    with pytest.raises(InvalidInput):
        held_out_r2(X, Y, G, n_components=2, folds=1)
