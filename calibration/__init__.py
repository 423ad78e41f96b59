"""seamguide calibration: camera intrinsics, hand-eye and the calibration file format."""
