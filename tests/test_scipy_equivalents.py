"""The numpy versions of savgol_filter, CubicSpline, erf and norm.cdf / pdf give scipy's numbers."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.interpolate
import scipy.signal
import scipy.special
import scipy.stats

from controller.vision.scipy_equivalents import CubicSpline, erf, norm_cdf_pdf, savgol_filter


def test_erf_is_scipys():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-10, 10, 20000), rng.uniform(-1.1, 1.1, 20000),
                        [0.0, 1.0, -1.0, 8.0, -8.0, 27.0, -40.0, 1e-300]])
    assert np.allclose(erf(x), scipy.special.erf(x), rtol=1e-15, atol=1e-300)
    assert erf(np.zeros((3, 4))).shape == (3, 4)


def test_norm_cdf_pdf_is_scipys_to_1e7():
    rng = np.random.default_rng(1)
    z = np.concatenate([rng.uniform(-12, 12, 20000), rng.uniform(-1.5, 1.5, 20000),
                        [0.0, -0.0, 1.0, -1.0, 40.0, -40.0]])
    P, g = norm_cdf_pdf(z)
    assert np.abs(P - scipy.stats.norm.cdf(z)).max() < 1e-7
    assert np.allclose(g, scipy.stats.norm.pdf(z), rtol=1e-14, atol=1e-300)
    # The CDF is monotone and its two halves add up to one (the models' steps are symmetric).
    zs = np.sort(z)
    assert np.all(np.diff(norm_cdf_pdf(zs)[0]) >= 0)
    assert np.abs(norm_cdf_pdf(z)[0] + norm_cdf_pdf(-z)[0] - 1).max() < 1e-8
    assert norm_cdf_pdf(np.zeros((3, 4)))[0].shape == (3, 4)


@pytest.mark.parametrize("n,window,order", [(5, 5, 2), (9, 7, 2), (40, 13, 2), (200, 29, 2),
                                            (57, 9, 1), (57, 9, 3)])
def test_savgol_filter_is_scipys(n, window, order):
    y = np.random.default_rng(n).normal(size=(n, 2)).cumsum(axis=0) * 10
    ref = scipy.signal.savgol_filter(y, window, order, axis=0, mode="interp")
    assert np.allclose(savgol_filter(y, window, order, axis=0), ref, rtol=0, atol=1e-11)


def test_savgol_filter_refuses_what_it_does_not_do():
    with pytest.raises(ValueError, match="mode"):
        savgol_filter(np.zeros(9), 5, 2, mode="nearest")
    with pytest.raises(ValueError, match="odd"):
        savgol_filter(np.zeros(9), 4, 2)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 12, 80])
def test_cubic_spline_is_scipys_inside_and_beyond_the_knots(n):
    rng = np.random.default_rng(n)
    t = np.sort(rng.choice(np.arange(300.0), n, replace=False))
    y = rng.normal(size=(n, 2)) * 50
    q = np.linspace(t[0] - 3, t[-1] + 3, 301)
    ref = scipy.interpolate.CubicSpline(t, y, axis=0)(q)
    assert np.allclose(CubicSpline(t, y, axis=0)(q), ref, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="increasing"):
        CubicSpline(t[::-1], y)
