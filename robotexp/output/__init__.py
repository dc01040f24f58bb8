"""What a run leaves behind: results files, figures, map images, video frames,
path files and fault-tolerant file writes.

Internal: what a plugin may use is exported by `robotexp`."""
