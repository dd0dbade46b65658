"""The force-balance model against the paper's numbers and against analytic identities."""

import math

import numpy as np
import pytest

from efam_mujoco import LAW_NAMES, Muscle, MuscleError, StressLaw, load_muscle
from efam_mujoco.musclefile import geometry_from_dict, read_document

PSI = 6894.757293168361
PAPER_PRESSURES = np.array([15, 30, 45, 60, 75]) * PSI  # 103.4 ... 517.1 kPa
TABLE4_LAWS = ("linear", "polynomial", "exponential_decay", "exponent")


def preset_geometry(name):
    doc, label = read_document(name)
    return geometry_from_dict(doc["geometry"], label)


# --------------------------------------------------------------------- paper's derived numbers
@pytest.mark.parametrize("name, theta", [("fam1", 12.54), ("fam2", 12.73)])
def test_resting_braid_angle_eq5(name, theta):
    assert preset_geometry(name).theta_rest_deg == pytest.approx(theta, abs=0.005)


def test_bladder_length_lost_in_fittings_eq7():
    geometry = preset_geometry("fam1")
    assert geometry.bladder_length_lost_m * 100 == pytest.approx(1.372, abs=0.001)
    working = geometry.bladder_length_m - geometry.bladder_length_lost_m
    assert working * 100 == pytest.approx(16.408, abs=0.001)


def test_working_bladder_volume_eq8():
    # the paper prints 0.01692 L; Eq. 8 from its inputs gives 0.01699 L (recorded in the preset)
    assert preset_geometry("fam1").bladder_volume_m3 * 1e3 == pytest.approx(0.0169, rel=0.01)


@pytest.mark.parametrize("name", ["fam1", "fam2"])
def test_blocked_force_about_280N_at_517kPa(name):
    muscle = load_muscle(name)
    blocked = muscle.blocked_tension(75 * PSI)
    assert blocked < 0  # an EFAM pushes (paper sign: positive pulls)
    assert -blocked == pytest.approx(280.0, rel=0.015)


@pytest.mark.parametrize("name", ["fam1", "fam2"])
@pytest.mark.parametrize("law", TABLE4_LAWS)
def test_free_extension_close_to_measured_98pct(name, law):
    extension = load_muscle(name, law).free_extension(75 * PSI)
    assert 0.95 <= extension <= 1.06


@pytest.mark.parametrize("name", ["fam1", "fam2"])
def test_free_extension_grows_with_pressure_and_saturates(name):
    # paper Fig. 7b: extension rises with pressure, its increments shrink
    extension = load_muscle(name).free_extension(PAPER_PRESSURES)
    steps = np.diff(extension)
    assert np.all(steps > 0) and np.all(np.diff(steps) < 0)


@pytest.mark.parametrize("name, tau_strain", [("fam1", 0.23), ("fam2", 0.10)])
def test_exponential_decay_transient_vanishes_at_paper_strain(name, tau_strain):
    # Sec. 4.8: 1 - exp(-E4 eps) reaches 0.95 at the strains the paper quotes
    E4 = load_muscle(name, "exponential_decay").stress.coefficients[3]
    assert 3.0 / E4 == pytest.approx(tau_strain, abs=0.006)


# ------------------------------------------------------------------------- analytic identities
@pytest.mark.parametrize("law", TABLE4_LAWS)
def test_eq2_at_rest_length_is_gaylord_eq9(law):
    muscle = load_muscle("fam2", law)
    pressures = np.linspace(0, 800e3, 17)
    np.testing.assert_allclose(
        muscle.tension(pressures, muscle.rest_length_m),
        muscle.blocked_tension(pressures),
        rtol=1e-12,
        atol=1e-6,
    )


def test_eq9_without_dead_band_is_gaylord_eq1():
    muscle = load_muscle("fam1")
    theta, D, P = math.radians(muscle.theta_rest_deg), muscle.rest_diameter_m, 400e3
    gaylord = P * math.pi * D**2 / (4 * math.cos(theta) ** 2) * (3 * math.sin(theta) ** 2 - 1)
    no_deadband = Muscle(**{**_constants(muscle), "deadband_Pa": 0.0}, stress=muscle.stress)
    assert no_deadband.blocked_tension(P) == pytest.approx(gaylord, rel=1e-12)


def test_thread_winds_round_the_resting_cylinder():
    # Eqs. 3, 4, 10: B^2 = L^2 + (2 pi N R_o)^2 and R_o(L_rest) = D_rest / 2
    muscle = load_muscle("fam1")
    assert muscle.outer_radius(muscle.rest_length_m) == pytest.approx(muscle.rest_diameter_m / 2, rel=1e-12)


def test_bladder_volume_is_conserved_over_admissible_lengths():
    # Eq. 11 keeps the wall volume: pi (R_o^2 - R_i^2) L = V_B
    muscle = load_muscle("fam1")
    L = np.linspace(muscle.min_length_m, muscle.max_length_m, 50)
    r_out = muscle.outer_radius(L)
    r_in = r_out - muscle.wall_thickness(L)
    np.testing.assert_allclose(math.pi * (r_out**2 - r_in**2) * L, muscle.bladder_volume_m3, rtol=1e-9)


def test_admissible_bounds_are_where_the_bladder_fills_the_sleeve():
    muscle = load_muscle("fam1")
    for L in (muscle.min_length_m, muscle.max_length_m):
        assert muscle.wall_thickness(L) == pytest.approx(muscle.outer_radius(L), rel=1e-6)
    assert 0 < muscle.min_length_m < muscle.rest_length_m < muscle.max_length_m < muscle.thread_length_m


def test_strains_zero_at_rest():
    muscle = load_muscle("fam2")
    assert np.allclose(muscle.strains(muscle.rest_length_m), 0.0, atol=1e-15)


@pytest.mark.parametrize("law", TABLE4_LAWS)
def test_free_length_is_a_root_of_eq2(law):
    muscle = load_muscle("fam1", law)
    for p in PAPER_PRESSURES:
        L = muscle.free_length(p)
        assert muscle.rest_length_m < L < muscle.max_length_m
        stiffness = abs(muscle.tension(p, L * 1.001) - muscle.tension(p, L * 0.999)) / (0.002 * L)
        assert abs(muscle.tension(p, L)) < 1e-9 * stiffness * L


def test_dead_band_pressure_term_never_negative():
    muscle = load_muscle("fam1")
    below = np.linspace(0, muscle.deadband_Pa, 7)
    # at rest no strain, no pressure term: no force below the dead band
    np.testing.assert_allclose(muscle.tension(below, muscle.rest_length_m), 0.0, atol=1e-9)
    # extended below the dead band the bladder only pulls back
    assert np.all(muscle.tension(below, 1.5 * muscle.rest_length_m) > 0)
    assert muscle.free_length(0.5 * muscle.deadband_Pa) == muscle.rest_length_m


def test_negative_pressure_is_taken_as_zero():
    muscle = load_muscle("fam1")
    L = 1.3 * muscle.rest_length_m
    assert muscle.tension(-200e3, L) == muscle.tension(0.0, L)


def test_force_is_linear_in_pressure_above_dead_band_for_linear_law():
    # Eq. 2 with Eq. 15 is affine in P: equal steps give equal force steps
    muscle = load_muscle("fam1", "linear")
    forces = muscle.tension(np.array([200e3, 300e3, 400e3]), 0.25)
    assert forces[2] - forces[1] == pytest.approx(forces[1] - forces[0], rel=1e-10)


# ------------------------------------------------------------------------------ contractile
def contractile_muscle(**kw):
    stress = StressLaw("linear", (2e6, 1.0))
    args = dict(rest_length_m=0.2, rest_diameter_m=0.02, theta_rest_deg=60.0, bladder_volume_m3=3e-6)
    args.update(kw)
    return Muscle(**args, deadband_Pa=20e3, stress=stress)


def test_contractile_muscle_pulls_and_shortens():
    muscle = contractile_muscle()
    assert muscle.kind == "contractile"
    assert muscle.blocked_tension(500e3) > 0
    assert muscle.free_length(500e3) < muscle.rest_length_m


def test_blocked_force_changes_sign_at_35_26_degrees():
    below = contractile_muscle(theta_rest_deg=35.0).blocked_tension(300e3)
    above = contractile_muscle(theta_rest_deg=35.5).blocked_tension(300e3)
    assert below < 0 < above


def test_tension_only_muscle_never_pushes():
    muscle = Muscle(
        **_constants(contractile_muscle()), stress=StressLaw("linear", (2e6, 1.0)), tension_only=True
    )
    L = np.linspace(0.5 * muscle.rest_length_m, 1.2 * muscle.rest_length_m, 40)
    assert np.all(muscle.tension(500e3, L) >= 0)
    assert muscle.tension(0.0, 0.6 * muscle.rest_length_m) == 0.0  # slack


# ------------------------------------------------------------------- documented edge behaviour
@pytest.mark.parametrize("law", LAW_NAMES[:4])
def test_outside_admissible_range_force_is_finite_and_locks(law):
    muscle = load_muscle("fam1", law)
    k = muscle.lock_stiffness_N_per_m
    hi, lo = muscle.max_length_m, muscle.min_length_m
    f_hi = muscle.tension(500e3, hi)
    assert muscle.tension(500e3, hi + 0.01) == pytest.approx(f_hi + k * 0.01, rel=1e-12)
    f_lo = muscle.tension(500e3, lo)
    assert muscle.tension(500e3, lo - 0.01) == pytest.approx(f_lo - k * 0.01, rel=1e-12)
    assert np.isfinite(muscle.tension(500e3, -1.0))


def test_non_finite_inputs_give_zero_force():
    muscle = load_muscle("fam1")
    assert muscle.tension(np.nan, 0.2) == 0.0
    assert muscle.tension(300e3, np.inf) == 0.0
    assert np.all(muscle.tension(np.array([np.nan, 3e5]), np.array([0.2, np.nan])) == 0.0)


def test_push_is_minus_tension():
    muscle = load_muscle("fam1")
    assert muscle.push(400e3, 0.2) == -muscle.tension(400e3, 0.2)


@pytest.mark.parametrize(
    "key, value",
    [
        ("rest_length_m", -0.1),
        ("rest_diameter_m", 0.0),
        ("theta_rest_deg", 95.0),
        ("bladder_volume_m3", -1e-6),
        ("deadband_Pa", -5.0),
        ("rest_length_m", float("nan")),
    ],
)
def test_impossible_constants_are_named(key, value):
    base = _constants(load_muscle("fam1"))
    base[key] = value
    with pytest.raises(MuscleError, match=key):
        Muscle(**base, stress=StressLaw("linear", (1.7e6, 1.5)))


def test_bladder_too_big_for_sleeve_is_rejected():
    base = _constants(load_muscle("fam1"))
    base["bladder_volume_m3"] = 5e-4
    with pytest.raises(MuscleError, match="bladder"):
        Muscle(**base, stress=StressLaw("linear", (1.7e6, 1.5)))


def _constants(muscle):
    return dict(
        rest_length_m=muscle.rest_length_m,
        rest_diameter_m=muscle.rest_diameter_m,
        theta_rest_deg=muscle.theta_rest_deg,
        bladder_volume_m3=muscle.bladder_volume_m3,
        deadband_Pa=muscle.deadband_Pa,
    )


@pytest.mark.parametrize(
    "change, words",
    [
        ({"tension_only": "false"}, "'tension_only' must be True or False"),  # a true string: pushed 0 N
        ({"rest_length_m": "0.17"}, "'rest_length_m' must be a number"),  # was a '>' TypeError
        ({"rest_length_m": True}, "'rest_length_m' must be a number"),  # was a 1 m muscle
        ({"stress": "exponential_decay"}, "'stress' must be a StressLaw"),  # was an AttributeError
        ({"name": 3}, "'name' must be a string"),
        # values the plugin and the muscle-file reader refuse (a 170 m muscle's free length was
        # 453 m; a 5 MPa dead band never inflates; 1e15 N/m pushed -2.3e14 N)
        ({"rest_length_m": 170.0}, r"'rest_length_m' is invalid: 170.0 \(.*was it in mm\?\)"),
        ({"deadband_Pa": 5e6}, r"'deadband_Pa' is invalid: .*was it in kPa\?"),
        ({"lock_stiffness_N_per_m": 1e15}, r"'lock_stiffness_N_per_m' is invalid: .*0 \.\. 1e9 N/m"),
    ],
)
def test_muscle_constructor_refuses_wrong_types_naming_the_field(change, words):
    from dataclasses import replace

    from efam_mujoco.muscle import MuscleError

    with pytest.raises(MuscleError, match=words):
        replace(load_muscle("FAM1"), **change)
