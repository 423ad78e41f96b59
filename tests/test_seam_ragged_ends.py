"""Ends of a ragged gap (controller/vision/seam_centreline.py): the last stretch before an end is
guided by a quadratic through the centres before it, which wander by the edges' jag; read off too
short a stretch its curvature curls the end sideways. Rendered wide-look joints (straight, arc,
S-curve) with ragged edges (0.3 mm jag on a 1 mm gap at 400 mm), both ends sheet borders in view,
exact truth from the renderer."""

import numpy as np
from sim_looks import NEUTRAL

from controller.geometry.camera_model import default_camera
from controller.vision.seam_detect import detect_seam
from drivers.sim.sim_render import render, suggest_view_poses
from drivers.sim.sim_scene import make_scene

CAM = default_camera()


def end_errors(kind, seed):
    """Distances (px) of the two detected ends from the true ends, and the end kinds."""
    sc = make_scene(kind, seed, "easy", variety="wide", look={**NEUTRAL, "ragged_mm": 0.3},
                    noise_dn=1.5, blur_px=0.6, glare=0.0, uneven_light=0.0, gap_mm=1.0,
                    length_mm=150.0, albedo_a=0.6, albedo_b=0.6, brush_contrast=0.05,
                    clutter=False)
    r = render(sc, CAM, suggest_view_poses(sc, CAM, standoff_mm=400.0)[0], seed=seed)
    det = detect_seam(r.image)
    E, TE = det.endpoints_px, r.seam_px[[0, -1]]
    if np.linalg.norm(E[0] - TE[0]) > np.linalg.norm(E[0] - TE[1]):
        TE = TE[::-1]
    assert det.end_kinds == r.end_kinds == ("joint_end", "joint_end")
    return list(np.linalg.norm(E - TE, axis=1))


def test_the_ends_of_a_ragged_gap_stay_on_the_seam():
    errs = [e for kind in ("straight", "arc", "s_curve") for seed in range(4)
            for e in end_errors(kind, seed)]
    # The scorer's end tolerance here is twice the jag, 4.1 px. Guided by 12 samples (48 px):
    # median 2.6 px, 9 of 24 ends beyond 4.1 px; by 24 samples: median 1.35 px, 3 of 24.
    assert np.median(errs) < 2.0, np.round(errs, 1)
    assert sum(e > 4.1 for e in errs) <= 4, np.round(errs, 1)
