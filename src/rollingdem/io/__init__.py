"""Input and output: case files, mapping files, and what a run writes (time series, snapshots, checkpoints)."""
