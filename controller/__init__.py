"""seamguide controller: the weld cycle, the CLI and the guidance maths."""
