"""A neutral wide look for the simulator's tests: every optional phenomenon off, so that a test
switches on the one it checks."""

NEUTRAL = dict(bow_mm=0.0, ragged_mm=0.0, taper=0.0, tilt_a_rad=0.0, tilt_b_rad=0.0,
               key_shadow=(), ring_glare=0.0, jpeg_quality=0, scanner_dots=0, pens=0,
               pen_cross=False, step_shadow_mm=0.0, corner_mm=0.0, cast_bgr=None, tacks=0,
               spatter=0, ground_mm=(0.0, 0.0), rust=0.0, pits=0.0, spot=0.0, table="plain",
               standoff_mm=350.0, gap_contrast=0.95, face_a=0.05, face_b=0.05)
