"""The pile cases of rollingdem validate at their quick sizes (slow: minutes each).

They assert the cases' own physics checks: EPSD's translational kinetic energy ends two decades
below CDT's chatter floor, a twisting model removes the spin, and the repose
angle grows with mu and mu_r. The default suite covers the pieces: the angle measurement on
synthetic piles (test_analysis.py), the statistics and the report (test_validate.py).
"""

import pytest

from rollingdem.cases.repose import angle_of_repose, repose_sweep

pytestmark = pytest.mark.slow

def test_angle_of_repose_quick(tmp_path):
    result = angle_of_repose(quick=True, outdir=tmp_path)
    failed = [c.as_dict() for c in result.checks if not c.passed]
    assert not failed, failed
    assert len(result.checks) == 2
    # a pile of 1000 spheres of Table 1 material with mu_r = 0.2 stands at 10-35 degrees (report, PFC)
    epsd = result.table.set_index("model").loc["epsd", "repose angle (deg)"]
    assert 10.0 < epsd < 35.0

def test_repose_sweep_quick(tmp_path):
    result = repose_sweep(quick=True, outdir=tmp_path)
    failed = [c.as_dict() for c in result.checks if not c.passed]
    assert not failed, failed
    assert (tmp_path / "repose_sweep_runs.csv").exists()
