"""drivers.abb."""
