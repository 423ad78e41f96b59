"""drivers.mock."""
