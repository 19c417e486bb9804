import gmr as gmr_peer
import numpy as np
import pytest

from robointel.errors import InvalidInput, NotFinite, ShapeError
from robointel.learning.gmr import GaussianMixtureRegression, regularize_covariances


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
