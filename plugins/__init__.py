"""Built-in explorer plugins of robotexp, registered through the robotexp.explorers entry point."""
