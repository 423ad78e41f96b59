"""numpy versions of the scipy functions the seam detector calls, computed as scipy does.

``savgol_filter`` (Savitzky-Golay, ``mode="interp"``), ``CubicSpline`` (not-a-knot, evaluated
along axis 0) and ``erf`` give scipy's numbers to about 1e-13 relative; ``norm_cdf_pdf`` gives
``scipy.stats.norm``'s CDF and density together (the profile models' blurred step and its
slope) to 1e-7, faster than exact. Importing ``scipy.signal``, ``scipy.interpolate``,
``scipy.special`` and ``scipy.stats`` costs several times what detecting the seam in a 2272x1704
image does, and ``seamguide detect`` is scripted over whole image sets; these need numpy alone
(``tests/test_scipy_equivalents.py`` compares them with scipy).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

F64 = NDArray[np.float64]


def savgol_filter(x: ArrayLike, window_length: int, polyorder: int, axis: int = -1,
                  mode: str = "interp") -> F64:
    """``scipy.signal.savgol_filter(x, window_length, polyorder, axis=axis, mode="interp")``.

    Inside, the least-squares polynomial of degree ``polyorder`` over each window of odd length
    ``window_length``, evaluated at its centre; the first and last ``window_length // 2`` samples
    from the polynomial fitted to the first (last) window. Only ``mode="interp"``.
    """
    if mode != "interp":
        raise ValueError(f"savgol_filter: only mode='interp' is implemented, got {mode!r}")
    a = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    n, w = a.shape[0], int(window_length)
    if w % 2 != 1 or w > n or polyorder >= w:
        raise ValueError(f"savgol_filter: window_length {w} must be odd, <= {n} and > polyorder")
    h = w // 2
    t = np.arange(-h, h + 1, dtype=np.float64)
    V = np.vander(t, polyorder + 1, increasing=True)  # (w, p + 1)
    pinv = np.linalg.pinv(V)  # polynomial coefficients from a window's samples
    flat = a.reshape(n, -1)
    out = np.empty_like(flat)
    centre = pinv[0]  # the value at t = 0
    for k in range(flat.shape[1]):
        out[h:n - h, k] = np.correlate(flat[:, k], centre, mode="valid")
    # Edges: the polynomial of the first (last) window evaluated at its own sample positions.
    out[:h] = V[:h] @ (pinv @ flat[:w])
    out[n - h:] = V[h + 1:] @ (pinv @ flat[n - w:])
    return np.moveaxis(out.reshape(a.shape), 0, axis)


def _solve_tridiagonal(A: F64, b: F64) -> F64:
    """Solve ``A x = b`` for a tridiagonal ``A`` (n, n) and ``b`` (n, m): the Thomas algorithm.

    O(n) instead of the O(n^3) of a dense solve (a 600-knot spline took ~0.1 s dense); on
    Python floats, as the recurrence is sequential. Not pivoted: the not-a-knot system is
    diagonally dominant in its interior rows (``tests/test_scipy_equivalents.py`` checks it
    against scipy). ``scipy.linalg.solve_banded`` would do it, but importing it costs more
    than a detection (module doc).
    """
    lo = [0.0, *np.diagonal(A, -1).tolist()]
    di = np.diagonal(A).tolist()
    up = [*np.diagonal(A, 1).tolist(), 0.0]
    rhs = np.asarray(b, dtype=np.float64).tolist()
    n, m = len(di), len(rhs[0])
    for i in range(1, n):
        w = lo[i] / di[i - 1]
        di[i] -= w * up[i - 1]
        r, rp = rhs[i], rhs[i - 1]
        for j in range(m):
            r[j] -= w * rp[j]
    x = [[0.0] * m for _ in range(n)]
    x[-1] = [v / di[-1] for v in rhs[-1]]
    for i in range(n - 2, -1, -1):
        x[i] = [(rhs[i][j] - up[i] * x[i + 1][j]) / di[i] for j in range(m)]
    return np.asarray(x, dtype=np.float64)


class CubicSpline:
    """``scipy.interpolate.CubicSpline(x, y, axis=0)`` with not-a-knot ends, evaluated by calling.

    ``x`` strictly increasing (n,), ``y`` (n, ...); calling it at points outside ``x``
    extrapolates with the end pieces, as scipy does.
    """

    def __init__(self, x: ArrayLike, y: ArrayLike, axis: int = 0) -> None:
        if axis != 0:
            raise ValueError("CubicSpline: only axis=0 is implemented")
        self.x = np.asarray(x, dtype=np.float64)
        yy = np.asarray(y, dtype=np.float64)
        n = len(self.x)
        if n < 2 or yy.shape[0] != n or np.any(np.diff(self.x) <= 0):
            raise ValueError("CubicSpline: x must be strictly increasing, 2 points at least, "
                             "one per row of y")
        self._shape = yy.shape[1:]
        y2 = yy.reshape(n, -1)
        dx = np.diff(self.x)[:, None]
        slope = np.diff(y2, axis=0) / dx
        if n == 2:
            s = np.vstack([slope, slope])
        elif n == 3:
            # Not-a-knot on three points: the parabola through them.
            c2 = (slope[1] - slope[0]) / (self.x[2] - self.x[0])
            s = np.vstack([slope[0] - c2 * dx[0], slope[0] + c2 * dx[0],
                           slope[1] + c2 * dx[1]])
        else:
            s = self._slopes(self.x, dx[:, 0], slope)
        t = (s[:-1] + s[1:] - 2 * slope) / dx
        self._c = np.stack([t / dx, (slope - s[:-1]) / dx - t, s[:-1], y2[:-1]])  # (4, n-1, m)

    @staticmethod
    def _slopes(x: F64, dx: F64, slope: F64) -> F64:
        """First derivatives at the knots: the not-a-knot system scipy solves."""
        n = len(x)
        A = np.zeros((n, n))
        b = np.empty((n, slope.shape[1]))
        i = np.arange(1, n - 1)
        A[i, i - 1] = dx[1:]
        A[i, i] = 2 * (dx[:-1] + dx[1:])
        A[i, i + 1] = dx[:-1]
        b[1:-1] = 3 * (dx[1:, None] * slope[:-1] + dx[:-1, None] * slope[1:])
        d0 = x[2] - x[0]
        A[0, 0], A[0, 1] = dx[1], d0
        b[0] = ((dx[0] + 2 * d0) * dx[1] * slope[0] + dx[0] ** 2 * slope[1]) / d0
        d1 = x[-1] - x[-3]
        A[-1, -1], A[-1, -2] = dx[-2], d1
        b[-1] = (dx[-1] ** 2 * slope[-2] + (2 * d1 + dx[-1]) * dx[-2] * slope[-1]) / d1
        return _solve_tridiagonal(A, b)

    def __call__(self, xq: ArrayLike) -> Any:
        """Values at ``xq`` (shape ``xq.shape + y.shape[1:]``)."""
        q = np.asarray(xq, dtype=np.float64)
        i = np.clip(np.searchsorted(self.x, q.ravel(), side="right") - 1, 0, len(self.x) - 2)
        h = (q.ravel() - self.x[i])[:, None]
        c = self._c[:, i]
        val = ((c[0] * h + c[1]) * h + c[2]) * h + c[3]
        return val.reshape(q.shape + self._shape)


# erf as the Cephes library computes it (ndtr.c: erf on |x| <= 1 from T/U, erfc beyond from
# P/Q below 8 and R/S above), the rational approximations scipy's own erf agrees with.
_T = np.array([9.60497373987051638749e0, 9.00260197203842689217e1, 2.23200534594684319226e3,
               7.00332514112805075473e3, 5.55923013010394962768e4])
_U = np.array([1.0, 3.35617141647503099647e1, 5.21357949780152679795e2, 4.59432382970980127987e3,
               2.26290000613890934246e4, 4.92673942608635921086e4])
_P = np.array([2.46196981473530512524e-10, 5.64189564831068821977e-1, 7.46321056442269912687e0,
               4.86371970985681366614e1, 1.96520832956077098242e2, 5.26445194995477358631e2,
               9.34528527171957607540e2, 1.02755188689515710272e3, 5.57535335369399327526e2])
_Q = np.array([1.0, 1.32281951154744992508e1, 8.67072140885989742329e1, 3.54937778887819891062e2,
               9.75708501743205489753e2, 1.82390916687909736289e3, 2.24633760818710981792e3,
               1.65666309194161350182e3, 5.57535340817727675546e2])
_R = np.array([5.64189583547755073984e-1, 1.27536670759978104416e0, 5.01905042251180477414e0,
               6.16021097993053585195e0, 7.40974269950448939160e0, 2.97886665372100240670e0])
_S = np.array([1.0, 2.26052863220117276590e0, 9.39603524938001434673e0, 1.20489539808096656605e1,
               1.70814450747565897222e1, 9.60896809063285878198e0, 3.36907645100081516050e0])


def _polyval(c: F64, x: F64) -> F64:
    out = np.full_like(x, c[0])
    for ck in c[1:]:
        out = out * x + ck
    return out


def erf(x: ArrayLike) -> F64:
    """The error function, elementwise (``scipy.special.erf``), to about 1e-16."""
    a = np.asarray(x, dtype=np.float64)
    ax = np.abs(a)
    out = np.empty_like(a)
    small = ax <= 1.0
    z = a[small] * a[small]
    out[small] = a[small] * _polyval(_T, z) / _polyval(_U, z)
    big = ~small
    xb = np.minimum(ax[big], 27.0)  # erfc underflows to 0 beyond ~26.6
    e = np.exp(-xb * xb)
    mid = xb < 8.0
    erfc = np.where(mid, e * _polyval(_P, xb) / _polyval(_Q, xb),
                    e * _polyval(_R, xb) / _polyval(_S, xb))
    out[big] = np.sign(a[big]) * (1.0 - erfc)
    return out


# Abramowitz & Stegun 7.1.26: |erf error| <= 1.5e-7.
_AS_P = 0.3275911
_AS_A = (1.061405429, -1.453152027, 1.421413741, -0.284496736, 0.254829592)


def norm_cdf_pdf(z: ArrayLike) -> tuple[F64, F64]:
    """``(scipy.stats.norm.cdf(z), scipy.stats.norm.pdf(z))`` elementwise, the CDF to 1e-7.

    One exponential serves both (the A&S 7.1.26 rational approximation of erf carries the
    density's ``exp(-z^2 / 2)``): the profile models evaluate this for every sample of every
    profile at every fitting step, and an exact erf costs three times as much. 1e-7 is far below
    an 8-bit grey level (4e-3).
    """
    a = np.asarray(z, dtype=np.float64)
    e = np.exp(-0.5 * a * a)
    t = 1.0 / (1.0 + (_AS_P / np.sqrt(2.0)) * np.abs(a))
    poly = _AS_A[0]
    for ck in _AS_A[1:]:
        poly = poly * t + ck
    h = 0.5 * poly * t * e  # the tail beyond |z|
    return np.where(a >= 0, 1.0 - h, h), e * (1.0 / np.sqrt(2.0 * np.pi))
