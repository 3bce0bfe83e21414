"""Studies over many runs: parameter sweeps on Dask, calibration, joint calibration, the repose-angle study."""
