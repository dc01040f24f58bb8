"""Real-robot backends of robotexp: P3-DX (ARIA), Kobuki and MAVLink rovers."""
