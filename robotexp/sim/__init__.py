"""robotexp.sim."""
