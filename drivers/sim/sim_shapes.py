"""Seam shape functions of the simulated workpiece, in the scene's local frame (mm).

The seam is the curve ``b = f(a)`` (``a`` along the chord, ``b`` across it in the table plane) on
the surface ``z = H(a)``. Kinds: ``straight``, ``arc`` (a circle through the chord's ends),
``s_curve`` (one sine period), ``nonplanar`` (straight in plan, the sheets rise in the middle). A
*bow* (the joint bent by up to a few mm, a parabola through the chord's ends) adds to any kind.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def shape_f(kind: str, shape: float, chord: float, a: NDArray[Any],
            bow: float = 0.0) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any]]:
    """(f, df/da, d2f/da2) of the seam at chord coordinate ``a`` (mm); ``bow`` mm at the middle."""
    a = np.asarray(a)
    f, f1, f2 = _shape_base(kind, shape, chord, a)
    if bow:
        k = 4.0 * bow / (chord * chord)
        f = f + bow - k * a * a
        f1 = f1 - 2.0 * k * a
        f2 = f2 - 2.0 * k
    return f, f1, f2


def _shape_base(kind: str, shape: float, chord: float,
                a: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any]]:
    if kind == "arc":
        # Circle of radius `shape` through (+-chord/2, 0), bulging toward +b.
        R = shape
        h0 = np.sqrt(R * R - (chord / 2) ** 2)
        r = np.sqrt(np.maximum(R * R - a * a, 1e-9))
        return r - h0, -a / r, -(R * R) / r**3
    if kind == "s_curve":
        k = 2 * np.pi / chord
        return shape * np.sin(k * a), shape * k * np.cos(k * a), -shape * k * k * np.sin(k * a)
    zero = np.zeros_like(a, dtype=np.float64 if a.dtype == np.float64 else np.float32)
    return zero, zero, zero


def height(kind: str, shape: float, chord: float,
           a: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any]]:
    """(H, dH/da): the sheets' surface height (mm, local z) at chord coordinate ``a``."""
    a = np.asarray(a)
    if kind != "nonplanar":
        zero = np.zeros_like(a, dtype=np.float64 if a.dtype == np.float64 else np.float32)
        return zero, zero
    # A smooth rise of `shape` mm in the middle: cos^2 over the chord, flat (H = 0) beyond.
    k = np.pi / chord
    inside = np.abs(a) <= chord / 2
    c = np.cos(k * a)
    H = np.where(inside, shape * c * c, 0.0)
    dH = np.where(inside, -shape * k * 2 * c * np.sin(k * a), 0.0)
    return H.astype(a.dtype, copy=False), dH.astype(a.dtype, copy=False)


def arc_length(kind: str, shape: float, chord: float, n: int = 4001,
               bow: float = 0.0) -> tuple[F64, F64]:
    """Dense (a, cumulative 3D arc length) along the seam, both (n,) mm."""
    a = np.linspace(-chord / 2, chord / 2, n)
    b = shape_f(kind, shape, chord, a, bow)[0]
    z = height(kind, shape, chord, a)[0]
    seg = np.sqrt(np.diff(a) ** 2 + np.diff(b) ** 2 + np.diff(z) ** 2)
    return a, np.concatenate([[0.0], np.cumsum(seg)])


def chord_for_length(kind: str, shape_of_chord: Any, length: float,
                     bow: float = 0.0) -> tuple[float, float]:
    """Chord (and shape value) giving the wanted arc length (mm), by fixed-point iteration."""
    chord = length
    shape = shape_of_chord(chord)
    for _ in range(60):
        shape = shape_of_chord(chord)
        s = arc_length(kind, shape, chord, bow=bow)[1][-1]
        chord *= length / s
    return chord, shape_of_chord(chord)
