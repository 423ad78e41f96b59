"""controller.vision."""
