"""3D plot of a located seam and its weld path, optionally coloured by the error to the truth."""

from __future__ import annotations

import io

import numpy as np
from numpy.typing import NDArray


def seam_plot_png(seam_mm: NDArray[np.float64], path_mm: NDArray[np.float64] | None = None,
                  error_mm: NDArray[np.float64] | None = None, title: str = "") -> bytes:
    """PNG bytes of a 3D plot: seam points (base frame, mm), weld targets, per-point error (mm).

    Uses matplotlib's Agg backend (no display needed).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig = plt.figure(figsize=(9, 4.5), dpi=100)
    ax = fig.add_subplot(1, 2 if error_mm is not None else 1, 1, projection="3d")
    s = np.asarray(seam_mm)
    if error_mm is not None:
        sc = ax.scatter(s[:, 0], s[:, 1], s[:, 2], c=error_mm, cmap="viridis", s=8)
        fig.colorbar(sc, ax=ax, shrink=0.6, pad=0.2, label="error to truth (mm)")
    else:
        ax.plot(s[:, 0], s[:, 1], s[:, 2], "b.-", ms=3, lw=1, label="seam")
    if path_mm is not None:
        p = np.asarray(path_mm)
        ax.plot(p[:, 0], p[:, 1], p[:, 2], "r-", lw=1, label="torch tip path")
    # Equal scale on every axis (a flat seam must look flat), with some height so a planar seam
    # is not drawn as a line.
    allp = s if path_mm is None else np.vstack([s, np.asarray(path_mm)])
    span = np.maximum(np.ptp(allp, axis=0), 1.0)
    span[2] = max(span[2], 0.25 * max(span[0], span[1]))
    ax.set_box_aspect(tuple(float(v) for v in span))
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.zaxis.set_major_locator(MaxNLocator(3))  # the z span is short: few ticks, no overlap
    if path_mm is not None or error_mm is None:
        ax.legend(loc="upper left", fontsize=8)
    if error_mm is not None:
        ax2 = fig.add_subplot(1, 2, 2)
        along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(s, axis=0), axis=1))])
        ax2.plot(along, error_mm, "k-")
        ax2.set_xlabel("along the seam (mm)")
        ax2.set_ylabel("3D error (mm)")
        ax2.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()
