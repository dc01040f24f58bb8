"""Kits for plugin and backend authors' own test suites (importing this package imports no test runner)."""
