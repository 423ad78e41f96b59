"""drivers.sim."""
