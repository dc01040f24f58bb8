"""robotexp.world."""
