"""controller.cell."""
