"""``diagnose`` on real Festo DMSP recordings (skips when ../shared, or $EFAM_SHARED_DIR, is absent)."""

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
from shared_data import festo_dir  # noqa: E402

sys.path.pop(0)
DATA = festo_dir()

pytestmark = pytest.mark.skipif(not (DATA / "recordings.json").exists(), reason="real Festo data absent")


def test_festo_hysteresis_is_found_and_held_out_error_falls():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import festo_diagnose as fd
    finally:
        sys.path.pop(0)
    meta = json.loads((DATA / "recordings.json").read_text())
    key = "dmsp10_cut20cm"
    row = fd.run_group(key, fd.groups(meta)[key], meta, make_figures=False)
    named = [e["name"] for e in row["effects"]]
    # a direction-dependent term (pressurising vs venting) is among the named effects
    assert set(named) & set(fd.HYSTERESIS_EFFECTS)
    # the load cell's zero, left in the data on purpose, is found, per file
    assert "force_offset" in named
    assert row["heldout_rms_after_N"] < 0.7 * row["heldout_rms_before_N"]
    for e in row["effects"]:
        assert e["heldout_rms_after_N"] < e["heldout_rms_before_N"]
    # the "slow hysteresis" of the rest-length file: the tension in the final low-pressure hold
    # after venting stands above the rising branch at that pressure when the rising branch is read
    # during the regulator's fast first step; the named terms (the pressure lag) replay that gap.
    # Against the settled plateaus of the rising branch no gap of that size remains.
    (hold,) = row["slow_hysteresis"]
    assert hold["file"].endswith("kink0.csv")
    measured, after = hold["gap_vs_all_rising_measured_N"], hold["gap_vs_all_rising_model_after_N"]
    assert 2.0 < measured < 25.0
    assert 0.5 * measured < after < 2.0 * measured  # the right sign and size (the model alone: below half)
    assert abs(hold["gap_vs_all_rising_model_before_N"]) < 0.5 * measured  # the model alone does not
    assert abs(hold["gap_measured_N"]) < 3.0
    assert hold["hold_heldout_rms_after_N"] < 0.5 * hold["hold_heldout_rms_before_N"]
    assert "half-cycles" in row["structure"]
