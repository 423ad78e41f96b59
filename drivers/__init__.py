"""seamguide drivers: everything that touches the outside world (robot link, cameras, simulators)."""
