"""``diagnose`` on any test protocol (a small version of bench/bench_diagnose.py), and its parts:
the segmentation of protocols it was not developed with, the probabilities, the data-driven
correction and the next-experiment design. Truths come from ``diagnose.virtual_bench`` (written
independently of the library, in other functional forms)."""

import dataclasses
import math

import mujoco
import numpy as np
import pytest
from test_diagnose_refit import _regulated  # the first-order regulator the re-fit tests drive

from efam_mujoco import load_muscle
from efam_mujoco.diagnose import diagnose
from efam_mujoco.diagnose import virtual_bench as V
from efam_mujoco.diagnose.confidence import (
    OUTSIDE,
    best_effect_z,
    block_sse,
    bootstrap,
    head_to_head,
    insample_supported,
    named_physics_probability,
    none_probability,
    paired_log_z,
    paired_z,
    separation,
    verdict,
    why_ambiguous,
)
from efam_mujoco.diagnose.design import candidates, recommend, unabsorbed
from efam_mujoco.diagnose.effects import BraidCompliance, Context, EffectModel, Viscoelasticity
from efam_mujoco.diagnose.model import _deadband_hi, refit
from efam_mujoco.diagnose.report import rig_with_effects
from efam_mujoco.diagnose.segment import label
from efam_mujoco.diagnose.synth import synthesize
from efam_mujoco.recordings import Recording


def _labels(t, L, P, rest):
    return label(t, L / rest - 1, P, [0])


# ------------------------------------------------------------------------------ segmentation
def test_sine_strokes_that_never_return_to_rest_split_into_their_half_cycles():
    # 6 periods of a sine about 30 % strain, amplitude 10 %: the strain never comes near 0
    rest = 0.17
    t = np.arange(0, 60, 0.02)
    x = 0.3 + 0.1 * np.sin(2 * np.pi * t / 10)
    rng = np.random.default_rng(1)
    P = np.full_like(t, 300e3) + rng.normal(0, 700, len(t))
    lab = _labels(t, rest * (1 + x) + rng.normal(0, 1e-5, len(t)), P, rest)
    n_half = lab.half_cycle.max() + 1
    assert 11 <= n_half <= 13  # 12 monotone runs (the first quarter joins the first)
    assert lab.n_folds == 5
    # every fold holds lengthening and shortening samples
    for k in range(5):
        d = lab.direction[lab.fold == k]
        assert (d > 0).any() and (d < 0).any()


def test_isometric_ramps_at_several_lengths_are_pressure_half_cycles_not_strokes():
    # three held lengths; at each a pressure ramp 0 -> 400 -> 0 kPa; the length changes at 0 kPa
    rest = 0.17
    tb = [0, 5, 10, 15, 35, 55, 60, 65, 85, 105, 110, 115, 135, 155, 160]
    Lb = [1.0, 1.0, 1.1, 1.1, 1.1, 1.1, 1.1, 1.25, 1.25, 1.25, 1.25, 1.4, 1.4, 1.4, 1.4]
    Pb = [0, 0, 0, 0, 400e3, 0, 0, 0, 400e3, 0, 0, 0, 400e3, 0, 0]
    t = np.arange(0, 160, 0.05)
    rng = np.random.default_rng(2)
    L = rest * np.interp(t, tb, Lb) + rng.normal(0, 1e-5, len(t))
    P = np.interp(t, tb, Pb) + rng.normal(0, 700, len(t))
    lab = _labels(t, L, P, rest)
    ramps = [
        h
        for h in range(lab.half_cycle.max() + 1)
        if np.all(lab.driver[(lab.half_cycle == h) & lab.moving] == 1)
    ]
    assert len(ramps) == 6  # three ramps up, three down
    # held out: whole half-cycles, not slices of one test
    assert "whole half-cycles" in lab.folds_rule
    # the pressure ramps are not taken for holds or strokes
    assert np.mean(lab.driver[lab.moving & (P > 50e3)] == 1) > 0.99


def test_dead_band_bound_does_not_depend_on_the_lowest_pressure_plateau():
    ramp = np.linspace(0, 500e3, 1000)  # a ramp passes through any dead band
    assert _deadband_hi(ramp) > 200e3


@pytest.mark.parametrize("seed", [11, 12])
def test_a_load_cell_zero_is_left_to_the_residual_not_bent_into_the_law(seed):
    # a clean stroke test at five pressures read through a load cell zeroed 6 N off: the
    # re-fitted law must still be the muscle's force, leaving the 6 N for ``force_offset``
    # (a law fitted without the zero as a nuisance takes it up where the muscle carries load)
    clean, truth = synthesize(seed, "none")
    shifted = Recording(clean.time_s, clean.length_m, clean.pressure_Pa, clean.force_N + 6.0)
    law = refit(load_muscle(truth.base_name), [shifted]).muscle.push(clean.pressure_Pa, clean.length_m)
    assert abs(np.mean(shifted.force_N - law) - 6.0) < 0.3
    assert np.sqrt(np.mean((law - clean.force_N) ** 2)) < 1.5 * truth.noise_N


def test_every_law_is_offered_the_zero_not_only_the_best_plain_fit():
    # a 6.9 N load-cell zero on pressure staircases at two lengths (virtual bench, retired seed
    # 97205; its muscle's law is the exponent law): the polynomial law bends best around the
    # zero (1.78 N RMS alone, 1.32 N beside a zero it cannot then find); the exponent law beside
    # its zero reaches the noise. Only the best plain law was offered the zero before.
    case = V.draw_case(97205, "isometric", "single")
    recording = V.make(case)
    fitted = refit(load_muscle(case.base_name), [recording]).muscle
    left = recording.force_N - fitted.push(recording.pressure_Pa, recording.length_m)
    assert np.mean(left) == pytest.approx(case.params["force_offset"]["offset_N"], abs=0.3)
    assert np.std(left) < 1.2 * case.noise_N


def test_the_refit_reaches_the_truth_where_fit_laws_start_does_not():
    # a clean test of pressure ramps and strokes (virtual bench seed 203907; its muscle is FAM1
    # with the preset's exponential-decay law, coefficients perturbed): fit_law's start for that
    # law settles at 1.00 N RMS and was refined no further, the polynomial law won at 0.72 N and
    # left a strain-organised residual the diagnosis called 'outside_library' at p 0.97. Refined
    # from the preset as well, the law reaches the truth muscle's own error
    case = V.draw_case(203907, "mixed", "clean")
    recording = V.make(case)
    P, L, F = recording.pressure_Pa, recording.length_m, recording.force_N
    truth_rms = float(np.sqrt(np.mean((case.muscle.push(P, L) - F) ** 2)))
    fitted = refit(load_muscle(case.base_name), [recording])
    assert fitted.law == "exponential_decay"
    assert fitted.rms_N <= 1.02 * truth_rms


# ----------------------------------------------------------------------------- confidence
def test_an_effect_that_does_not_pay_in_sample_gives_its_held_out_wins_to_none():
    raw = {"none": 0.1, "drift": 0.7, "friction": 0.2}
    # drift's single fit raises the in-sample BIC (+13.6), friction's lowers it (-250)
    gated = insample_supported(raw, {"drift": 13.6, "friction": -250.0}, threshold=0.0)
    assert gated == pytest.approx({"none": 0.8, "drift": 0.0, "friction": 0.2})
    assert insample_supported(gated, {"drift": 13.6, "friction": -250.0}, threshold=0.0) == gated
    # without a BIC change (older rows, or none given) nothing moves
    assert insample_supported(raw, {"drift": None}) == raw
    assert insample_supported(raw, None) == raw


def test_a_clean_isometric_test_is_not_called_drift_for_a_held_out_win_alone():
    # clean pressure ramps at two lengths (virtual bench, retired seed 104001): in-sample every
    # hypothesis sits at the noise; held out, the model alone is 18 % above it and a drift's time
    # columns take that up (93 % of the bootstrap draws). Drift does not pay in-sample (its BIC
    # rises), so its held-out wins are not evidence: it was answered `drift` at p 0.88
    case = V.draw_case(104001, "isometric", "clean")
    d = diagnose([V.make(case)], load_muscle(case.base_name), next_experiment=False)
    assert d.decisions["drift"]["delta_bic"] > 0.0
    assert d.verdict.raw["drift"] == 0.0
    assert d.verdict.answer == "none"


def test_bootstrap_is_sure_of_a_clear_winner_and_splits_a_tie():
    rng = np.random.default_rng(0)
    n, blocks = 3000, np.repeat(np.arange(30), 100)
    noise = rng.normal(0, 1, n)
    clear = bootstrap({"none": noise + np.sin(np.arange(n) / 50), "friction": noise}, blocks)
    assert clear["friction"] > 0.99
    tie = bootstrap({"none": noise * 3, "a": noise, "b": noise * 1.001}, blocks, tie_margin=0.02)
    assert tie["a"] == pytest.approx(0.5, abs=0.01) and tie["b"] == pytest.approx(0.5, abs=0.01)
    # an effect 4.5 % under none's held-out RMS, past the 3 % relevance margin: no tie with none
    # (a tie there too split such an effect 50:50 however many blocks the data had)
    past = bootstrap({"none": noise, "friction": noise * 0.955}, blocks, tie_margin=0.02)
    assert past["friction"] > 0.99
    within = bootstrap({"none": noise, "friction": noise * 0.975}, blocks, tie_margin=0.02)
    assert within["none"] > 0.99  # inside the relevance margin, none
    v = verdict(tie, excess_cut=0.9, dd_gain=0.0, n_blocks=30)
    assert v.ambiguous and set(v.contenders) == {"a", "b"}
    assert "cannot separate" in v.words()
    # most of the excess over the noise left by the best term (cut 0.3): not the physics
    v = verdict({"none": 0.0, "a": 1.0}, excess_cut=0.3, dd_gain=0.4, n_blocks=30)
    assert v.answer == OUTSIDE


def test_paired_test_over_blocks_separates_a_real_difference_and_not_noise():
    rng = np.random.default_rng(1)
    n, blocks = 3000, np.repeat(np.arange(30), 100)
    a, b = rng.normal(0, 1, n), rng.normal(0, 1, n)
    # two models with the same error level: the held-out difference is noise, |z| small
    assert abs(paired_z(block_sse(a, blocks), block_sse(b, blocks))) < 3
    # one model misses a slow structure of 0.5 x the noise: clearly separated, in its favour
    worse = a + 0.5 * np.sin(np.arange(n) / 40)
    assert paired_z(block_sse(worse, blocks), block_sse(a, blocks)) > 4


def test_log_ratio_test_sees_an_advantage_concentrated_in_a_few_blocks():
    # a drift-like model error: 20 x the noise's mean square in 3 of 40 blocks, 30 % more in the
    # other 37; the model without it has the noise alone. The plain difference of squared errors
    # is dominated by the 3 large blocks (its spread hides the rest); the per-block log-ratio
    # counts the 40 blocks alike and sees that the second model is better in every one.
    rng = np.random.default_rng(4)
    n, blocks = 4000, np.repeat(np.arange(40), 100)
    good = rng.normal(0, 1, n)
    scale = np.where(np.isin(blocks, [3, 21, 35]), np.sqrt(20.0), np.sqrt(1.3))
    bad = rng.normal(0, 1, n) * scale
    sse_bad, sse_good = block_sse(bad, blocks), block_sse(good, blocks)
    assert abs(paired_z(sse_bad, sse_good)) < 2.5  # three blocks carry the whole difference
    # expected: mean log-ratio (37 x ln 1.3 + 3 x ln 20) / 40 = 0.47 over a standard error of
    # about 0.72 / sqrt(40) = 0.11 (the 3 large blocks dominate the spread): z ~ 4
    z_log = paired_log_z(sse_bad, sse_good)
    assert z_log > 3 and z_log > 1.5 * abs(paired_z(sse_bad, sse_good))
    assert paired_log_z(sse_good, sse_bad) == pytest.approx(-paired_log_z(sse_bad, sse_good))
    # two models with the same error level: no separation
    other = rng.normal(0, 1, n)
    assert abs(paired_log_z(block_sse(other, blocks), sse_good)) < 3


def _sine_strokes_at_300_kPa():
    """FAM1 stroked about 15 % strain (+-10 %, 10 s period) at 300 kPa for 40 s: its context, and
    the columns its own parameter corrections move over a candidate test."""
    from efam_mujoco.diagnose.model import linearise

    muscle = load_muscle("FAM1")
    t = np.arange(0, 40, 0.02)
    L = muscle.rest_length_m * (1.0 + 0.15 + 0.1 * np.sin(2 * np.pi * t / 10))
    P = np.full_like(t, 300e3)
    ctx = Context.from_recordings([Recording(t, L, P, muscle.push(P, L))], muscle)

    def absorb(t_, L_, P_):
        return linearise(muscle, P_, L_, muscle).J

    return muscle, ctx, absorb


def _friction(muscle, f0_N: float) -> EffectModel:
    return EffectModel(muscle, [("friction", {"f0_N": f0_N, "f1_N_per_MPa": 10.0, "slip_strain": 0.005,
                                              "slip_kPa": 0.0, "relax_per_s": 0.0})])  # fmt: skip


def test_a_difference_a_parameter_refit_makes_does_not_count_as_separation():
    # two models that differ only by the muscle's own parameters (a braid angle / dead band step
    # along the linearisation): whatever the raw difference, a re-fit takes it up; a friction
    # term on top of the same muscle is not taken up
    from efam_mujoco.diagnose.model import linearise

    muscle, ctx, absorb = _sine_strokes_at_300_kPa()
    lin = linearise(muscle, ctx.P, ctx.L, muscle)
    shifted = EffectModel(lin.muscle_for(0.5 * np.ones(len(lin.keep))), [])
    plain = EffectModel(muscle, [])
    friction = _friction(muscle, 5.0)
    for e in candidates(ctx, 0.01):
        t_, L_, P_ = e.sampled()
        raw = float(np.std(shifted.push(t_, L_, P_) - plain.push(t_, L_, P_)))
        if raw > 0.5:
            assert unabsorbed(shifted, plain, e, absorb) < 0.1 * raw
        moved = unabsorbed(friction, plain, e)  # a strain friction shows where strokes reverse
        if moved > 2.0:
            assert unabsorbed(friction, plain, e, absorb) > 0.2 * moved


def test_two_fits_of_one_effect_are_not_separated_by_any_experiment():
    # two fitted models that differ only in an effect's amplitude (a friction of 5 N or 2 N):
    # whatever the test, the rival's own re-fit on the joined data takes the difference up, so no
    # candidate may promise a decision; counted against the muscle's parameters alone, the
    # same pair looks decidable. A friction against a viscoelasticity stays decidable.
    from functools import partial

    from efam_mujoco.diagnose import _own_columns

    muscle, ctx, absorb = _sine_strokes_at_300_kPa()
    models = {"friction": _friction(muscle, 5.0), "friction_refit": _friction(muscle, 2.0)}
    rivals = {h: partial(_own_columns, m, muscle) for h, m in models.items()}
    naive = recommend(models, ctx, 0.01, 0.3, absorb=absorb)
    assert naive["recommended"]["expected_z"] > 3.0
    plan = recommend(models, ctx, 0.01, 0.3, absorb=absorb, rivals=rivals)
    assert max(c["expected_z"] for c in plan["candidates"]) < 0.1
    assert max(c["unabsorbed_rms_N"] for c in plan["candidates"]) < 0.01
    visco = EffectModel(muscle, [("viscoelasticity", {"k0_N": 60.0, "k1_N_per_MPa": 200.0, "tau_s": 2.0})])
    models = {"friction": _friction(muscle, 5.0), "viscoelasticity": visco}
    rivals = {h: partial(_own_columns, m, muscle) for h, m in models.items()}
    plan = recommend(models, ctx, 0.01, 0.3, absorb=absorb, rivals=rivals)
    assert plan["recommended"]["expected_z"] > 3.0


def test_each_way_round_counts_except_where_the_rival_contains_the_truth():
    from efam_mujoco.diagnose.design import directions

    assert directions("friction", "viscoelasticity") == [
        ("friction", "viscoelasticity"),
        ("viscoelasticity", "friction"),
    ]
    # none lies inside any effect (its amplitudes at 0): the effect must show where none cannot follow
    assert directions("none", "drift") == [("drift", "none")]
    assert directions("drift", "none") == [("drift", "none")]
    # a named model lies inside itself plus the data-driven correction
    assert directions("end_effects", OUTSIDE) == [(OUTSIDE, "end_effects")]


def test_a_clean_file_is_not_doubted_when_the_correction_gains_one_percent():
    # the example: none wins every draw, the held-out mean square 8 % above the noise,
    # the data-driven correction gains 1 %, not significantly: outside does not compete
    sse = {"none": np.ones(30), "friction": np.ones(30) * 1.01}
    v = verdict({"none": 1.0, "friction": 0.0}, excess_cut=0.1, dd_gain=0.01, n_blocks=30, excess=0.08,
                dd_gain_none=0.01, block_sse=sse, dd_z=0.8, dd_z_none=0.8, excess_left=0.08)  # fmt: skip
    assert v.answer == "none" and not v.ambiguous and not v.outside_supported
    assert OUTSIDE not in v.probabilities  # the maps' doubt is reported as unresolved, not as outside
    # the same file with a large, significant data-driven gain: outside competes
    v = verdict({"none": 1.0, "friction": 0.0}, excess_cut=0.1, dd_gain=0.4, n_blocks=30, excess=0.8,
                dd_gain_none=0.4, block_sse=sse, dd_z=6.0, dd_z_none=6.0, excess_left=0.8)  # fmt: skip
    assert v.probabilities[OUTSIDE] > 0.5


def test_a_significant_but_immaterial_structure_does_not_let_outside_compete():
    # the correction gains 4 % and significantly (z 5), but the model alone leaves a held-out
    # mean square only 7 % above the noise (a structure of a quarter of the noise's RMS): not
    # "structured residual above the noise"; from 20 % (half the noise's RMS) it competes
    sse = {"none": np.ones(30), "friction": np.ones(30) * 1.01}
    kwargs = dict(
        excess_cut=0.1, dd_gain=0.0, n_blocks=30, dd_gain_none=0.04, block_sse=sse, dd_z=0.0, dd_z_none=5.0
    )
    small = verdict({"none": 1.0, "friction": 0.0}, excess=0.07, excess_left=0.07, **kwargs)
    assert not small.outside_supported and OUTSIDE not in small.probabilities
    material = verdict({"none": 1.0, "friction": 0.0}, excess=0.25, excess_left=0.25, **kwargs)
    assert material.outside_supported and OUTSIDE in material.probabilities


@pytest.mark.parametrize("hz", [26.0, 30.0, 100.0, 500.0])
def test_the_errors_in_variables_column_is_the_sensor_noise_not_the_regulator(hz):
    # a regulator (second order, 1 Hz, damping 0.6, integrated finely) steps the pressure every
    # 15 s; the transducer adds 0.7 kPa of white noise. The column should follow the force error
    # that noise causes (dF/dP x noise), and the regulator's real settling should stay out of it:
    # at 26 Hz a 5-sample window spans 0.15 s and its column is more settling than noise
    # (real part / noise part 1.06, correlation with the noise term 0.61)
    muscle = load_muscle("FAM1")
    t = np.arange(0, 60, 1 / hz)
    setpoint = np.select([t < 15, t < 30, t < 45], [0.0, 300e3, 150e3], 400e3)
    wn, zeta, fine = 2 * np.pi, 0.6, 20
    p, v, P = 0.0, 0.0, np.empty_like(t)
    for i in range(len(t)):
        for _ in range(fine):
            v += (wn * wn * (setpoint[i] - p) - 2 * zeta * wn * v) / hz / fine
            p += v / hz / fine
        P[i] = p
    L = np.full_like(t, 1.2 * muscle.rest_length_m)
    noise = np.random.default_rng(1).normal(0.0, 700.0, len(t))
    real = Context(t, L, P, [0], muscle).input_noise()
    noisy = Context(t, L, P + noise, [0], muscle)
    column = noisy.input_noise()
    assert np.corrcoef(column, noisy.dF_dP() * noise)[0, 1] > 0.7
    assert np.std(real) < 0.5 * np.std(column - real)


def test_pressure_steps_do_not_swamp_the_errors_in_variables_column():
    # a valve steps the pressure between holds within one sample (48 Hz) while strokes run;
    # the transducer adds 0.7 kPa of white noise. The column is regressed on the force error
    # that noise causes: the few samples at the steps (deviations of 100 kPa) must not decide
    # its coefficient. With them in the column the coefficient was 0.03 and the correlation
    # 0.14: the column no longer took out the sensor noise's force error at all.
    muscle = load_muscle("FAM1")
    t = np.arange(0, 240, 1 / 48.0)
    P = np.array([280e3, 100e3, 520e3, 300e3])[np.minimum(t // 60, 3).astype(int)]
    L = muscle.rest_length_m * (1 + 0.25 * (1 - np.cos(2 * np.pi * t / 20)))
    noise = np.random.default_rng(3).normal(0.0, 700.0, len(t))
    noisy = Context(t, L, P + noise, [0], muscle)
    column, target = noisy.input_noise(), noisy.dF_dP() * noise
    assert 0.9 < (column @ target) / (column @ column) < 1.1
    assert np.corrcoef(column, target)[0, 1] > 0.85
    # the force error the window mean's own noise leaves: dF/dP x 0.7 kPa / sqrt(5)
    expected = np.sqrt(np.mean(noisy.dF_dP() ** 2)) * 700.0 / np.sqrt(5)
    assert noisy.input_noise_floor() == pytest.approx(expected, rel=0.1)


@pytest.mark.parametrize("seed", [94096, 94176])
def test_clean_low_rate_strokes_through_regulator_transients_raise_no_alarm(seed):
    # isobaric strokes recorded at 26-30 Hz through a second-order regulator with a ripple: the
    # pressure changes between samples are real, and the errors-in-variables column must not
    # take them for sensor noise (a 5-sample window did: "outside the library" was answered)
    case = V.draw_case(seed, "isobaric", "clean")
    recording = V.make(case)
    assert case.sample_hz < 31
    d = diagnose([recording], load_muscle(case.base_name), next_experiment=False)
    assert d.verdict.answer == "none"
    assert not d.verdict.outside_supported


def _pair_verdict(b_over_a, raw):
    """The verdict on 40 blocks where hypothesis b's held-out errors are a's times ``b_over_a``
    (and the model alone's three times a's), the bootstrap's shares ``raw``."""
    base = 1 + 0.1 * np.random.default_rng(2).random(40)
    sse = {"none": base * 3, "a": base, "b": base * b_over_a}
    return verdict(raw, excess_cut=0.9, dd_gain=0.0, n_blocks=40, block_sse=sse,
                   dd_z=0.0, dd_z_none=0.0, excess_left=0.0)  # fmt: skip


def test_two_effects_are_ambiguous_only_when_the_paired_test_cannot_separate_them():
    close = 1 + 0.02 * np.random.default_rng(3).normal(size=40)
    v = _pair_verdict(close, {"a": 0.55, "b": 0.45})
    assert v.ambiguous and set(v.contenders) == {"a", "b"}
    v = _pair_verdict(1.5, {"a": 0.7, "b": 0.3})
    assert v.answer == "a" and not v.ambiguous and v.tentative and "tentative" in v.words()


def test_an_ambiguity_says_why_the_two_are_not_told_apart():
    # the report says which of three reasons holds: both fits at the noise floor (no analysis
    # of this file can separate them), an effect too weak for the model alone, or a difference
    # in held-out RMS that sits in a few blocks; nothing when the verdict is not ambiguous
    v = _pair_verdict(1 + 0.02 * np.random.default_rng(3).normal(size=40), {"a": 0.55, "b": 0.45})
    assert v.ambiguous

    def fits(ha, ca, hb, cb):
        return [
            dict(name="a", heldout_rms_N=ha, excess_cut=ca),
            dict(name="b", heldout_rms_N=hb, excess_cut=cb),
        ]

    floor = why_ambiguous(v, fits(0.742, 0.98, 0.7421, 0.97), 1.2, 0.73)
    assert "both fits reach the noise floor (0.730 N)" in floor and "differ by 0.01%" in floor
    few = why_ambiguous(v, fits(0.70, 0.95, 0.76, 0.85), 1.2, 0.60)
    assert "differ by 8.6%" in few and "a few of them" in few
    weak = dataclasses.replace(v, contenders=["none", "b"])
    said = why_ambiguous(weak, fits(0.70, 0.95, 1.17, 0.4), 1.2, 1.1)
    assert "b lowers the held-out RMS from 1.200 N to 1.170 N (2.5%" in said and "model alone" in said
    assert why_ambiguous(dataclasses.replace(v, contenders=["a", OUTSIDE]), fits(1, 1, 1, 1), 1.2, 1.0) == ""
    assert why_ambiguous(dataclasses.replace(v, ambiguous=False), fits(1, 1, 1, 1), 1.2, 1.0) == ""


def test_a_term_ahead_of_the_library_but_mostly_doubted_is_reported_unresolved_first():
    # an outside review read "Answer (tentative): drift (p = 0.15)" with 0.81 on 'unresolved'
    rng = np.random.default_rng(2)
    base = 1 + 0.1 * rng.random(40)
    apart = {"none": base * 3, "drift": base, "viscoelasticity": base * 1.5}
    v = verdict({"drift": 0.8, "viscoelasticity": 0.2}, excess_cut=0.05, dd_gain=0.0, n_blocks=40,
                block_sse=apart, dd_z=0.0, dd_z_none=0.0, excess_left=0.0)  # fmt: skip
    assert v.tentative and v.answer == "drift" and v.probabilities["unresolved"] > v.probability
    assert v.words().startswith("Unresolved (p = ") and "best library term is drift" in v.words()


def test_a_pair_the_bootstrap_tells_apart_is_not_called_ambiguous():
    # the error one hypothesis removes sits in 3 of 40 blocks (a drift at the end of a test):
    # there the other is 25 x the noise, elsewhere both are at the noise (+-3 %). The per-block
    # log-ratio averages 37 near-zero values with 3 of ln 25 = 3.2: mean 0.24 over a standard
    # error of about 0.85 / sqrt(40) = 0.13, z ~ 1.8 < 2, its spread hides the advantage; the head-to-head bootstrap over the same blocks, weighing blocks by their error,
    # finds the first better in practically every draw: the two are told apart
    rng = np.random.default_rng(5)
    a = 1.0 + 0.03 * rng.normal(size=40)
    b = 1.0 + 0.03 * rng.normal(size=40)
    b[[37, 38, 39]] = 25.0
    sse = {"none": b * 1.2, "drift": a, "viscoelasticity": b}
    assert abs(paired_log_z(sse["viscoelasticity"], sse["drift"])) < 2.0
    assert head_to_head(sse, "drift", "viscoelasticity") < 0.01
    assert head_to_head(sse, "viscoelasticity", "drift") > 0.99
    v = verdict({"drift": 0.97, "viscoelasticity": 0.03}, excess_cut=0.3, dd_gain=0.05, n_blocks=40,
                block_sse=sse, dd_z=0.0, dd_z_none=0.0, excess_left=0.1)  # fmt: skip
    assert v.answer == "drift" and not v.confident  # the map doubts the name ...
    assert not v.ambiguous and v.tentative  # ... not the pair
    # the same pair with errors within 1 % in every block: inside the tie margin between two
    # effects, the bootstrap splits them, ambiguous
    even = {"none": a * 1.5, "drift": a, "viscoelasticity": a * (1 + 0.01 * rng.normal(size=40))}
    assert 0.2 < head_to_head(even, "drift", "viscoelasticity") < 0.8
    v = verdict({"drift": 0.55, "viscoelasticity": 0.45}, excess_cut=0.9, dd_gain=0.0, n_blocks=40,
                block_sse=even, dd_z=0.0, dd_z_none=0.0, excess_left=0.0)  # fmt: skip
    assert v.ambiguous


def test_a_runner_up_the_probabilities_rule_out_is_not_called_ambiguous():
    # an effect halves the model's error in 3 of 40 blocks (a first loading) and is no better
    # elsewhere: neither the paired test nor the head-to-head bootstrap (with the relevance
    # margin an effect must beat none by) separates the two, but the model alone stands far above
    # the noise floor, which the none map reads: p(none) is near 0, and "these data cannot
    # separate softening and none (p = 0.46 and 0.00)" says something the probabilities deny.
    # Odds of 3 decide, as between a named term and outside the library
    rng = np.random.default_rng(7)
    a = 1.0 + 0.03 * rng.normal(size=40)
    none = a.copy()
    none[[12, 25, 38]] *= 2.0
    sse = {"none": none, "softening": a * (1 + 0.01 * rng.normal(size=40))}
    assert abs(separation(sse, "softening", "none")) < 2.0
    assert 0.05 < head_to_head(sse, "softening", "none") < 0.95
    raw = {"none": 0.3, "softening": 0.7}
    far = verdict(raw, excess_cut=0.5, dd_gain=0.0, n_blocks=40, excess=0.9, block_sse=sse,
                  dd_z=0.0, dd_z_none=0.0, excess_left=0.1)  # fmt: skip
    assert far.answer == "softening" and far.probabilities["none"] < 0.01
    assert not far.confident and not far.ambiguous and far.tentative
    # the same blocks with the model alone at the noise floor: none is a live rival, ambiguous
    near = verdict(raw, excess_cut=0.5, dd_gain=0.0, n_blocks=40, excess=0.0, block_sse=sse,
                   dd_z=0.0, dd_z_none=0.0, excess_left=0.1)  # fmt: skip
    p = near.probabilities
    assert 3 * p["none"] > p[near.answer] and near.ambiguous
    assert set(near.contenders) == {"softening", "none"}


def test_a_pair_kept_together_is_the_answer_not_an_ambiguity():
    # select kept friction and pressure_lag together (the pair predicts held-out data better
    # than either alone): under p = 0.8 the answer is both, tentative; it is ambiguous only when
    # a third hypothesis is within posterior odds of 3 of the pair (maps without per-term
    # offsets: the rule, not the fitted constants, is under test)
    from efam_mujoco.diagnose.confidence import CALIBRATION

    cal = dataclasses.replace(CALIBRATION, effect_offset={})
    sse = {"none": np.full(40, 3.0), "friction": np.ones(40), "pressure_lag": np.full(40, 1.05)}
    raw = {"none": 0.0, "friction": 0.6, "pressure_lag": 0.4}
    v = verdict(raw, excess_cut=0.6, dd_gain=0.02, n_blocks=40, pair=("friction", "pressure_lag"),
                block_sse=sse, dd_z=0.0, dd_z_none=0.0, excess_left=0.1, cal=cal)  # fmt: skip
    assert v.both and set(v.contenders) == {"friction", "pressure_lag"}
    assert not v.confident and not v.ambiguous and v.tentative  # the doubt is the names', not the pair's
    assert "both needed" in v.words()
    raw3 = {"none": 0.0, "friction": 0.35, "pressure_lag": 0.3, "viscoelasticity": 0.35}
    sse3 = sse | {"viscoelasticity": np.ones(40)}
    v = verdict(raw3, excess_cut=0.6, dd_gain=0.02, n_blocks=40, pair=("friction", "viscoelasticity"),
                block_sse=sse3, dd_z=0.0, dd_z_none=0.0, excess_left=0.1, cal=cal)  # fmt: skip
    assert v.both and v.ambiguous  # pressure_lag, a third, is not told apart from the pair


def test_the_calibration_cases_have_the_benchmarks_mix():
    # the probability maps learn base rates: the calibration recordings must be drawn in the
    # benchmark's own mix of clean / one-effect / two-effect / outside cases, on their own seeds
    from collections import Counter

    bench = _bench()
    cases = bench.calibration_plan()
    seeds = [s for lo, hi in bench.CALIBRATION_SEEDS for s in range(lo, hi + 1)]
    assert [seed for seed, _, _ in cases] == seeds
    share = Counter(kind for _, _, kind in cases)
    for kind, goal in bench.MIX.items():
        assert share[kind] / len(cases) == pytest.approx(goal, abs=0.01), kind
    assert set(Counter(family for _, family, _ in cases).values()) == {len(cases) // len(V.FAMILIES)}
    # the documented run's seeds (100000+) do not overlap the calibration's
    assert not {seed for seed, _, _ in bench.plan(76, 100000)} & set(seeds)


def _bench(script: str = "bench_diagnose"):
    """``bench/<script>.py`` as a module (the benches are scripts, not part of the package)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "bench" / f"{script}.py"
    spec = importlib.util.spec_from_file_location(f"{script}_for_test", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def test_stored_calibration_rows_that_cannot_be_read_are_one_clear_error(tmp_path):
    bench = _bench()
    broken = tmp_path / "run.rows.jsonl"
    broken.write_text('{"seed": 70000, "family": "isobaric"\n')
    for path, words in ((tmp_path / "absent.rows.jsonl", "cannot read"), (broken, "not a benchmark run")):
        with pytest.raises(SystemExit) as stop:
            bench.main(["--calibrate", "--calibrate-rows", str(path)])
        assert str(path) in str(stop.value) and words in str(stop.value)


def test_a_term_that_often_stands_in_for_other_physics_gets_a_lower_physics_probability():
    # synthetic calibration rows, written here: the same measured evidence (excess cut, data-
    # driven gain) for both terms, but 'drift' wins in place of outside physics in 1 case of 2
    # and 'friction' in 1 of 10; the fitted per-term offsets must say so, and the verdict must
    # hand the stand-in's doubt to outside the library
    bench = _bench()
    rng = np.random.default_rng(11)
    rows = []
    for i in range(400):
        term = "drift" if i % 2 else "friction"
        stand_in = rng.random() < (0.5 if term == "drift" else 0.1)
        cut = float(rng.uniform(0.6, 1.0))
        rows.append({"raw": {"none": 0.0, term: 1.0}, "delta_bic": {term: -50.0}, "excess_cut": cut,
                     "dd_gain": float(rng.uniform(0, 0.1)), "kind": "outside" if stand_in else "single",
                     "truth": [] if stand_in else [term], "shows": True, "excess": 0.5, "dd_gain_none": 0.3,
                     "evidence": {}})  # fmt: skip
    rows += [{"raw": {"none": 1.0}, "delta_bic": {}, "excess_cut": 0.0, "dd_gain": 0.0, "kind": "clean",
              "truth": [], "shows": True, "excess": float(x), "dd_gain_none": 0.0, "evidence": {}}
             for x in rng.uniform(0, 0.2, 50)]  # fmt: skip
    cal = bench.fit_calibration(rows)
    assert cal.offset_ridge in bench.OFFSET_RIDGES
    assert cal.effect_offset["drift"] < 0 < cal.effect_offset["friction"]
    q_drift = named_physics_probability(0.8, 0.05, cal, "drift")
    q_friction = named_physics_probability(0.8, 0.05, cal, "friction")
    assert q_drift == pytest.approx(0.5, abs=0.12) and q_friction == pytest.approx(0.9, abs=0.06)
    # a term the calibration never saw takes no offset
    assert named_physics_probability(0.8, 0.05, cal, "softening") == named_physics_probability(0.8, 0.05, cal)
    for term, q in (("drift", q_drift), ("friction", q_friction)):
        v = verdict({"none": 0.0, term: 1.0}, excess_cut=0.8, dd_gain=0.05, n_blocks=40, cal=cal)
        assert v.probabilities[term] == pytest.approx(q) and v.physics_probability == pytest.approx(q)
        assert sum(v.probabilities.values()) == pytest.approx(1.0)


def test_the_physics_map_never_reorders_the_bootstraps_shares():
    # the map is fitted on the raw winner's measurements and term: one value for every effect,
    # so a term with a quarter of the draws and a large offset (softening) never overtakes the
    # winner with three quarters and a smaller one (a braid stretch)
    from efam_mujoco.diagnose.confidence import CALIBRATION

    assert CALIBRATION.effect_offset["softening"] > CALIBRATION.effect_offset["braid_compliance"]
    raw = {"none": 0.0, "braid_compliance": 0.75, "softening": 0.25}
    v = verdict(raw, excess_cut=0.5, dd_gain=0.1, n_blocks=40, dd_z=0.0)
    q = named_physics_probability(0.5, 0.1, CALIBRATION, "braid_compliance")
    assert v.answer == "braid_compliance" and v.physics_probability == pytest.approx(q)
    assert v.probabilities["braid_compliance"] == pytest.approx(3 * v.probabilities["softening"])


def test_none_is_less_sure_when_an_effect_comes_close_on_every_block():
    # the best effect's separation from none is the paired log-ratio z of the effect against
    # none after the relevance margin: an effect 10 % better in every block (RMS 5 %, over the
    # 3 % margin) is clearly separated; one 10 % worse is clearly not
    rng = np.random.default_rng(6)
    base = 1.0 + 0.05 * rng.random(40)
    closer = {"none": base * 1.10, "end_effects": base, "friction": base * 1.3}
    further = {"none": base, "end_effects": base * 1.10, "friction": base * 1.3}
    assert best_effect_z(closer) > 5 and best_effect_z(further) < -5
    assert best_effect_z(None) == 0.0
    from efam_mujoco.diagnose.confidence import CALIBRATION

    if CALIBRATION.dn != 0.0:  # the fitted weight says how much; its sign must be the physics'
        assert CALIBRATION.dn < 0
        assert none_probability(0.05, 0.0, effect_z=best_effect_z(closer)) < none_probability(
            0.05, 0.0, effect_z=best_effect_z(further)
        )


# ---------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def cases():
    out = {}
    for key, seed, family, kind in (
        ("clean_isometric", 811, "isometric", "clean"),
        ("clean_sinusoidal", 812, "sinusoidal", "clean"),
        ("lag_isometric", 813, "isometric", "single"),
        ("visco_sine", 814, "sinusoidal", "single"),
    ):
        case = V.draw_case(seed, family, kind)
        if key == "lag_isometric":
            case.effects = [("pressure_lag", "delay")]
        if key == "visco_sine":
            case.effects = [("viscoelasticity", "qlv")]
        recording = V.make(case)
        out[key] = (case, recording, diagnose([recording], load_muscle(case.base_name)))
    return out


@pytest.mark.parametrize("key", ["clean_isometric", "clean_sinusoidal"])
def test_clean_recordings_of_other_protocols_raise_no_alarm(cases, key):
    case, _, d = cases[key]
    assert d.answer == "none"
    assert d.effects == []
    assert d.noise_N == pytest.approx(case.noise_N, rel=0.3)


@pytest.mark.parametrize("key,effect", [("lag_isometric", "pressure_lag"), ("visco_sine", "viscoelasticity")])
def test_effects_in_other_forms_and_protocols_are_named_with_confidence(cases, key, effect):
    case, _, d = cases[key]
    assert d.candidates[0]["name"] == effect  # the best library term on held-out half-cycles
    assert d.names[0] == effect  # and the first one switched on
    if d.verdict.confident:
        assert d.answer == effect
    elif d.verdict.ambiguous:
        # a truth form the library term only approximates (a transport delay, not a first-order
        # lag) leaves structure the data-driven correction finds: the report doubts the name,
        # says with what, and proposes the experiment that would decide
        assert effect in d.verdict.contenders
        assert d.next_experiment["recommended"]["predicted_difference_rms_N"] > 0
    else:
        # or the effect leads a pair that predicts held-out data better than either alone (a
        # relaxation spectrum: one Maxwell branch and a play take its fast and slow parts), stated
        # tentatively: the doubt is about the names, not between the two
        assert d.verdict.tentative and d.answer == effect
        assert d.verdict.both or len(d.verdict.contenders) == 1
    assert d.heldout_rms_after_N < 0.6 * d.heldout_rms_before_N
    js = d.to_json()
    assert js["verdict"]["answer"] == d.answer and "held out" in js["structure"]


def test_a_relaxation_at_a_fixed_length_is_taken_by_the_bladder_branch():
    # isometric pressure ramps at three lengths with a Zener solid on the whole bladder force
    # (seed 107225 of a benchmark run). The strain branch sees nothing at a fixed length; before
    # the bladder branch the best held-out term was friction's relaxing stuck force (p 0.58,
    # ambiguous with pressure_lag)
    case = V.draw_case(107225, "isometric", "single")
    assert [name for name, _ in case.effects] == ["viscoelasticity"]
    recording = V.make(case)
    d = diagnose([recording], load_muscle(case.base_name), next_experiment=False)
    best = d.candidates[0]
    assert best["name"] == "viscoelasticity", [(c["name"], c["heldout_rms_N"]) for c in d.candidates]
    fitted = best["parameters"]
    # one relaxation time: either bladder branch may carry it (the slow one at 20 tau is the
    # same Maxwell element as the fast one at a 20 x longer tau)
    share, tau = max(
        (fitted["g_bladder"], fitted["tau_s"]),
        (fitted["g_slow_bladder"], Viscoelasticity.slow_tau(fitted["tau_s"])),
    )
    assert share > 0.02
    truth = case.params["viscoelasticity"]
    assert 0.2 < tau / truth["tau_s"] < 5.0
    assert d.answer == "viscoelasticity"


@pytest.mark.parametrize("seed", [114449, 114497], ids=["Fung QLV spectrum", "two Maxwell branches"])
def test_a_broad_relaxation_at_fixed_lengths_is_taken_by_the_slow_bladder_branch(seed):
    # isometric pressure ramps with relaxation spread over decades (seeds of the 114200 run, the
    # truths written in the virtual bench: six Maxwell branches from ~1 s to ~100 s; two at
    # 0.8-4 s and 10-60 s). With one bladder branch both were answered `friction` (p 0.89 and
    # 0.96): a broad spectrum loads and unloads almost independently of the rate, as a play does
    case = V.draw_case(seed, "isometric", "single")
    assert [name for name, _ in case.effects] == ["viscoelasticity"]
    recording = V.make(case)
    d = diagnose([recording], load_muscle(case.base_name), next_experiment=False)
    best = d.candidates[0]
    assert best["name"] == "viscoelasticity", [(c["name"], c["heldout_rms_N"]) for c in d.candidates]
    assert best["parameters"]["g_slow_bladder"] > 0.02
    assert d.answer == "viscoelasticity"


def _thread_strain(values: dict, q: np.ndarray) -> np.ndarray:
    # the braid term's thread strain as its equation writes it: b1 q + b2 q^2, q in MPa
    return values["b1_per_MPa"] * q + values["b2_per_MPa2"] * q * q


def test_the_braid_fit_spans_exactly_the_thread_strains_that_grow_with_the_load():
    # a thread under more load is not shorter: on [0, q_top] the fit basis's box (k >= 0) must
    # hold every non-decreasing quadratic strain through zero within the term's own bounds,
    # and nothing else. Checked on a dense grid of loads, not through the basis's algebra
    muscle = load_muscle("FAM1")
    t = np.linspace(0.0, 20.0, 2001)
    L = muscle.rest_length_m * (1.1 + 0.1 * np.sin(t))
    P = 300e3 + 250e3 * np.sin(0.37 * t)
    ctx = Context(t, L, P, [0], muscle)
    q_load = (
        np.maximum(P - muscle.deadband_Pa, 0.0) / 1e6 * muscle.outer_radius(L) / muscle.rest_outer_radius_m
    )
    q_top = q_load.max()
    T, lo, hi = BraidCompliance().fit_basis(ctx)
    grid = np.linspace(0.0, q_top, 401)
    rng = np.random.default_rng(11)
    for k in rng.uniform(lo, hi, size=(300, 2)):
        b1, b2 = T @ k
        strain = _thread_strain({"b1_per_MPa": b1, "b2_per_MPa2": b2}, grid)
        assert np.all(np.diff(strain) >= -1e-15) and 0.0 <= b1 <= 0.2 and -0.2 <= b2 <= 0.2
    # the other way: non-decreasing strains (a crimp that straightens, a stiffening thread)
    # are inside the box, strains that fall with the load are not
    for b1, b2 in [(0.02, -0.01), (0.05, 0.0), (0.0, 0.1), (0.03, -0.03 / (2 * q_top))]:
        k = np.linalg.solve(T, [b1, b2])
        assert np.all(k >= -1e-12) and np.all(k <= hi + 1e-12), (b1, b2, k)
    for b1, b2 in [(0.0, -0.2), (0.01, -0.05 / q_top), (-0.01, 0.05)]:
        assert np.any(np.linalg.solve(T, [b1, b2]) < 0.0), (b1, b2)


@pytest.mark.parametrize("seed", [115012, 115740], ids=["error 17.7 kPa", "error 13 kPa"])
def test_a_transducer_calibration_error_is_not_named_a_braid_stretch(seed):
    # isobaric strokes read through a pressure transducer with a calibration error (a period of
    # a sine over the pressure range, written in the virtual bench; seeds of the 115000/115600
    # runs). The braid term fitted it as threads that shorten as the load rises (b1 0,
    # b2 -0.2 per MPa^2) and was named at p 0.90 and 0.89
    case = V.draw_case(seed, "isobaric", "outside")
    assert case.names == ["sensor_nonlinearity"]
    d = diagnose([V.make(case)], load_muscle(case.base_name), next_experiment=False)
    braid = next(c for c in d.candidates if c["name"] == "braid_compliance")
    m = d.ctx.muscle
    q = np.maximum(d.ctx.P - m.deadband_Pa, 0.0) / 1e6 * m.outer_radius(d.ctx.L) / m.rest_outer_radius_m
    strain = _thread_strain(braid["parameters"], np.linspace(0.0, q.max(), 201))
    assert np.all(np.diff(strain) >= -1e-12), braid["parameters"]
    assert not (d.verdict.answer == "braid_compliance" and d.verdict.probability >= 0.8)


def test_a_crimp_that_straightens_is_still_a_braid_stretch():
    # the other side of that bound: a thread strain that rises steeply while the crimp
    # straightens and slowly after (a knee at 22 % of the top load, the virtual bench's
    # bilinear truth; seed of the 115000 run) grows with the load, and is still fitted and named
    case = V.draw_case(115267, "mixed", "single")
    assert case.effects == [("braid_compliance", "bilinear")]
    d = diagnose([V.make(case)], load_muscle(case.base_name), next_experiment=False)
    best = d.candidates[0]
    assert best["name"] == "braid_compliance"
    assert d.answer == "braid_compliance"


def test_a_long_transport_delay_is_fitted_as_a_delay():
    # pressure steps through a 50 ms regulator in shuffled order, the length switched between
    # two strains every 20 s; the muscle sees the measured pressure 0.2 s late (a long line),
    # written here with numpy's interpolation, not the library's delay. With a delay grid that
    # stopped at 0.08 s this was fitted as a 0.11 s delay plus a 0.13 s lag (held-out 4.1 N,
    # ten times the noise)
    muscle = load_muscle("FAM1")
    rng = np.random.default_rng(3)
    rest = muscle.rest_length_m
    t = np.arange(0.0, 120.0, 0.01)
    levels = rng.permutation(np.tile([100e3, 200e3, 300e3, 400e3, 500e3], 5))[:21]
    set_point = levels[(t // 6).astype(int)]
    pressure = _regulated(t, set_point, 0.05)
    wave = np.sin(2 * np.pi * t / 40.0)
    length = rest * (1.2 + 0.15 * np.sign(wave) * np.minimum(1.0, 5.0 * np.abs(wave)))
    seen = np.interp(t - 0.2, t, pressure, left=pressure[0])
    recording = Recording(
        t,
        length + rng.normal(0.0, 1e-5, len(t)),
        pressure + rng.normal(0.0, 700.0, len(t)),
        muscle.push(seen, length) + rng.normal(0.0, 0.4, len(t)),
    )
    d = diagnose([recording], muscle, next_experiment=False)
    assert d.answer == "pressure_lag" and d.names[0] == "pressure_lag"
    lag = d.effects[0]["parameters"]
    assert 0.15 < lag["delay_s"] < 0.25 and lag["tau_s"] < 0.05
    assert d.heldout_rms_after_N < 3 * 0.4


@pytest.mark.parametrize(
    "seed, family, clock, course",
    [(70182, "sinusoidal", 1.0, 0.0), (108193, "isometric", 0.0, -1.0)],
    ids=["creep under pressure", "a warm-up still building"],
)
def test_a_drift_is_named_on_its_own_clock_and_course(seed, family, clock, course):
    # the virtual bench's drifts, written there: a logarithmic creep of the bladder's rest length
    # under its pressure history, log(1 + int P / p_top dt / t0) (seed 70182, a calibration
    # recording), and a bladder modulus falling as t^1.38 (seed 108193 of a benchmark run). With
    # the wall clock's saturating course alone both were answered viscoelasticity (0.47,
    # ambiguous; 0.82, confident); the creep is now the logarithmic course on the pressure clock
    case = V.draw_case(seed, family, "single")
    assert [name for name, _ in case.effects] == ["drift"]
    recording = V.make(case)
    d = diagnose([recording], load_muscle(case.base_name), next_experiment=False)
    best = d.candidates[0]
    assert best["name"] == "drift", [(c["name"], c["heldout_rms_N"]) for c in d.candidates]
    assert (best["parameters"]["clock"], best["parameters"]["course"]) == (clock, course)
    assert d.answer == "drift" and not d.verdict.ambiguous
    if seed == 70182:
        assert d.verdict.confident
    # the warm-up is named drift with the runner-up told apart, but not at p >= 0.8 since the
    # viscoelasticity's slow bladder branch (20 tau, up to 1000 s) takes part of a slow change
    # too (p 0.41): a trade the 115000 benchmark run measured (docs/diagnosis.md)


@pytest.mark.parametrize(
    "case_id, variant",
    [
        # a known miss: long holds where the viscoelasticity's slow branch predicts the held-out
        # blocks better than the drift (1.59 N against 1.94 N) and is named at p 0.83
        pytest.param("d02", 0, marks=pytest.mark.xfail(strict=True, reason="still viscoelasticity 0.83")),
        ("d03", 0),
        ("d02", 1),
        ("d03", 1),
    ],
)
def test_a_warm_up_of_tens_of_seconds_is_fitted_as_a_drift_that_follows_its_course(case_id, variant):
    # the outside reviewer's warm-up (bench/bench_diagnose_forms.py, written without reading the
    # library): F + A (1 - exp(-t / T)), T 15-40 s. With the drift's time constant held at 30 s or
    # more, three of these four were answered viscoelasticity at p 0.83-0.90, its slow branch
    # standing in for the warm-up (d03 on both seed sets); with a floor of 10 s, d03 is answered
    # drift 0.94 on the main set and the replica's is no longer confident. On the wall clock the
    # fitted course follows the warm-up's over the test (normalised to its end value, within 0.1;
    # a saturating course's time constant 25 % off T gives 0.06-0.09, a straight line 0.36): the
    # saturating course, or the logarithmic one with a shorter time constant
    forms = _bench("bench_diagnose_forms")
    k, spec = next((k, s) for k, s in enumerate(forms.plan()) if s["id"] == case_id)
    entry, recording, _ = forms.generate_one(spec, forms.seed_of(k, variant))
    truth_tau = next(p["T_s"] for p in entry["truth_params"] if p["form"] == "warmup")
    d = diagnose([recording], load_muscle(spec["muscle"]), next_experiment=False)
    drift = next(c["parameters"] for c in d.candidates if c["name"] == "drift")
    assert not (d.answer == "viscoelasticity" and d.verdict.confident), (d.answer, d.verdict.probability)
    if drift["clock"] == 0.0:  # (on the pressure clock its time is in seconds at 1 MPa, not comparable)
        from efam_mujoco.diagnose.effects import Drift

        t = recording.time_s - recording.time_s[0]
        fitted = Drift.course(t, drift["tau_s"], drift["course"])
        warm_up = 1.0 - np.exp(-t / truth_tau)
        assert np.max(np.abs(fitted / fitted[-1] - warm_up / warm_up[-1])) < 0.1, drift


def test_the_noise_floor_never_stands_above_what_a_hypothesis_predicts():
    # a clean 30 Hz test of isobaric strokes (seed 108000 of a benchmark run): the second
    # differences read the model error at each reversal as noise, 0.62 N against a force noise of
    # 0.41 N, while the model alone predicts held-out strokes to 0.50 N
    from efam_mujoco.diagnose.effects import high_frequency_noise

    case = V.draw_case(108000, "isobaric", "clean")
    recording = V.make(case)
    d = diagnose([recording], load_muscle(case.base_name), next_experiment=False)
    residual = recording.force_N - d.predicted_before
    measured = np.hypot(high_frequency_noise(residual), d.ctx.input_noise_floor())
    assert measured > 1.15 * d.heldout_rms_before_N  # the estimate alone over-reads here
    assert d.noise_N <= min([d.heldout_rms_before_N] + [c["heldout_rms_N"] for c in d.candidates])
    assert d.noise_N > case.noise_N  # still above the force noise (the pressure's adds to it)
    assert d.answer == "none" and d.verdict.confident


def test_a_transport_delay_is_fitted_as_one(cases):
    # the truth: the pressure shifted by its delay, then a first-order fill (written in the
    # virtual bench, not with the library's term). Slow pressure changes see the mean lag of that
    # response, delay + tau; its split between the two is what a fast step would show
    case, _, d = cases["lag_isometric"]
    truth = case.params["pressure_lag"]
    fitted = {e["name"]: e["parameters"] for e in d.effects}["pressure_lag"]
    assert fitted["delay_s"] > 0.0
    mean_lag = fitted["delay_s"] + fitted["tau_s"]
    assert mean_lag == pytest.approx(truth["delay_s"] + truth["tau_s"], rel=0.25)
    # the rig the report writes carries it on MuJoCo's own ctrl delay, and compiles
    model = mujoco.MjModel.from_xml_string(rig_with_effects(d))
    assert model.actuator_delay[0] == pytest.approx(fitted["delay_s"], rel=1e-12)


def _friction_and_viscoelasticity(muscle) -> dict:
    """Two fitted hypotheses that differ in holds and rate: a pressure-scaled friction and a
    one-branch viscoelasticity, each on ``muscle``."""
    friction = EffectModel(muscle, [("friction", {"f0_N": 3.0, "f1_N_per_MPa": 10.0, "slip_strain": 0.01,
                                                   "slip_kPa": 0.0, "relax_per_s": 0.0})])  # fmt: skip
    visco = EffectModel(muscle, [("viscoelasticity", {"k0_N": 60.0, "k1_N_per_MPa": 200.0, "tau_s": 2.0})])
    return {"friction": friction, "viscoelasticity": visco}


def test_next_experiment_separates_friction_from_viscoelasticity(cases):
    # two hypotheses that differ in holds and rate: the design proposes a test where they differ
    _, _, d = cases["visco_sine"]
    plan = recommend(_friction_and_viscoelasticity(d.muscle_after), d.ctx, 5e-3, d.noise_N)
    best = plan["recommended"]
    assert best["name"] in ("long_hold", "fast")
    assert best["predicted_difference_rms_N"] > 3 * d.noise_N
    assert "noise floor" in plan["words"]
    assert isinstance(d.ctx, Context)


def test_a_test_short_of_deciding_is_repeated_until_it_decides(cases):
    # the same two hypotheses as above against a noise so large that no candidate (nor two run
    # one after the other) reaches the decision z: the design repeats the best as often as it
    # takes. Noise-dominated and with nothing recorded before, z ~ sqrt(sum of the block gaps) /
    # (2 noise), so k repeats of a test give sqrt(k) times its z
    from efam_mujoco.diagnose.design import MAX_REPEATS, MAX_TEST_S, TIMES, Z_DECIDE, experiment

    _, _, d = cases["visco_sine"]
    models = _friction_and_viscoelasticity(d.muscle_after)
    noise = d.noise_N
    while True:  # raise the noise until the best single test reaches z ~ 1-1.5
        plan = recommend(models, d.ctx, 5e-3, noise)
        if max(c["expected_z"] for c in plan["candidates"]) < 1.5:
            break
        noise *= 1.25
    best = plan["recommended"]
    single = {c["name"]: c for c in plan["candidates"]}
    assert max(c["expected_z"] for c in single.values()) < Z_DECIDE
    assert 2 <= best["repeats"] <= MAX_REPEATS and best["name"].endswith(f"{TIMES}{best['repeats']}")
    assert best["duration_s"] <= MAX_TEST_S
    once = best["name"].rpartition(TIMES)[0]
    # the repeated test is the named one run k times, and its z grows as sqrt(k)
    k = best["repeats"]
    assert experiment(best["name"], d.ctx, 5e-3).t[-1] == pytest.approx(best["duration_s"], rel=1e-6)
    assert best["duration_s"] == pytest.approx(k * experiment(once, d.ctx, 5e-3).t[-1], rel=0.01)
    if once in single:
        assert best["expected_z"] == pytest.approx(single[once]["expected_z"] * np.sqrt(k), rel=0.2)
    assert f"{k} times over" in best["protocol"] and "noise floor" in plan["words"]


# ---------------------------------------------------------------------- next-experiment score
def test_decision_z_predicts_the_bootstrap_win_fraction():
    # the design's expected z against the decision rule itself: 20 blocks already recorded where
    # the two hypotheses split evenly (+-D), then the new test's blocks, each adding S_k to the
    # wrong hypothesis's held-out error; the bootstrap's win fraction of the truth ~ Phi(z)
    from math import erf, sqrt

    from efam_mujoco.diagnose.design import decision_z

    rng = np.random.default_rng(5)
    for gaps in ([40.0], [10.0] * 4, [3.0, 5.0, 8.0, 20.0, 2.0, 2.0]):
        before = np.r_[np.full(10, 12.0), np.full(10, -12.0)]
        base = np.full(20 + len(gaps), 50.0)
        a = base.copy()  # the truth
        b = base.copy()
        b[:20] += before  # b is better in half the old blocks and worse in the other half
        a[:20] += 0.0
        b[20:] += gaps
        block = np.arange(len(base))
        win = bootstrap(
            {"a": np.sqrt(a), "b": np.sqrt(b)}, block, margin=0.0, draws=20000, seed=int(rng.integers(99))
        )
        z = decision_z(np.array(gaps), 0.0, before)
        assert win["a"] == pytest.approx(0.5 * (1 + erf(z / sqrt(2))), abs=0.06)


def test_decision_z_prices_the_relevance_margin_and_what_the_old_data_say():
    # an effect against none: the bootstrap weighs the effect's error 1/(1 - MIN_GAIN)^2, so in
    # each new block the truth gains S_k less that margin on the block's own error, and in the old
    # blocks it starts from what they say (here behind: the re-fit half absorbed it); the win
    # fraction of the effect in the bootstrap itself ~ Phi(z)
    from math import erf, sqrt

    from efam_mujoco.diagnose.confidence import MIN_GAIN, relevance_penalty
    from efam_mujoco.diagnose.design import decision_z

    w = relevance_penalty("braid_compliance") / relevance_penalty("none")
    assert w == pytest.approx(1 / (1 - MIN_GAIN) ** 2)
    rng = np.random.default_rng(11)
    for gaps, lead in (
        ([6.0] * 12, -1.0),
        ([9.0] * 6 + [3.0] * 6, -0.5),
        ([12.0] * 20, -2.0),
        ([4.0] * 30, 0.5),
    ):
        old = 20
        noise_sse = np.full(old + len(gaps), 50.0)  # each block's own error under the truth
        effect = noise_sse.copy()
        none = noise_sse.copy()
        none[:old] += rng.normal(lead, 3.0, old)  # the old blocks: none a little worse or better
        none[old:] += gaps
        block = np.arange(len(noise_sse))
        win = bootstrap(
            {"none": np.sqrt(none), "braid_compliance": np.sqrt(effect)}, block, draws=20000,
            seed=int(rng.integers(99)),
        )  # fmt: skip
        before = none[:old] - w * effect[:old]
        z = decision_z(np.array(gaps), 0.0, before, (w - 1) * noise_sse[old:])
        assert win["braid_compliance"] == pytest.approx(0.5 * (1 + erf(z / sqrt(2))), abs=0.06)
    # without the margin and the old blocks' lead the same test looks decisive
    assert (
        decision_z(np.array([6.0] * 12), 0.0)
        > 3
        > decision_z(
            np.array([6.0] * 12), 0.0, np.full(20, 50.0 - w * 50.0 - 1.0), np.full(12, (w - 1) * 50.0)
        )
    )


def test_decision_z_counts_a_spread_difference_more_than_the_same_in_one_block():
    from efam_mujoco.diagnose.design import decision_z

    # the same total squared difference: one block decides nothing under the bootstrap (z = 1),
    # spread over K equal blocks it gives sqrt(K) (noise-free); the noise's cross term lowers it
    assert decision_z(np.array([100.0]), 0.0) == pytest.approx(1.0)
    assert decision_z(np.full(9, 100.0 / 9), 0.0) == pytest.approx(3.0)
    assert decision_z(np.full(9, 100.0 / 9), 1.0) == pytest.approx(100 / np.sqrt(9 * (100 / 9) ** 2 + 400))


def test_two_experiments_run_one_after_the_other(cases):
    from efam_mujoco.diagnose.design import THEN, blocks_of, experiment

    _, _, d = cases["visco_sine"]
    first, second = experiment("fast", d.ctx, 5e-3), experiment("long_hold", d.ctx, 5e-3)
    both = experiment(f"fast{THEN}long_hold", d.ctx, 5e-3)
    assert both.t[-1] == pytest.approx(first.t[-1] + second.t[-1], abs=0.01)
    t, L, P = both.sampled()
    t1, L1, P1 = first.sampled()
    np.testing.assert_allclose(L[: len(t1) - 1], L1[:-1], atol=1e-9)
    np.testing.assert_allclose(P[: len(t1) - 1], P1[:-1], atol=1e-6)
    # blocks as the joint diagnosis cuts them: pieces of half-cycles up to MIN_BLOCKS in all,
    # whole half-cycles once the data already recorded have that many
    from efam_mujoco.diagnose.confidence import MIN_BLOCKS

    alone, joined = blocks_of(first, d.ctx.muscle), blocks_of(first, d.ctx.muscle, half_cycles_before=100)
    assert alone.max() + 1 >= MIN_BLOCKS
    assert 8 <= joined.max() + 1 < MIN_BLOCKS  # two pressures x two strokes each way, at least
    assert np.all(np.diff(alone) >= 0) and np.all(np.diff(joined) >= 0)


def test_data_driven_correction_sees_a_pressure_transducer_error():
    # isometric ramps read through a transducer whose error is a full sine period over the range
    # (virtual_bench's sensor_nonlinearity, outside the library): the force error is the model's
    # pressure sensitivity times an error that is a function of the pressure alone, which the
    # input-error features (bump(P) x dF/dP) describe and a pressure bump alone only approximates
    case = V.draw_case(918, "isometric", "outside")
    case.effects = [("sensor_nonlinearity", "")]
    recording = V.make(case)
    d = diagnose([recording], load_muscle(case.base_name), next_experiment=False)
    c = d.correction
    assert c.terms and any("dF/dP" in t for t in c.terms)
    assert c.heldout_rms_after_N < 0.6 * c.heldout_rms_before_N  # held out: the folds' unseen data
    assert c.heldout_rms_after_N < 1.5 * case.noise_N
    assert c.gain >= d.verdict.dd_gain  # no worse than the calibrated feature set alone


def test_a_single_ramp_is_held_out_in_interleaved_pieces_not_extrapolated():
    # one pressure ramp 0-400 kPa over 40 s and a 20 s hold at one length: one half-cycle, so it
    # is cut into pieces; every fold's pieces must be spread over the whole test (each held-out
    # piece has training data on both sides of it in pressure), not one sixth of the ramp each
    from efam_mujoco.diagnose.segment import MAX_FOLDS, PIECES_PER_FOLD

    t = np.arange(0.0, 60.0, 0.02)
    P = np.minimum(10e3 * t, 400e3)
    labels = label(t, np.full_like(t, 0.1), P, [0])
    assert "contiguous blocks" in labels.folds_rule and labels.n_folds == MAX_FOLDS
    ramp = P < 399e3
    for k in range(labels.n_folds):
        held = labels.fold == k
        assert np.count_nonzero(np.diff(held.astype(int)) == 1) + held[0] >= PIECES_PER_FOLD
        # every pressure on the ramp has training data within 40 kPa of it (20 kPa pieces)
        train_P = P[~held & ramp]
        gap = np.min(np.abs(P[ramp][:, None] - train_P[None, :]), axis=1).max()
        assert gap <= 40e3, f"fold {k}: a held-out pressure {gap / 1e3:.0f} kPa from any trained one"


@pytest.mark.parametrize("seed", [99991, 99992])
def test_a_clean_single_ramp_and_hold_raises_no_alarm(seed):
    # the blocked-force test many labs run: one pressure ramp and a hold at a fixed length, no
    # effect concealed. Held out in six contiguous blocks, the top of the ramp was predicted from
    # the bottom (and the bottom from the top) and `drift` or `outside_library` won at p 0.91-0.96
    case = V.draw_case(seed, "isometric", "clean")
    nominal = load_muscle(case.base_name)
    t = np.linspace(0.0, 60.0, 601)
    recording = V.run_plan(
        case, t, np.full_like(t, 1.1 * nominal.rest_length_m), np.minimum(10e3 * t, 400e3), 50.0, 5
    )
    d = diagnose([recording], nominal, next_experiment=False)
    assert not (d.verdict.confident and d.verdict.answer != "none"), (d.verdict.answer, d.verdict.probability)
    assert d.heldout_rms_before_N < 1.5 * d.noise_N


def test_a_stroke_before_a_long_hold_is_cut_as_finely_as_the_hold():
    # a creep test: one 10 s stroke at 300 kPa, then 115 s held at the far end. Cut by time, the
    # stroke fell in three of twenty pieces and its start was held out with no strain near it
    # left to train on; cut by progress (time plus ground covered) every fold holds a few short
    # pieces of the stroke and its training set covers the whole stroke within 10 % of the range
    from efam_mujoco.diagnose.segment import MAX_FOLDS

    t = np.arange(0.0, 130.0, 0.02)
    x = np.interp(t, [0, 5, 15, 130], [0.0, 0.0, 0.25, 0.25])
    labels = label(t, x, np.full_like(t, 300e3), [0])
    assert labels.n_folds == MAX_FOLDS
    stroke = (t > 5) & (t < 15)
    for k in range(labels.n_folds):
        held = labels.fold == k
        assert (held & stroke).any(), f"fold {k} holds none of the stroke"
        gap = np.min(np.abs(x[stroke][:, None] - x[stroke & ~held][None, :]), axis=1).max()
        assert gap <= 0.025, f"fold {k}: a held-out strain {gap:.3f} from any trained one"


def _staircase_after_the_only_stroke(rest, rng):
    """A blocked-force staircase as many labs run it: from the rest length, one stroke at zero
    pressure to 1.4 x rest (5 mm/s), then nine pressures 60-500 kPa in shuffled order, each
    held 4 s, then vented (breakpoints: time s, length m, pressure Pa)."""
    L = 1.4 * rest
    t, lengths, pressures = [0.0, 4.0], [rest, rest], [0.0, 0.0]
    steps = [((L - rest) / 5e-3, 0.0), (3.0, 0.0)]
    for p in rng.permutation(np.linspace(60e3, 500e3, 9)):
        steps += [(0.5, p), (4.0, p)]
    for dt, p in steps + [(0.5, 0.0), (4.0, 0.0)]:
        t.append(t[-1] + dt)
        lengths.append(L)
        pressures.append(p)
    return np.array(t), np.array(lengths), np.array(pressures)


def test_the_only_stroke_of_a_test_is_held_out_in_pieces_every_fold_trains_around():
    # before the staircase, the approach stroke is the test's only length change: held out whole,
    # the stroke's strain range would be predicted from data that never left one length
    from efam_mujoco.diagnose.segment import MAX_FOLDS

    rest = 0.2
    tb, Lb, Pb = _staircase_after_the_only_stroke(rest, np.random.default_rng(1))
    t = np.arange(0.0, tb[-1], 0.01)
    L, P = np.interp(t, tb, Lb), np.interp(t, tb, Pb)
    labels = _labels(t, L, P, rest)
    assert "alone covering part of the strain-pressure range" in labels.folds_rule
    assert labels.n_folds == MAX_FOLDS
    stroke = (t > 4.0) & (t < tb[2])
    x = L / rest - 1
    for k in range(labels.n_folds):
        held = labels.fold == k
        assert (held & stroke).any(), f"fold {k} holds none of the stroke"
        gap = np.min(np.abs(x[held & stroke][:, None] - x[stroke & ~held][None, :]), axis=1).max()
        assert gap <= 0.05 * np.ptp(x), f"fold {k}: a held-out strain {gap:.3f} from any trained one"


@pytest.mark.parametrize("seed", [99966, 99967])
def test_a_clean_pressure_staircase_after_its_only_stroke_raises_no_alarm(seed):
    # no effect concealed. With the approach stroke held out whole, every hypothesis extrapolated
    # the zero-pressure stiffness over 0.4 x rest from one length: held-out RMS 2.0 x the noise
    # and `outside_library` at p 1.00 on both seeds
    case = V.draw_case(seed, V.FAMILIES[seed % 4], "clean")
    V.make(case)  # draws the case's noise level
    nominal = load_muscle(case.base_name)
    t, L, P = _staircase_after_the_only_stroke(nominal.rest_length_m, np.random.default_rng(seed))
    d = diagnose([V.run_plan(case, t, L, P, 100.0, seed)], nominal, next_experiment=False)
    assert d.verdict.answer == "none", (d.verdict.answer, d.verdict.probability)
    assert d.heldout_rms_before_N < 1.2 * d.noise_N


@pytest.mark.parametrize("seed", [99981, 99982])
def test_clean_strokes_at_a_single_pressure_raise_no_alarm(seed):
    # a creep test (one stroke, then a long hold) and length steps at one pressure: no effect
    # concealed. At a single pressure a load-cell zero is one of the stress law's own force
    # changes; the re-fit took a 76 N zero beside the exponent law, set it aside, and
    # `force_offset` was named at p 0.95 (and, with the stroke held out by time, `softening` at 0.91)
    case = V.draw_case(seed, "isobaric", "clean")
    nominal = load_muscle(case.base_name)
    V.make(case)  # draws the case's noise level
    rest = nominal.rest_length_m
    t = np.arange(0.0, 130.0, 0.02)
    creep = np.interp(t, [0, 5, 15, 130], [rest, rest, 1.25 * rest, 1.25 * rest])
    steps = rest * (1 + 0.25 / 6 * np.minimum(np.floor(t / 10), 12 - np.minimum(np.floor(t / 10), 12)))
    for L in (creep, steps):
        recording = V.run_plan(case, t, L, np.full_like(t, 300e3), 50.0, seed)
        d = diagnose([recording], nominal, next_experiment=False)
        assert not (d.verdict.confident and d.verdict.answer != "none"), (
            d.verdict.answer,
            d.verdict.probability,
        )
        assert d.heldout_rms_before_N < 1.5 * d.noise_N


@pytest.mark.parametrize(
    "seed, family, kind, effect",
    [(115249, "isometric", "single", "drift"), (115012, "isobaric", "outside", "sensor_nonlinearity"),
     (115013, "isometric", "outside", "strain_bump"), (115036, "isobaric", "single", "braid_compliance")],
    ids=["thermal drift", "transducer error", "buckling bump", "braid stretch"],
)  # fmt: skip
def test_a_later_test_of_a_case_sees_the_same_rig(seed, family, kind, effect):
    # a next experiment is the same muscle on the same rig: the virtual bench's truth must not
    # move with the later test's own duration, top pressure or strain range. Causality and
    # physics say it: the noise-free force at a time, length and pressure cannot depend on how
    # long the test goes on after it, nor on the highest pressure it will reach. Before, the
    # thermal drift lost its whole share by the end of any test (a 200 s next experiment lost
    # what the case's 1000 s test did), a transducer's error followed the test's top pressure,
    # a thread stretched by its share of the test's top pressure and a buckling bump sat at a
    # percentile of the test's own strains: physics no library term can follow across tests
    case = V.draw_case(seed, family, kind)
    assert effect in case.names
    first = V.make(case)
    assert case.rig["duration_s"] == pytest.approx(first.time_s[-1] - first.time_s[0], rel=0.05)
    rest = case.muscle.rest_length_m
    span = min(case.rig["duration_s"], 600.0)
    forces = []
    for duration, top in ((0.3 * span, 200e3), (0.9 * span, 450e3)):
        t = np.arange(0.0, duration, 0.05)
        L = rest * (1.15 + 0.1 * np.sin(2 * np.pi * t / 20.0))
        P = np.where(t < 0.25 * span, 200e3, top)  # the same until 0.25 span, then another top
        truth = V.run_plan(case, t, L, P, 20.0, case.seed).meta["noise_free"]
        early = truth.time_s < 0.2 * span
        forces.append(truth.force_N[early])
    n = min(len(f) for f in forces)
    assert np.max(np.abs(forces[0][:n] - forces[1][:n])) < 0.02 + 1e-3 * np.max(np.abs(forces[1][:n]))


def test_a_load_cell_zero_at_a_single_pressure_is_not_identifiable():
    # the zero's standard error, fitted beside the law and the geometry: infinite or far above
    # the noise where every stroke is at one pressure, tiny where strokes at zero pressure (the
    # muscle slack or passive) pin it apart from the stress law's own force
    from efam_mujoco.diagnose.model import ZERO_Z, zero_standard_errors

    nominal = load_muscle("FAM1")
    rest = nominal.rest_length_m
    L = rest * (1 + 0.2 * np.abs(np.sin(np.linspace(0, 6 * np.pi, 1200))))
    rng = np.random.default_rng(1)
    for P, expect_pinned in ((np.full_like(L, 300e3), False), (np.repeat([0.0, 150e3, 300e3], 400), True)):
        F = nominal.push(P, L) + 5.0 + rng.normal(0, 0.5, len(L))
        rec = np.zeros(len(L), dtype=int)
        se = zero_standard_errors(nominal, P, L, F, np.array([5.0]), rec, nominal)
        assert (5.0 >= ZERO_Z * se[0]) == expect_pinned, se


def _strokes_begun_at_zero_pressure(rest, top, hz):
    """12 s of 0.5 Hz sine strokes about 30 % of the stroke range: the first second at zero
    pressure (still, then stretched to the mean length), then 207 kPa, then 414 kPa."""
    t = np.arange(0.0, 12.0, 1.0 / hz)
    L = rest + (top - rest) * (0.3 + 0.2 * np.sin(np.pi * (t - 1))) * np.clip((t - 0.5) / 0.5, 0, 1)
    P = np.where(t < 1, 0.0, np.where(t < 6, 206.8e3, 413.7e3))
    return t, L, P


def test_a_stroke_alone_at_zero_pressure_is_held_out_in_pieces_whatever_its_driver():
    # every half-cycle is a stroke, but only the first one goes where the others never do (a
    # stretch at zero pressure): held out whole, each fold would extrapolate the passive muscle
    # from 207 and 414 kPa; in pieces, every piece is predicted from zero-pressure neighbours
    rest, top = 0.17, 0.17 * 1.4
    t, L, P = _strokes_begun_at_zero_pressure(rest, top, 200.0)
    labels = _labels(t, L, P, rest)
    assert "alone covering part of the strain-pressure range" in labels.folds_rule
    x = L / rest - 1
    passive = (P < 1e3) & (x > 0.02)
    for k in range(labels.n_folds):
        held = labels.fold == k
        if not (held & passive).any():
            continue
        assert (passive & ~held).any(), f"fold {k}: its training set never stretched the muscle unpressurised"
        gap = np.min(np.abs(x[held & passive][:, None] - x[passive & ~held][None, :]), axis=1).max()
        assert gap <= 0.1 * np.ptp(x), f"fold {k}: a held-out passive strain {gap:.3f} from any trained one"


def test_clean_strokes_begun_at_zero_pressure_raise_no_alarm():
    # no effect concealed (seed 203044 of the other-protocols benchmark, its 1 kHz test). With
    # the first half-cycle held out whole: held-out RMS 0.75 N against a 0.44 N noise, and
    # `outside_library` at p 0.95
    seed = 203044
    case = V.draw_case(seed, V.FAMILIES[seed % 4], "clean")
    V.make(case)  # draws the case's noise level
    nominal = load_muscle(case.base_name)
    _, top = V._stroke_range(case.muscle, None)
    t, L, P = _strokes_begun_at_zero_pressure(nominal.rest_length_m, top, 1000.0)
    d = diagnose([V.run_plan(case, t, L, P, 1000.0, seed)], nominal, next_experiment=False)
    assert not (d.verdict.confident and d.verdict.answer != "none"), (d.verdict.answer, d.verdict.probability)
    assert d.heldout_rms_before_N < 1.2 * d.noise_N


def test_the_only_low_pressure_half_cycles_of_a_test_land_in_different_folds():
    # pressurise at the rest length, nine half-cycles of a sinusoid at the top pressure, vent:
    # dealt in time order alone, the first and the eleventh unit share fold 0 of 5, and the
    # other folds' training sets never see a pressure below the top
    hz = 50.0
    ramp = np.arange(0, 5, 1 / hz)
    sine = np.arange(0, 9 * 2.0, 1 / hz)  # a 4 s period: nine half-cycles of 2 s
    t = np.r_[ramp, 5 + sine, 5 + sine[-1] + 1 / hz + ramp]
    x = np.r_[np.zeros(len(ramp)), 0.15 * (1 - np.cos(np.pi * sine / 2.0)), np.full(len(ramp), 0.0)]
    x[len(ramp) + len(sine) :] = x[len(ramp) + len(sine) - 1]
    top = 300e3
    P = np.r_[top * ramp / 5, np.full(len(sine), top), top * (1 - ramp / 5)]
    labels = label(t, x, P, [0])
    assert labels.n_folds == 5
    low = P < 0.1 * top
    for k in range(labels.n_folds):
        held = labels.fold == k
        assert (low & ~held).any(), f"fold {k}: its training set has no low pressure"
    assert labels.fold[0] != labels.fold[-1]  # the pressurising and the venting ramp


def test_scoring_sees_the_effect_not_the_sensors_noise():
    """The benchmark's "does the effect show" check works on noise-free inputs: the sensors'
    noise passes into the force through Eq. 2 in every recording, clean ones too, and no
    hypothesis can take it up. On a clean file the truth muscle at the noise-free inputs
    reproduces the truth force (only the sub-sample averaging differs); at the recorded inputs it
    is off by exactly what the generator's sensor noise (700 Pa and 10 um, white) does through
    Eq. 2, one sensor at a time, added in quadrature."""
    case = V.draw_case(102050, "sinusoidal", "clean")
    rec = V.make(case)
    m = case.muscle
    P, L = case.true_pressure_Pa, case.true_length_m
    assert np.std(rec.pressure_Pa - P) == pytest.approx(700.0, rel=0.05)
    assert np.std(rec.length_m - L) == pytest.approx(1e-5, rel=0.05)

    def rms(u):
        return float(np.sqrt(np.mean(u**2)))

    by_pressure = rms(m.push(rec.pressure_Pa, L) - m.push(P, L))
    by_length = rms(m.push(P, rec.length_m) - m.push(P, L))
    assert rms(m.push(P, L) - case.true_force_N) < 0.02
    assert rms(m.push(rec.pressure_Pa, rec.length_m) - case.true_force_N) == pytest.approx(
        math.hypot(by_pressure, by_length), rel=0.05
    )
    # together large enough to pass for an effect by the old check (noisy inputs)
    assert math.hypot(by_pressure, by_length) > 0.25 * case.noise_N
    shows, left = V.identifiable(case, rec, m)
    assert left < 0.05 and not shows


def test_a_ramp_at_another_length_makes_a_hidden_tapered_end_show():
    """Scoring a next experiment on the joined data: the re-fitted law and geometry take up this
    file's tapered ends to within a quarter of the noise, but not once a pressure ramp at a held
    length joins it (the ends' force depends on pressure at fixed length differently from Eq.
    2's). The same file joined with itself changes nothing: a re-fit on repeated data is the same."""
    case = V.draw_case(102119, "mixed", "single")
    rec = V.make(case)
    nominal = load_muscle(case.base_name)
    shows, left = V.identifiable(case, rec, nominal)
    assert not shows and left < 0.25 * case.noise_N
    t = np.linspace(0.0, 60.0, 601)
    P_set = np.interp(t, [0, 5, 30, 55, 60], [0, 0, np.percentile(rec.pressure_Pa, 99), 0, 0])
    L_held = np.full_like(t, np.percentile(rec.length_m, 60))
    ramp = V.run_plan(case, t, L_held, P_set, 50.0, case.seed)
    shows_joined, left_joined = V.identifiable(case, rec, nominal, more=(ramp.meta["noise_free"],))
    assert shows_joined and left_joined > 1.5 * left
    again = V.identifiable(case, rec, nominal, more=(V._noise_free(case, rec),))
    assert again == (False, pytest.approx(left, rel=1e-3))


def test_a_nanosecond_time_base_does_not_ask_for_a_huge_smoothing_window():
    """Past --allow time-unit, a 1 ns time base asked segment.smooth for a 5e8-sample kernel:
    one convolution that ran for over ten minutes, deaf to SIGTERM. The window is at most the
    recording."""
    from efam_mujoco.diagnose import segment

    t = np.arange(3000) * 1e-9
    assert segment._window(t) <= len(t)


def test_t_optimal_weights_give_the_textbook_design_for_telling_a_curve_from_a_line():
    # the classic case (Atkinson & Fedorov 1975; Atkinson, Donev & Tobias, Optimum Experimental
    # Designs, ch. 20): the truth quadratic, the rival a straight line on [-1, 1]; what no line
    # takes up is x^2 less its projection, and the T-optimal design puts weights 1/4, 1/2, 1/4 at
    # -1, 0, 1 (the residual +-1/2 there, the criterion 1/4). Written without the package.
    from efam_mujoco.diagnose.design import t_optimal_weights

    x = np.linspace(-1.0, 1.0, 41)
    w = t_optimal_weights(x**2, [np.column_stack([np.ones_like(x), x])], iterations=2000)
    near = lambda c: w[np.abs(x - c) < 0.06].sum()  # noqa: E731
    assert near(-1.0) == pytest.approx(0.25, abs=0.02)
    assert near(0.0) == pytest.approx(0.5, abs=0.02)
    assert near(1.0) == pytest.approx(0.25, abs=0.02)
    # the criterion at these weights: the weighted least-squares residual of x^2 on (1, x)
    X = np.column_stack([np.ones_like(x), x]) * np.sqrt(w)[:, None]
    coef, *_ = np.linalg.lstsq(X, x**2 * np.sqrt(w), rcond=None)
    r = x**2 - np.column_stack([np.ones_like(x), x]) @ coef
    assert float(np.sum(w * r * r)) == pytest.approx(0.25, abs=0.01)
    # two rivals (a line; a line plus x^4): the weaker way round decides. The design for the line
    # alone leaves the second rival almost nothing to miss (x^2 ~ a + b x^4 at -1, 0, 1); the
    # maximin design keeps what the harder rival cannot take up
    from efam_mujoco.diagnose.design import t_criterion

    line = np.column_stack([np.ones_like(x), x])
    quartic = np.column_stack([np.ones_like(x), x, x**4])
    both = t_optimal_weights(x**2, [line, quartic], iterations=2000)
    for_line = t_optimal_weights(x**2, [line], iterations=2000)
    for_quartic = t_optimal_weights(x**2, [quartic], iterations=2000)
    assert t_criterion(x**2, [line, quartic], for_line) < 1e-3
    assert t_criterion(x**2, [line, quartic], both) >= 0.99 * t_criterion(x**2, [quartic], for_quartic) > 0.01


def test_the_optimal_design_holds_where_a_static_term_shows_and_travels_as_set_points():
    # a braid stretch against the model alone: a static error growing with pressure, which a
    # re-fit of the muscle's own parameters largely takes up on strokes at one pressure. The
    # optimal-design candidate holds at set points inside the recorded ranges, leaves at least as
    # much that no re-fit takes up as any fixed candidate, and its set points (which no name
    # alone rebuilds) travel with the recommendation
    from efam_mujoco.diagnose.design import FOCUSED, experiment

    muscle, ctx, absorb = _sine_strokes_at_300_kPa()
    braid = EffectModel(muscle, [("braid_compliance", {"b1_per_MPa": 0.05, "b2_per_MPa2": 0.0})])
    plan = recommend(
        {"braid_compliance": braid, "none": EffectModel(muscle, [])}, ctx, 0.01, 0.3, absorb=absorb
    )
    scored = {c["name"]: c for c in plan["candidates"]}
    assert FOCUSED in scored
    fixed = max(c["unabsorbed_rms_N"] for n, c in scored.items() if n != FOCUSED)
    assert scored[FOCUSED]["unabsorbed_rms_N"] >= fixed
    best = plan["recommended"]
    e = experiment(best["name"], ctx, 0.01, best["set_points"])
    assert e.t[-1] == pytest.approx(best["duration_s"], rel=1e-9)
    assert e.L.min() >= np.percentile(ctx.L, 1) - 1e-9 and e.L.max() <= np.percentile(ctx.L, 99) + 1e-9
    assert e.P.max() <= max(np.percentile(ctx.P, 99), 50e3) + 1e-6
    with pytest.raises(ValueError, match="set_points"):
        experiment(FOCUSED, ctx, 0.01)
    # set points that cannot be a test are refused, naming what is wrong
    sp = best["set_points"]
    with pytest.raises(ValueError, match="pressure_Pa"):
        experiment(best["name"], ctx, 0.01, dict(sp, pressure_Pa=[float("nan")] * len(sp["time_s"])))
    with pytest.raises(ValueError, match="backwards"):
        experiment(best["name"], ctx, 0.01, dict(sp, time_s=sp["time_s"][::-1]))
    with pytest.raises(ValueError, match="differ in length"):
        experiment(best["name"], ctx, 0.01, dict(sp, length_m=sp["length_m"][:-1]))


def test_the_maps_in_force_are_the_ones_fitted_on_the_stored_calibration_rows():
    """The constants in ``confidence.CALIBRATION`` are what ``bench/bench_diagnose.py
    --calibrate`` fitted last (stored with its rows): a change to the diagnosis that re-runs the
    calibration and forgets to carry its fit over would leave probabilities fitted to other
    evidence."""
    import json
    from pathlib import Path

    from efam_mujoco.diagnose.confidence import CALIBRATION

    stored = Path(__file__).resolve().parents[1] / "bench" / "results" / "diagnose_calibration.json"
    fitted = json.loads(stored.read_text())["calibration"]
    for key in ("a", "b", "c", "an", "bn", "cn", "dn", "concentration", "tie_margin", "offset_ridge"):
        assert getattr(CALIBRATION, key) == pytest.approx(fitted[key], abs=5e-4), key
    assert set(CALIBRATION.effect_offset) == set(fitted["effect_offset"])
    for term, offset in fitted["effect_offset"].items():
        assert CALIBRATION.effect_offset[term] == pytest.approx(offset, abs=5e-4), term


def _triangle_strokes_on_a_ringing_load_cell(mass_kg: float, seed: int):
    """Constant-speed strokes (strain 5-35 %, 4 s each way) at three pressures, 250 Hz, read by a
    load cell that rings at 6 Hz (damping 0.1) when the carriage's speed reverses. The ring is
    written here from its impulse response, not from the package: each reversal changes the
    speed by dv, and the cell adds m dv wn^2 / wd exp(-zeta wn s) sin(wd s), s after it."""
    muscle = load_muscle("fam1")
    rest, hz, fn, zeta = muscle.rest_length_m, 250.0, 6.0, 0.1
    half, lo, hi = 4.0, 0.05, 0.35
    t = np.arange(0.0, 3 * 3 * 2 * half, 1.0 / hz)
    phase = (t / half) % 2.0
    x = lo + (hi - lo) * np.where(phase < 1.0, phase, 2.0 - phase)
    P = np.array([200e3, 300e3, 400e3])[(t // (6 * half)).astype(int)]
    L = rest * (1.0 + x)
    speed = (hi - lo) * rest / half
    wn = 2 * math.pi * fn
    wd = wn * math.sqrt(1 - zeta**2)
    ring = np.zeros_like(t)
    for k in range(1, int(t[-1] / half) + 1):  # reversals at k * half: +v -> -v, then -v -> +v
        dv = -2 * speed if k % 2 else 2 * speed
        s = t - k * half
        ring += np.where(s > 0, mass_kg * dv * wn**2 / wd * np.exp(-zeta * wn * s) * np.sin(wd * s), 0.0)
    rng = np.random.default_rng(seed)
    force = muscle.push(P, L) - ring + rng.normal(0.0, 0.3, t.size)
    recording = Recording(t, L + rng.normal(0.0, 2e-6, t.size), P + rng.normal(0.0, 300.0, t.size), force)
    return recording, muscle, float(np.sqrt(np.mean(ring**2)))


def test_the_data_driven_correction_sees_a_load_cell_that_rings():
    # outside the library: the correction must take it up with its resonance features (the bare
    # acceleration is a spike at each reversal, the ring a decaying 6 Hz oscillation after it),
    # predict held-out blocks better, and never give it a physical name
    recording, muscle, ring_rms = _triangle_strokes_on_a_ringing_load_cell(mass_kg=5.0, seed=3)
    assert 0.3 < ring_rms < 1.0  # the ring stands above the 0.3 N noise, not far above
    d = diagnose([recording], muscle, next_experiment=False)
    c = d.correction
    assert any(term.startswith("resonance(") for term in c.terms), c.terms
    assert c.heldout_rms_after_N < 0.7 * c.heldout_rms_before_N
    assert not (d.verdict.confident and d.verdict.answer not in ("none", OUTSIDE)), d.verdict.answer
    # the same strokes on a stiff load cell: nothing to correct, no alarm
    quiet, muscle, _ = _triangle_strokes_on_a_ringing_load_cell(mass_kg=0.0, seed=3)
    d = diagnose([quiet], muscle, next_experiment=False)
    assert d.verdict.answer == "none", (d.verdict.answer, d.verdict.probability)


@pytest.mark.parametrize("hz, drive_hz", [(4.0, 1.0), (4.0, 4.0), (16.0, 30.0)])
def test_a_resonance_feature_answers_a_sine_as_its_transfer_function_says(hz, drive_hz):
    # below, at and above the resonance: the steady amplitude and phase of the filtered strain
    # against H(jw) = -w^2 wn^2 / (wn^2 - w^2 + 2 j zeta wn w) (in phase) and j w wn^3 / (...)
    # (quadrature), evaluated here from the formula, not from the filter's coefficients
    from efam_mujoco.diagnose.datadriven import RESONANCE_DAMPING, _resonance

    fs = 1000.0
    t = np.arange(0.0, 20.0, 1.0 / fs)
    w, wn = 2 * math.pi * drive_hz, 2 * math.pi * hz
    x = np.sin(w * t)
    late = t > 10.0  # the ring of the start has died out (zeta wn t >= 25)
    for quadrature, numerator in ((False, -(w**2) * wn**2), (True, 1j * w * wn**3)):
        H = numerator / (wn**2 - w**2 + 2j * RESONANCE_DAMPING * wn * w)
        expected = np.abs(H) * np.sin(w * t + np.angle(H))
        got = _resonance(x, 1.0 / fs, hz, quadrature)
        scale = np.abs(H)
        # Tustin's rule warps frequency by (w dt / 2)^2 / 3: under 0.5 % at 30 Hz and 1 kHz
        assert np.max(np.abs(got[late] - expected[late])) < 0.01 * scale, (quadrature, drive_hz)
