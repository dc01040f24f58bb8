"""One run: the loop, its spec and plan, observers, the record, honest endings,
the laser mount and on-line localization.

Internal: what a plugin may use is exported by `robotexp`."""
