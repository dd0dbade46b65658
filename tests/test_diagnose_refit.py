"""The re-fit that comes before any effect is named (``diagnose.model``): the pressure it fits
the law to, and what one slow stroke at one pressure, a protocol a lab often runs first, gets
from it. Truths are ``Muscle.push`` on the true pressure, with sensors added here (not the
virtual bench's)."""

import numpy as np
import pytest

from efam_mujoco import load_muscle
from efam_mujoco.diagnose import diagnose
from efam_mujoco.diagnose.model import denoised_pressure
from efam_mujoco.recordings import Recording

PRESSURE_NOISE_PA = 700.0


def _regulated(t, set_point, tau_s):
    """A first-order regulator following ``set_point`` (exact for a set point held per step)."""
    out = np.empty_like(set_point)
    out[0] = set_point[0]
    a = 1.0 - np.exp(-np.diff(t) / tau_s)
    for k in range(1, len(t)):
        out[k] = out[k - 1] + a[k - 1] * (set_point[k] - out[k - 1])
    return out


def _rise_time(t, u, lo, hi):
    """Seconds from 10 % to 90 % of a rise from ``lo`` to ``hi`` (first crossings)."""
    a = lo + 0.1 * (hi - lo)
    b = lo + 0.9 * (hi - lo)
    return t[np.argmax(u >= b)] - t[np.argmax(u >= a)]


def test_denoised_pressure_averages_a_hold_and_keeps_a_step_and_a_ramp():
    t = np.arange(0.0, 40.0, 0.01)
    set_point = np.where(t < 5.0, 0.0, 300e3) + np.clip((t - 20.0) * 10e3, 0.0, 100e3)
    true = _regulated(t, set_point, 0.05)
    rng = np.random.default_rng(5)
    measured = true + rng.normal(0.0, PRESSURE_NOISE_PA, len(t))
    flat = np.full(len(t), 0.2)
    smooth = denoised_pressure(Recording(t, flat, measured, np.zeros(len(t))))

    def rms(mask):
        return float(np.sqrt(np.mean((smooth[mask] - true[mask]) ** 2)))

    hold = (t > 6.0) & (t < 19.0)
    ramp = (t > 21.0) & (t < 29.0)
    # a hold: the noise averaged down more than five times (a 2 s window: 14 times)
    assert rms(hold) < PRESSURE_NOISE_PA / 5
    # a ramp: a centred mean is exact on it, so it is averaged too and not biased
    assert rms(ramp) < PRESSURE_NOISE_PA / 2
    assert abs(float(np.mean(smooth[ramp] - true[ramp]))) < 100.0
    # the regulator's step (a 110 ms rise) keeps its rise within 30 ms
    step = (t > 4.0) & (t < 6.0)
    rise_true = _rise_time(t[step], true[step], 0.0, 300e3)
    rise_smooth = _rise_time(t[step], smooth[step], 0.0, 300e3)
    assert abs(rise_smooth - rise_true) < 0.03
    # and no sample of the step strays from the truth by more than a tenth of the step height
    assert np.max(np.abs(smooth[step] - true[step])) < 30e3
    # a pressure held exactly (no noise at all) is returned as measured
    held = np.full(len(t), 250e3)
    np.testing.assert_array_equal(denoised_pressure(Recording(t, flat, held, np.zeros(len(t)))), held)


def _single_stroke(seed: int, zero_N: float) -> tuple[Recording, object]:
    """One slow stroke at one pressure, 3 s vented just past rest before and after: 30 s out to
    1.4 x rest, 30 s back. Load cell 0.4 N noise plus ``zero_N``, pressure transducer 0.7 kPa
    noise on the regulator's output, encoder 10 um."""
    muscle = load_muscle("FAM1")
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 70.0, 0.01)
    top = rng.uniform(260e3, 380e3)
    set_point = np.interp(t, [0, 3, 6, 66, 69, 70], [0, 0, top, top, 0, 0])
    pressure = _regulated(t, set_point, 0.05)
    rest = muscle.rest_length_m
    low, high = rest + 0.002, rest * rng.uniform(1.35, 1.45)
    phase = np.clip((t - 6.0) / 60.0, 0.0, 1.0)
    length = low + (high - low) * 0.5 * (1.0 - np.cos(2 * np.pi * phase))
    force = muscle.push(pressure, length) + zero_N + rng.normal(0.0, 0.4, len(t))
    recording = Recording(
        t,
        length + rng.normal(0.0, 1e-5, len(t)),
        pressure + rng.normal(0.0, PRESSURE_NOISE_PA, len(t)),
        force,
    )
    return recording, muscle


@pytest.mark.parametrize("seed", [1, 2])
def test_one_clean_slow_stroke_at_one_pressure_is_not_called_a_load_cell_zero(seed):
    """Before the re-fit read the pressure averaged, the transducer's noise paid a law with a
    flatter pressure slope and a zero of about -1.8 N beside it (4.9 standard errors), and these
    clean files were answered ``force_offset`` at p 0.83-0.96."""
    recording, muscle = _single_stroke(seed, 0.0)
    d = diagnose(recording, muscle, next_experiment=False)
    assert "force_offset" not in d.names
    assert d.verdict.answer != "force_offset"


@pytest.mark.parametrize("seed, zero_N", [(3, 4.0), (5, -5.0)])
def test_a_real_load_cell_zero_on_one_slow_stroke_is_still_named(seed, zero_N):
    """At one pressure a zero is nearly one of the law's own force changes (the braid angle and
    the law trade against it), so its size is only roughly pinned; its sign and its name are.
    Before the re-fit read the pressure averaged, the -5 N zero was answered ``none`` and a
    4 N zero (seed 4) was fitted as 18.7 N."""
    recording, muscle = _single_stroke(seed, zero_N)
    d = diagnose(recording, muscle, next_experiment=False)
    assert d.verdict.answer == "force_offset"
    fitted = [e for e in d.effects if e["name"] == "force_offset"][0]
    assert abs(fitted["parameters"]["offset_N"] - zero_N) < 0.6 * abs(zero_N)


def test_a_braid_angle_moved_further_than_a_built_muscle_differs_is_reported_with_a_caution():
    """The re-fit takes up a length-scaled effect in the braid angle (an outside review's rigid end
    fittings came back `none` with the angle 7 % off and no word): the report says how far each
    constant moved and cautions above 5 % of the angle. Truth: the paper's protocol on FAM1 with
    its angle 8 % high (a caution), and on FAM1 as given (none)."""
    from dataclasses import replace

    from efam_mujoco.calibrate.synth import synthesize
    from efam_mujoco.diagnose.report import text

    nominal = load_muscle("FAM1")
    for factor, cautioned in ((1.08, True), (1.0, False)):
        truth = replace(nominal, theta_rest_deg=nominal.theta_rest_deg * factor)
        d = diagnose(synthesize(truth, rate_Hz=10.0, noise_N=0.3, seed=4), nominal, next_experiment=False)
        shift = d.refit_shift()["theta_rest_deg"]
        assert shift == pytest.approx(nominal.theta_rest_deg * (factor - 1.0), abs=0.15)
        assert bool(d.refit_caution()) is cautioned
        assert ("CAUTION" in text(d)) is cautioned
        assert d.to_json()["refit"]["shift_from_nominal"]["theta_rest_deg"] == shift
