"""controller.path."""
