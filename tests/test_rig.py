"""The MuJoCo rigs against the analytic model (paper Eqs. 2 and 9)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from efam_mujoco import load_muscle, rig

PSI = 6894.757293168361
PAPER_PRESSURES = [p * PSI for p in (15, 30, 45, 60, 75)]
TABLE4_LAWS = ("linear", "polynomial", "exponential_decay", "exponent")
MODELS = Path(__file__).resolve().parents[1] / "models"


@pytest.mark.parametrize("preset", ["FAM1", "FAM2"])
@pytest.mark.parametrize("law", TABLE4_LAWS)
def test_blocked_force_is_eq9(preset, law):
    muscle = load_muscle(preset, law)
    for p in PAPER_PRESSURES:
        eq9_push = -muscle.blocked_tension(p)
        assert rig.blocked_push(muscle, p) == pytest.approx(eq9_push, rel=0.005)


@pytest.mark.parametrize("preset", ["FAM1", "FAM2"])
@pytest.mark.parametrize("law", TABLE4_LAWS)
def test_free_extension_is_root_of_eq2(preset, law):
    muscle = load_muscle(preset, law)
    for p in PAPER_PRESSURES:
        analytic = muscle.free_extension(p)
        assert rig.free_extension(muscle, p) == pytest.approx(analytic, rel=0.005)


def test_loaded_rig_balances_the_load():
    muscle = load_muscle("FAM1")
    p, load = 300e3, 40.0  # a 40 N weight on an upright muscle at 300 kPa
    # independent root: push(P, L) = load between rest and free length
    expected = brentq(lambda L: muscle.push(p, L) - load, muscle.rest_length_m, muscle.free_length(p))
    assert rig.equilibrium_length(muscle, p, load_N=load) == pytest.approx(expected, rel=0.002)


def test_stroke_rig_reads_eq2_along_the_stroke():
    muscle = load_muscle("FAM2", "exponent")
    lengths = muscle.rest_length_m * np.linspace(1.0, 1.9, 7)
    np.testing.assert_allclose(
        rig.stroke_forces(muscle, 310e3, lengths), muscle.push(310e3, lengths), rtol=1e-9
    )


@pytest.mark.parametrize("mode", rig.MODES)
def test_committed_models_match_the_builder(mode):
    committed = (MODELS / f"rig_{mode}_fam1.xml").read_text()
    assert committed == rig.rig_xml(load_muscle("FAM1"), rig.RigOptions(mode=mode))


def test_bad_rig_options():
    with pytest.raises(ValueError, match="rig mode 'bench'"):
        rig.RigOptions(mode="bench")
    with pytest.raises(ValueError, match="pressure_lag_s"):
        rig.RigOptions(pressure_lag_s=-0.1)
