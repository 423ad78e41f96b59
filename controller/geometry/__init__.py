"""controller.geometry."""
