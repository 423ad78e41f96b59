"""controller.stereo."""
