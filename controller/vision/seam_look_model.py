"""The learned look check: how likely a seam candidate is the joint, from its look features.

A random forest (``cv2.ml.RTrees``, shipped as ``data/seam_look.yml.gz``) trained by
``bench/train_seam_look.py`` on the candidates the detector weighs on the tuning part of the
simulator's scenes (never the held-out part, never the photographs). Its answer is the share of
trees that vote "on the joint" (0..1); :mod:`controller.vision.seam_decision` reads it.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from controller.vision.seam_look import look_features
from controller.vision.seam_params import Candidate

MODEL_PATH = Path(__file__).resolve().parent / "data" / "seam_look.yml.gz"
TREES = 150
SEED = 20261201


def train_forest(X: np.ndarray, y: np.ndarray) -> Any:
    """A forest on features ``X`` (N, F) and labels ``y`` (N,) 0/1; fixed seed."""
    cv2.setRNGSeed(SEED)
    m = cv2.ml.RTrees_create()
    m.setMaxDepth(10)
    m.setMinSampleCount(4)
    m.setActiveVarCount(0)
    m.setCalculateVarImportance(True)
    m.setTermCriteria((cv2.TERM_CRITERIA_MAX_ITER, TREES, 0.0))
    m.train(np.asarray(X, np.float32), cv2.ml.ROW_SAMPLE, np.asarray(y, np.int32))
    return m


def votes(model: Any, X: np.ndarray) -> np.ndarray:
    """Share of the trees voting class 1 for each row of ``X`` (N, F): (N,) 0..1."""
    X = np.asarray(X, np.float32).reshape(len(X), -1)
    if len(X) == 0:
        return np.zeros(0)
    v = model.getVotes(X, 0)
    # The first row of getVotes names the classes; the rest are the counts per sample.
    classes = v[0].tolist()
    counts = v[1:].astype(np.float64)
    one = counts[:, classes.index(1)] if 1 in classes else np.zeros(len(X))
    return np.asarray(one / np.maximum(counts.sum(axis=1), 1.0))


@functools.cache
def _model(path: str) -> Any:
    # OpenCV's FileStorage reads (and writes) a .yml.gz itself.
    return cv2.ml.RTrees_load(path)


def joint_probability(features: np.ndarray, path: Path = MODEL_PATH) -> np.ndarray:
    """(N,) share of trees that call each row of ``features`` (N, F) a candidate on the joint."""
    return votes(_model(str(path)), features)


#: Below this share of trees, a candidate does not look like two sheets meeting: rejected, and
#: it makes no other candidate ambiguous. Chosen on the tuning part's out-of-fold votes
#: (bench/train_seam_look.py), where 1 % of the candidates below it lay on the joint.
LOOK_NOT = 0.15


def check_looks(grey: np.ndarray, cands: list[Candidate]) -> None:
    """Vote on each refined candidate of ``cands`` (in place): ``stats["look"]`` 0..1, and those
    that do not look like a joint (:data:`LOOK_NOT`) are rejected and are no one's rival.

    ``grey``: the image the candidates' points (full-resolution px) are in.
    """
    live = [c for c in cands if c.points is not None and len(c.points) >= 2
            and (not c.why_rejected or c.rival)]
    if not live:
        return
    prob = joint_probability(np.array([look_features(grey, c) for c in live]))
    for c, pj in zip(live, prob, strict=True):
        c.stats["look"] = float(pj)
        if pj < LOOK_NOT:
            c.rival = False
            if not c.why_rejected:
                c.why_rejected = (f"does not look like two sheets meeting (learned look check "
                                  f"{pj:.2f} < {LOOK_NOT})")
