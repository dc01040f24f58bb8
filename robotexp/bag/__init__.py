"""Runs as ROS 2 bags in MCAP: the recorder (`robotexp.bag.recorder.BagRecorder`, a run observer),
the replay (`robotexp.bag.replay`) and the commands `robotexp replay` and `robotexp video`
(`robotexp.cli.bag`). Import the submodules: this package imports nothing heavy itself."""
