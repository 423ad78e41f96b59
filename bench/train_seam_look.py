"""Train the learned look check of seam candidates (controller/vision/seam_look_model.py).

Reads the candidates of bench/seam_look_data.py (tuning part only), trains a random forest
(OpenCV's ``cv2.ml.RTrees``: no new runtime dependency) to tell a candidate on the joint from
one that is not, reports a case-grouped cross-validation (no case in both the training and the
test fold) and writes the model into the package. Fixed seeds: the same data give the same model.

    python -m bench.seam_look_data && python -m bench.train_seam_look
"""

from __future__ import annotations

import argparse
import json
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from bench.seam_look_data import OUT as DATA
from controller.vision.seam_look_model import MODEL_PATH, TREES, train_forest, votes


def folds(cases: np.ndarray, k: int) -> np.ndarray:
    """Fold of each row by a stable hash of its case (all views of a case in one fold)."""
    return np.array([zlib.crc32(str(c).encode()) % k for c in cases])


def cross_validate(X: np.ndarray, y: np.ndarray, cases: np.ndarray, k: int = 5
                   ) -> dict[str, Any]:
    """Out-of-fold probability of each row and a summary (share right at 0.5, per-bin counts)."""
    f = folds(cases, k)
    prob = np.zeros(len(y))
    for i in range(k):
        m = train_forest(X[f != i], y[f != i])
        prob[f == i] = votes(m, X[f == i])
    bins = [0.0, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8, 0.9, 1.01]
    table = []
    for a, b in zip(bins[:-1], bins[1:], strict=True):
        s = (prob >= a) & (prob < b)
        table.append({"p": f"{a:.2f}-{min(b, 1.0):.2f}", "n": int(s.sum()),
                      "joint": int(y[s].sum())})
    return {"prob": prob, "accuracy": float(np.mean((prob >= 0.5) == (y == 1))), "bins": table}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--data", default=str(DATA))
    ap.add_argument("--out", default=str(MODEL_PATH))
    a = ap.parse_args(argv)
    z = np.load(a.data)
    X, y = z["X"].astype(np.float32), (z["y"] >= 1).astype(np.int32)
    cv = cross_validate(X, y, z["case"])
    print(json.dumps({"candidates": len(y), "on_joint": int(y.sum()), "trees": TREES,
                      "cv_accuracy": round(cv["accuracy"], 4), "cv_bins": cv["bins"]}, indent=1))
    model = train_forest(X, y)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    model.save(str(a.out))
    print(f"model written to {a.out} ({Path(a.out).stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
