"""robotexp.planning."""
