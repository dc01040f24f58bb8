"""robotexp.mapping."""
