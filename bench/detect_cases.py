"""The scenes of the detection benchmark (bench/bench_detect.py): which, rendered how, cached where.

Sets (each case is one scene; ``classic`` cases are one view, the others a pair of views):

- ``classic``: the scenes the detector was first tuned on, exactly as the earlier benchmark
  rendered them (seeds 0..N-1, kinds cycling straight/arc/s_curve/nonplanar, one suggested view
  rolled by a seeded angle and shifted a little; :func:`classic_pose`).
- ``wide``: ``variety="wide"`` scenes (drivers/sim/sim_look.py), seeds taken from one part of the
  split (:func:`drivers.sim.sim_look.seeds_in`, from 10000 up), seen by the product's two views
  (across the seam, view 2 rolled to the image diagonal, as the dry run) at the look's distance
  +-10 %, both views rolled by one seeded angle and shifted along the seam by up to a quarter of
  its length (so that the seam leaves the image at one or both ends in many cases).
- ``pen``: ``variety="pen"`` scenes (1-3 lines parallel to the joint), seeds from 50000 up, the
  same views.
- ``tee``: ``variety="tee"`` scenes (close-ups whose joint ends at a T-corner at one end), seeds
  from 60000 up, medium and hard in turn, the same views. Not in the default run (``--sets``).
- ``rough``: ``variety="rough"`` scenes (a wide look whose sheets change in brightness along the
  joint as much as the real photographs' do), seeds from 70000 up, easy, medium and hard in
  turn, the same views. Not in the default run (``--sets``).
- ``strip``: ``variety="strip"`` scenes (the shop look as the real photographs the detector
  refuses show it: a joint through both images between two ground strips whose outer edges are
  crisp dark lines as long as it, unground scale beyond), seeds from 80000 up, easy, medium and
  hard in turn, the same views. Not in the default run (``--sets``).

Renders are cached as PNG (lossless; a JPEG look's artefacts are already in the image) with the
truth in an .npz under bench/cache/detect/ (git-ignored), keyed by :data:`CACHE_TAG`, bumped when
the simulator changes what it draws.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from controller.geometry.camera_model import default_camera
from controller.geometry.poses import make_pose, rotation_about
from drivers.sim.sim_look import seeds_in
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import DIFFICULTIES, KINDS, make_scene

#: Where renders are cached; the environment variable SEAMGUIDE_DETECT_CACHE points elsewhere (one
#: worktree can use another's renders: rendering the full set takes an hour or more here).
CACHE = Path(os.environ.get("SEAMGUIDE_DETECT_CACHE",
                            Path(__file__).resolve().parent / "cache" / "detect"))
CACHE_TAG = "v4"  # v4: a dark line at the ground strips' outer edges (shop look)
#: First seed of each set (disjoint seed ranges, then split by sim_look.split_of).
SEED_START = {"wide": 10000, "pen": 50000, "tee": 60000, "rough": 70000, "strip": 80000}
#: The sets that mix difficulties, and the difficulties each takes in turn.
MIXED = {"pen": DIFFICULTIES, "tee": ("medium", "hard"), "rough": DIFFICULTIES,
         "strip": DIFFICULTIES}
#: A case: (set, difficulty, split, seed).
Case = tuple[str, str, str, int]
VIEW2_ROLL_DEG = float(np.degrees(np.arctan2(1704.0, 2272.0)))  # as controller/cell/dry_run.py


def case_list(kind_set: str, difficulty: str, split: str, n: int) -> list[Case]:
    """``n`` cases (set, difficulty, split, seed) of one set, difficulty and part.

    The pen set mixes the difficulties (easy, medium, hard in turn), the tee set medium and hard;
    ``difficulty`` is ignored for them.
    """
    if kind_set == "classic":
        return [("classic", difficulty, "tuning", s) for s in range(n)]
    seeds = seeds_in(split, n, start=SEED_START[kind_set])
    if kind_set in MIXED:
        mix = MIXED[kind_set]
        return [(kind_set, mix[k % len(mix)], split, s) for k, s in enumerate(seeds)]
    return [(kind_set, difficulty, split, s) for s in seeds]


#: Cases per group: classic views per difficulty, wide pairs per difficulty and part, pen pairs
#: per part.
FULL = {"classic": 52, "wide/heldout": 100, "wide/tuning": 50, "pen": 25, "tee": 25,
        "rough": 30, "strip": 30}
QUICK = {"classic": 8, "wide/heldout": 10, "wide/tuning": 10, "pen": 6, "tee": 6, "rough": 6,
         "strip": 6}


def plan(sizes: dict[str, int], difficulties: list[str], splits: list[str],
         sets: list[str]) -> dict[str, list[Case]]:
    """The benchmark's case groups, keyed "set/difficulty/split" (pen: "pen/mixed/split")."""
    groups: dict[str, list[Case]] = {}
    if "classic" in sets:
        for d in difficulties:
            groups[f"classic/{d}/tuning"] = case_list("classic", d, "tuning", sizes["classic"])
    for split in splits:
        if "wide" in sets:
            for d in difficulties:
                groups[f"wide/{d}/{split}"] = case_list("wide", d, split,
                                                        sizes[f"wide/{split}"])
        for mixed in MIXED:
            if mixed in sets:
                groups[f"{mixed}/mixed/{split}"] = case_list(mixed, "", split, sizes[mixed])
    return groups


def render_order(groups: dict[str, list[Case]]
                 ) -> list[Case]:
    """All cases, the groups interleaved in proportion to their sizes, held-out groups at twice
    the pace of the others and the held-out pen set at four times (a run stopped early has the
    held-out part furthest along)."""
    def pace(key: str) -> float:
        return 4.0 if key.startswith("pen") and key.endswith("heldout") else (
            2.0 if key.endswith("heldout") else 1.0)

    keyed = [((i + 0.5) / len(g) / pace(key), k, c)
             for k, (key, g) in enumerate(groups.items()) for i, c in enumerate(g)]
    return [c for _, _, c in sorted(keyed)]


def classic_pose(scene: Any, cam: Any, seed: int) -> np.ndarray:
    """The earlier benchmark's seeded view: a suggested pose, rolled and shifted."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4242]))
    T = suggest_view_poses(scene, cam)[seed % 2].copy()
    roll = rng.uniform(-np.pi, np.pi)
    R = np.eye(4)
    R[:3, :3] = rotation_about((0.0, 0.0, 1.0), roll)
    T = T @ R
    shift = rng.uniform(-15, 15, 2)
    T[:3, 3] += T[:3, 0] * shift[0] + T[:3, 1] * shift[1]
    return T


def pair_poses(scene: Any, cam: Any, seed: int) -> list[np.ndarray]:
    """The two views of a wide or pen case (module doc), camera poses T_base_cam (mm)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4243]))
    standoff = scene.look.standoff_mm * float(rng.uniform(0.9, 1.1))
    poses = suggest_view_poses(scene, cam, standoff_mm=standoff,
                               baseline_mm=200.0 * standoff / 350.0)
    poses[1] = poses[1] @ make_pose(rotation_about([0, 0, 1], np.radians(VIEW2_ROLL_DEG)))
    roll = make_pose(rotation_about([0, 0, 1], float(rng.uniform(-np.pi, np.pi))))
    P = scene.seam_points_mm
    chord = (P[-1] - P[0]) / np.linalg.norm(P[-1] - P[0])
    shift = chord * float(rng.uniform(-0.25, 0.25)) * scene.length_mm
    out = []
    for T in poses:
        T = T @ roll
        T[:3, 3] += shift
        out.append(T)
    return out


def make_case_scene(case: Case) -> Any:
    """The scene of a case."""
    kind_set, difficulty, _, seed = case
    kind = KINDS[seed % len(KINDS)]
    return make_scene(kind, seed, difficulty, variety=kind_set)  # each set is a variety


def _stem(case: Case) -> Path:
    kind_set, difficulty, split, seed = case
    return CACHE / CACHE_TAG / kind_set / difficulty / f"{split}-{seed:05d}"


def case_cached(case: Case) -> bool:
    """Whether a case's views are in the cache."""
    return _stem(case).with_suffix(".npz").exists()


def render_case(case: Case) -> str:
    """Render (and cache) the views of a case; returns "cached" or "rendered"."""
    stem = _stem(case)
    if stem.with_suffix(".npz").exists():
        return "cached"
    stem.parent.mkdir(parents=True, exist_ok=True)
    cam = default_camera()
    scene = make_case_scene(case)
    seed = case[3]
    poses = [classic_pose(scene, cam, seed)] if case[0] == "classic" else \
        pair_poses(scene, cam, seed)
    truth: dict[str, Any] = {"n_views": len(poses), "gap_mm": scene.gap_mm, "kind": scene.kind,
                             "family": scene.look.family if scene.look else "classic",
                             "ragged_mm": scene.look.ragged_mm if scene.look else 0.0,
                             "centre_mm": scene.centre_mm, "radius_mm": scene.region_radius_mm}
    for i, T in enumerate(poses):
        r = render(scene, cam, T, seed=seed + 7919 * i)
        cv2.imwrite(str(stem) + f"-{i}.png", r.image)
        truth.update({f"seam_px{i}": r.seam_px, f"seam_index{i}": r.seam_index, f"T{i}": T,
                      f"end_kinds{i}": np.array(r.end_kinds), f"end_tol_px{i}": r.end_tol_px,
                      f"gap_px{i}": r.gap_px,
                      f"spans{i}": np.array(r.occluded_spans_px, float).reshape(-1, 2),
                      f"n_pens{i}": len(r.pen_lines_px)})
        for k, P in enumerate(r.pen_lines_px):
            truth[f"pen{i}_{k}"] = P
    truth["seam_points_mm"] = scene.seam_points_mm
    truth["rendered_with"] = libraries()
    np.savez(str(stem) + ".npz", **truth)
    return "rendered"


def libraries() -> str:
    """The versions of the libraries a render's pixels depend on (numpy's and OpenCV's).

    Renders are cached across runs and library upgrades: a new OpenCV changed rendered views
    (twenty-second session: rendered again in a fresh environment, OpenCV 4.14.0, the strip
    set's counts moved by one view in each part with the same detector), so a report says what
    its renders were made with (:func:`rendered_with`).
    """
    return f"numpy {np.__version__}, opencv {cv2.__version__}"


def rendered_with(cases: list[Case]) -> dict[str, int]:
    """How many of the cached ``cases`` were rendered with each library set ("unknown": before
    the renders recorded it)."""
    out: dict[str, int] = {}
    for case in cases:
        path = _stem(case).with_suffix(".npz")
        if not path.exists():
            continue
        with np.load(str(path)) as z:
            key = str(z["rendered_with"]) if "rendered_with" in z.files else "unknown"
        out[key] = out.get(key, 0) + 1
    return out


def load_case(case: Case) -> tuple[list[np.ndarray], dict[str, Any]]:
    """(images, truth) of a rendered case; truth as saved by :func:`render_case`."""
    stem = _stem(case)
    z = dict(np.load(str(stem) + ".npz"))
    imgs = [cv2.imread(str(stem) + f"-{i}.png", cv2.IMREAD_UNCHANGED)
            for i in range(int(z["n_views"]))]
    return imgs, z


def view_truth(z: dict[str, Any], i: int, image: Any = None) -> dict[str, Any]:
    """The truth of view ``i`` of a case: seam_px, end kinds and tolerance, spans, pens, gap_px.

    With the view's ``image`` (an array, rows x columns), also its ``image_size`` (width, height
    px), which the scorer needs to tell an end at the image border.
    """
    truth = {"seam_px": z[f"seam_px{i}"], "end_kinds": [str(k) for k in z[f"end_kinds{i}"]],
             "end_tol_px": float(z[f"end_tol_px{i}"]), "spans": z[f"spans{i}"],
             "pens": [z[f"pen{i}_{k}"] for k in range(int(z[f"n_pens{i}"]))],
             "gap_px": float(z[f"gap_px{i}"]), "gap_mm": float(z["gap_mm"]),
             "ragged_mm": float(z["ragged_mm"]), "family": str(z["family"])}
    if image is not None:
        truth["image_size"] = (image.shape[1], image.shape[0])
    return truth
