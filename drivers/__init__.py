"""seamguide drivers: all that touches the outside world (robot link, cameras, simulators)."""
