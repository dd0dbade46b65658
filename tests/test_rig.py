"""The MuJoCo rigs against the analytic model (paper Eqs. 2 and 9)."""

import warnings
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
    # each was accepted: MuJoCo took a NaN mass as its default, ran a negative timestep or damping,
    # and a NaN top pressure was blamed on min_pressure_Pa
    for field, value in [("timestep_s", -1.0), ("timestep_s", 0.0), ("timestep_s", float("nan")),
                         ("damping_Ns_per_m", -100.0), ("plate_mass_kg", float("nan")),
                         ("max_pressure_Pa", float("nan"))]:  # fmt: skip
        with pytest.raises(ValueError, match=f"RigOptions.{field}"):
            rig.RigOptions(**{field: value})


def test_a_law_infinitely_stiff_at_rest_settles_in_its_limit_cycle(capsys):
    """The exponent law (E3 < 1) has an unbounded slope at zero strain: vented, the plate keeps a
    limit cycle of tens of nm about the resting length instead of stopping. That is settled (the
    muscle at rest, free extension 0), not 'rig did not settle'."""
    from efam_mujoco.cli import main

    muscle = load_muscle("FAM2", law="exponent")
    assert rig.equilibrium_length(muscle, 0.0) == pytest.approx(muscle.rest_length_m, rel=1e-6)
    assert main(["muscle", "FAM2", "--stress", "exponent", "--pressures-kPa", "0", "10"]) == 0
    assert "did not settle" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "call, words",
    [
        # MuJoCo zeroes a NaN control: the answer was the no-load length
        (lambda m: rig.equilibrium_length(m, 200e3, load_N=float("nan")), "load_N must be a finite number"),
        # far beyond what the muscle holds: MuJoCo reset the run and the answer was the rest length
        (
            lambda m: rig.equilibrium_length(m, 200e3, load_N=1e9),
            "went unstable .* under a load of 1e\\+09 N",
        ),
        (lambda m: rig.equilibrium_length(m, 200e3, max_time_s=float("nan")), "max_time_s"),
        (lambda m: rig.stroke_forces(m, 200e3, [float("nan")]), "lengths_m"),  # was 0 N
        (lambda m: rig.stroke_forces(m, 200e3, [-1.0]), "lengths_m"),  # was -2.2e7 N
        (lambda m: rig.stroke_forces(m, 200e3, [[0.17, 0.18]]), "1-D"),
        (lambda m: rig.stroke_forces(m, 200e3, [0.17], settle_s=-1), "settle_s"),
    ],
)
def test_rig_refuses_inputs_that_gave_plausible_looking_wrong_answers(call, words):
    with pytest.raises(ValueError if "unstable" not in words else RuntimeError, match=words):
        call(load_muscle("FAM1"))


@pytest.mark.parametrize(
    "effects", ["friction", [("friction",)], [("bogus",)], [{"name": "friction"}], ["friction"]]
)
def test_effects_that_are_not_name_parameter_pairs_are_refused_by_name(effects):
    # a bare 'friction' was unpacked into its letters ("not enough values to unpack (expected 2,
    # got 1)"), ('bogus',) said "too many values to unpack"
    with pytest.raises(ValueError, match=r"effects must be (a list of )?\(name, parameters\) pairs"):
        rig.stroke_forces(load_muscle("FAM1"), 3e5, [0.2], effects=effects)


def test_a_rig_that_goes_unstable_with_no_load_blames_the_muscle_not_a_load():
    """Before: a braid angle of 85.5 deg (a sleeve angle of 89 deg in the geometry) loaded, and
    the free rig's divergence said 'under a load of 0 N: ... or a load in the wrong unit'."""
    from dataclasses import replace

    steep = replace(load_muscle("FAM1"), theta_rest_deg=85.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MuJoCo's own warning, said again in the error
        with pytest.raises(
            RuntimeError, match=r"went unstable at 200000 Pa with no load .*braid angle 85\.5 deg"
        ) as err:
            rig.equilibrium_length(steep, 200e3)
    assert "load in the wrong unit" not in str(err.value)
