"""robotexp.lua."""
