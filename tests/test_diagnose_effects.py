"""Candidate effect terms: causal primitives against analytic solutions, the per-sample reference
(what a plugin runs) against the vectorised terms, and the physics each term must have."""

import math

import numpy as np
import pytest

from efam_mujoco import load_muscle
from efam_mujoco.diagnose import effects as E
from efam_mujoco.recordings import Recording
from efam_mujoco.stress import StressLaw


@pytest.fixture(scope="module")
def fam1():
    return load_muscle("FAM1")


def test_lag_step_response_is_exponential():
    # a unit step held from t = 0: y = 1 - exp(-t / tau) exactly at every sample (filterexact)
    t = np.linspace(0.0, 2.0, 201)
    u = np.r_[0.0, np.ones(200)]
    y = E.lag(t, u, 0.3)
    np.testing.assert_allclose(y[1:], 1.0 - np.exp(-t[1:] / 0.3), rtol=0, atol=1e-12)


@pytest.mark.parametrize("tau", [0.004, 0.3, 40.0])
def test_lag_nonuniform_sampling_matches_the_recursion(tau):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.05, 3000))
    u = np.sin(t) + rng.normal(0, 0.1, len(t))
    starts = [0, 1200]
    ref = np.empty_like(u)
    for b, e in ((0, 1200), (1200, 3000)):
        y = u[b]
        for k in range(b, e):
            if k > b:
                y += (1 - math.exp(-(t[k] - t[k - 1]) / tau)) * (u[k] - y)
            ref[k] = y
    np.testing.assert_allclose(E.lag(t, u, tau, starts), ref, rtol=0, atol=1e-10)


@pytest.mark.parametrize("pause_s", [60.0, 1e5])
def test_lag_across_a_pause_in_the_recording_stays_finite_and_exact(pause_s):
    # a logger paused mid-test: one time step of 60 s (1200 tau) or a day. The recursion forgets
    # everything across it (y = u after the pause); a block formula measured from before the
    # pause underflowed exp(-dt / tau) to 0 and turned every later sample into NaN
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.005, 0.03, 800))
    t[400:] += pause_s
    u = np.cos(3 * t) + rng.normal(0, 0.05, len(t))
    tau = 0.05
    ref = np.empty_like(u)
    y = u[0]
    for k in range(len(t)):
        if k:
            a = math.exp(-(t[k] - t[k - 1]) / tau)
            y = a * y + (1 - a) * u[k]
        ref[k] = y
    out = E.lag(t, u, tau)
    assert np.all(np.isfinite(out))
    assert out[400] == pytest.approx(u[400], abs=1e-12)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)


def test_play_operator_saturates_after_twice_its_width_and_holds():
    # triangle 0 -> 1 -> 0 with width 0.1: z reaches 1 after 0.1 of travel, stays 1 while the
    # input turns, and reaches -1 after 0.2 of travel back
    u = np.r_[np.linspace(0, 1, 101), np.linspace(1, 0, 101)[1:]]
    z = E.play(u, 0.1)
    assert z[10] == pytest.approx(1.0)
    assert np.all(z[10:101] == 1.0)
    # sample 100 + k has travelled 0.01 k back: z = 1 - k / 10
    assert z[110] == pytest.approx(0.0, abs=1e-9)
    assert z[120] == pytest.approx(-1.0, abs=1e-9)
    assert np.all(z[120:] == -1.0)


def test_a_relaxing_play_restarts_with_each_recordings_clock():
    # two recordings joined, the second's clock starting again at 0 after 600 s: the jump back
    # is not a time step (exp(+relax x 600 s) would overflow and 0 x inf poison the file), and
    # each recording plays exactly as it does alone; within one, a hold decays as exp(-r t)
    t = np.r_[np.linspace(0, 600, 601), np.linspace(0, 100, 101)]
    u = np.r_[np.linspace(0, 0.5, 601), np.r_[np.linspace(0, 0.05, 11), np.full(90, 0.05)]]
    z = E.play(u, 0.1, starts=(0, 601), t=t, relax_per_s=2.0)
    assert np.all(np.isfinite(z))
    np.testing.assert_array_equal(z[601:], E.play(u[601:], 0.1, t=t[601:], relax_per_s=2.0))
    assert z[611] > 0.05 and z[611 + 3] == pytest.approx(z[611] * math.exp(-2.0 * 3.0), rel=1e-12)


def test_high_frequency_noise_recovers_white_noise_under_a_smooth_signal():
    rng = np.random.default_rng(1)
    t = np.linspace(0, 100, 20000)
    u = 50 * np.sin(t / 7) + rng.normal(0, 0.4, len(t))
    assert E.high_frequency_noise(u) == pytest.approx(0.4, rel=0.05)


def test_thread_scale_one_is_eq2(fam1):
    L = np.linspace(fam1.rest_length_m, 1.9 * fam1.rest_length_m, 50)
    P = np.linspace(0, 517e3, 50)
    np.testing.assert_allclose(E.tension_with_thread(fam1, P, L, 1.0), fam1.tension(P, L), rtol=1e-12)


def test_bladder_share_plus_pressure_term_is_eq2(fam1):
    L = np.linspace(fam1.rest_length_m, 1.9 * fam1.rest_length_m, 50)
    P = np.linspace(0, 517e3, 50)
    gauge = np.maximum(P - fam1.deadband_Pa, 0)
    pressure = gauge / (4 * math.pi * fam1.turns**2) * (3 * L * L - fam1.thread_length_m**2)
    np.testing.assert_allclose(pressure + E.bladder_tension(fam1, P, L), fam1.tension(P, L), rtol=1e-10)


def _eq2_with_longer_threads(muscle, P, L, stretch):
    """Eq. 2 (paper sign) written out here for threads ``1 + stretch`` times as long: the sleeve
    radius from B^2 = L^2 + (2 pi N R_o)^2, the wall from the bladder's volume, the strains from
    the resting state (Sec. 2, Eqs. 1-4); the reference for the braid term below."""
    B = muscle.thread_length_m * (1.0 + stretch)
    N, V = muscle.turns, muscle.bladder_volume_m3
    r_out = np.sqrt(B * B - L * L) / (2 * math.pi * N)
    wall = r_out - np.sqrt(r_out * r_out - V / (math.pi * L))
    eps_z = L / muscle.rest_length_m - 1.0
    eps_c = (r_out - wall / 2) / (muscle.rest_outer_radius_m - muscle.rest_wall_thickness_m / 2) - 1.0
    gauge = np.maximum(P - muscle.deadband_Pa, 0.0)
    return (gauge / (4 * math.pi * N * N) * (3 * L * L - B * B) + muscle.stress(eps_z, P) * V / L
            - muscle.stress(eps_c, P) * wall * L * L / (2 * math.pi * r_out * N * N))  # fmt: skip


def test_braid_term_follows_a_stretch_of_the_threads_at_the_resting_length(fam1):
    """Threads 0.3-2 % longer change the push force by what Eq. 2 with the longer threads gives,
    within 12 %, at the resting length too, where the circumferential strain is zero and the
    exponent law (Eq. 21, E3 < 1) has no finite slope. The tangent there was 4-13 times too steep
    (the bench's braid stretches on strokes from rest were then named end effects)."""
    law = StressLaw.from_dict("exponent", {"E1_Pa": 5.2e5, "E2": 2.0, "E3": 0.52, "E4": 1.3})
    muscle = fam1.with_stress(law)
    rest = muscle.rest_length_m
    L = np.r_[np.full(4, rest), np.linspace(1.02, 1.5, 6) * rest]
    P = np.r_[np.linspace(150e3, 517e3, 4), np.full(6, 400e3)]
    assert np.max(np.abs(_eq2_with_longer_threads(muscle, P, L, 0.0) - muscle.tension(P, L))) < 1e-8
    term = E.get("braid_compliance")
    q = term.hoop_load(muscle, P, L)
    for stretch in (0.003, 0.01, 0.02):
        b1 = stretch / q  # a thread strain of exactly ``stretch`` at each sample
        exact = -(_eq2_with_longer_threads(muscle, P, L, stretch) - muscle.tension(P, L))  # push sign
        for i in range(len(P)):
            sample = E.Sample(
                t=0.0, P=P[i], L=L[i], P_prev=P[i], L_prev=L[i], dt=0.0, first=True, muscle=muscle
            )
            got = term.step({"b1_per_MPa": b1[i], "b2_per_MPa2": 0.0}, [], sample)
            assert got == pytest.approx(exact[i], rel=0.12), (stretch, L[i], P[i])


VALUES = {
    "friction": dict(
        f0_N=2.0, f1_N_per_MPa=8.0, slip_strain=0.004, slip_kPa=8.0, relax_per_s=0.05, smooth=0.0
    ),
    "viscoelasticity": dict(k0_N=40.0, k1_N_per_MPa=60.0, g_bladder=0.2, tau_s=3.0, g_slow_bladder=0.1),
    "end_effects": dict(kappa0=0.05, kappa1=0.1, P_e_kPa=80.0),
    "braid_compliance": dict(b1_per_MPa=0.02, b2_per_MPa2=-0.01),
    "softening": dict(a=0.1, width=0.03),
    "drift": dict(d0_N_per_s=0.002, d1_N_per_s=-0.01, d2_N_per_s_MPa=0.01, tau_s=300.0),
    "pressure_lag": dict(tau_s=0.2, volume_gain=0.6),
    "force_offset": dict(offset_N=1.5),
}


def _stroke_recording(muscle, n=700):
    """Pressure ramp at rest length, then a stroke out and back, a hold, irregular sampling."""
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.04, 0.06, n))
    t -= t[0]
    rest = muscle.rest_length_m
    L = rest * (1 + 0.6 * np.clip(np.sin(np.linspace(-0.6, 2 * np.pi, n)), 0, None))
    P = np.minimum(t / 3.0, 1.0) * 300e3 + 5e3 * np.sin(t)
    return Recording(t, L, P, np.zeros(n))


@pytest.mark.parametrize("name", E.EFFECT_NAMES)
def test_per_sample_reference_equals_vectorised_term(fam1, name):
    rec = _stroke_recording(fam1)
    model = E.EffectModel(fam1, [(name, VALUES[name])])
    vectorised = model.push_recording(rec)
    stepwise = model.push_stepwise(rec.time_s, rec.length_m, rec.pressure_Pa)
    base = fam1.push(rec.pressure_Pa, rec.length_m)
    assert np.max(np.abs(vectorised - base)) > 1e-3  # the term does something here
    np.testing.assert_allclose(stepwise, vectorised, rtol=1e-9, atol=1e-9)


def _ctx(muscle, t, L, P):
    return E.Context(t, L, P, [0], muscle)


def test_friction_is_rate_independent_and_viscoelasticity_is_not(fam1):
    # the same stroke at two speeds: friction gives the same force along the path, a Maxwell
    # branch more force at the faster speed
    rest = fam1.rest_length_m
    path = rest * (1 + 0.5 * np.r_[np.linspace(0, 1, 400), np.linspace(1, 0, 400)])
    P = np.full(800, 300e3)
    slow, fast = np.linspace(0, 80, 800), np.linspace(0, 8, 800)
    fr, ve = E.get("friction"), E.get("viscoelasticity")
    stuck = dict(VALUES["friction"], relax_per_s=0.0)  # a contact that does not relax in time
    f_slow = fr.force(_ctx(fam1, slow, path, P), stuck)
    f_fast = fr.force(_ctx(fam1, fast, path, P), stuck)
    np.testing.assert_allclose(f_slow, f_fast, atol=1e-12)
    v_slow = ve.force(_ctx(fam1, slow, path, P), VALUES["viscoelasticity"])
    v_fast = ve.force(_ctx(fam1, fast, path, P), VALUES["viscoelasticity"])
    assert np.max(np.abs(v_fast)) > 3 * np.max(np.abs(v_slow))


def test_friction_opposes_motion_and_persists_through_a_hold(fam1):
    rest = fam1.rest_length_m
    L = rest * (1 + 0.4 * np.r_[np.linspace(0, 1, 300), np.ones(200)])
    t = np.linspace(0, 100, 500)
    values = dict(VALUES["friction"], relax_per_s=0.0)
    f = E.get("friction").force(_ctx(fam1, t, L, np.full(500, 200e3)), values)
    expected = -(values["f0_N"] + values["f1_N_per_MPa"] * 0.2)  # lengthening: pushes less
    assert f[250] == pytest.approx(expected)
    assert f[-1] == pytest.approx(expected)  # stick: no relaxation during the hold
    # relax_per_s may be left out (files written before it existed): 0, a contact that holds
    absent = {k: v for k, v in values.items() if k != "relax_per_s"}
    assert E.check_values("friction", absent)["relax_per_s"] == 0.0
    np.testing.assert_array_equal(E.get("friction").force(_ctx(fam1, t, L, np.full(500, 200e3)), absent), f)
    # a contact that relaxes (the supply's dither): the stuck force decays as exp(-r t) in the hold
    relaxing = dict(values, relax_per_s=0.05)
    f = E.get("friction").force(_ctx(fam1, t, L, np.full(500, 200e3)), relaxing)
    hold = np.arange(300, 500)
    np.testing.assert_allclose(f[hold] / f[299], np.exp(-0.05 * (t[hold] - t[299])), rtol=1e-12)


def test_smooth_friction_rounds_the_corner_as_dahls_model(fam1):
    # Dahl's model, dF/dx = sigma (1 - F/F_c sign(dx)), from F = 0 on a lengthening stroke at a
    # constant pressure: F = F_c (1 - exp(-(x - x_0) / w)), w = F_c / sigma; reversing from +F_c
    # it goes back as F_c (2 exp(-(x_top - x) / w) - 1). The sharp (play) operator instead is
    # F_c (x - x_0) / w up to F_c, then flat. Written out here, not taken from effects.play.
    rest = fam1.rest_length_m
    x = 0.03 * np.r_[np.linspace(0.0, 1.0, 301), np.linspace(1.0, 0.0, 301)[1:]]
    L = rest * (1 + x)
    t = np.linspace(0.0, 60.0, len(x))
    P = np.full(len(x), 250e3)
    v = dict(VALUES["friction"], slip_kPa=0.0, relax_per_s=0.0, smooth=1.0)
    F_c = v["f0_N"] + v["f1_N_per_MPa"] * 0.25
    w = v["slip_strain"]
    up, down = np.arange(301), np.arange(301, len(x))
    expected = np.empty(len(x))
    expected[up] = F_c * (1 - np.exp(-x[up] / w))
    top = expected[300]
    # back down: dF/d(-x) = sigma (1 + F/F_c): F + F_c = (top + F_c) exp(-(x_top - x) / w)
    expected[down] = (top + F_c) * np.exp(-(x[300] - x[down]) / w) - F_c
    f = E.get("friction").force(_ctx(fam1, t, L, P), v)
    np.testing.assert_allclose(-f, expected, rtol=1e-9, atol=1e-12)  # friction opposes the motion
    # the sharp corner: the same stroke with smooth 0 reaches F_c at x = w and stays there
    sharp = E.get("friction").force(_ctx(fam1, t, L, P), dict(v, smooth=0.0))
    assert -sharp[up][x[up] >= w * 1.01] == pytest.approx(F_c)
    assert np.max(np.abs(sharp - f)) > 0.2 * F_c  # the two corners differ by a good share of F_c
    # the per-sample reference takes the same state
    m = E.EffectModel(fam1, [("friction", v)])
    np.testing.assert_allclose(m.push_stepwise(t, L, P) - fam1.push(P, L), f, rtol=1e-9, atol=1e-9)


def test_a_pressure_change_slides_the_same_contact_as_a_stroke(fam1):
    # one contact, one slip: after a lengthening stroke the play is at +1; at the held length a
    # pressure change of w_P moves it by s_P (B^2 > 3 L^2 here: pressure pushes, s_P = +1), so
    # venting by 2 w_P reverses the friction force, and a rise of w_P / 4 from there moves it by 1/4
    rest = fam1.rest_length_m
    assert fam1.thread_length_m**2 > 3 * (1.2 * rest) ** 2
    v = dict(VALUES["friction"], relax_per_s=0.0)
    wp = v["slip_kPa"] * 1e3
    L = rest * np.r_[np.linspace(1.0, 1.2, 100), np.full(300, 1.2)]
    P = 300e3 + np.r_[np.zeros(100), np.linspace(0.0, -2 * wp, 100), np.full(100, -2 * wp),
                      np.linspace(-2 * wp, -1.75 * wp, 100)]  # fmt: skip
    t = np.linspace(0.0, 40.0, 400)
    f = E.get("friction").force(_ctx(fam1, t, L, P), v)
    stick = -(v["f0_N"] + v["f1_N_per_MPa"] * P / 1e6)  # the force at z = +1
    assert f[99] == pytest.approx(stick[99])  # after the stroke: z = +1
    assert f[250] == pytest.approx(-stick[250])  # vented by 2 w_P: z = -1
    assert f[-1] == pytest.approx(-0.75 * stick[-1])  # up by w_P / 4: z = -1 + 1/4


def test_maxwell_branch_relaxes_exponentially_during_a_hold(fam1):
    rest = fam1.rest_length_m
    dt = 0.01
    t = np.arange(0, 20, dt)
    x = np.where(t < 2.0, 0.2 * t / 2.0, 0.2)
    ctx = _ctx(fam1, t, rest * (1 + x), np.zeros(len(t)))
    tau = 1.5
    f = E.get("viscoelasticity").force(ctx, dict(k0_N=100.0, k1_N_per_MPa=0.0, tau_s=tau))
    hold = t >= 2.0
    ratio = f[hold][200] / f[hold][0]
    assert ratio == pytest.approx(math.exp(-(t[hold][200] - t[hold][0]) / tau), rel=1e-6)


def test_drift_on_the_pressure_clock_stands_still_while_vented_and_can_accelerate(fam1):
    # written out: at a held pressure P the pressure clock runs at P_MPa seconds per second, so
    # the saturating course is tau (1 - exp(-P_MPa t / tau)), the accelerating one tau
    # (exp(P_MPa t / tau) - 1) and the logarithmic one tau log(1 + P_MPa t / tau) (rubber's
    # logarithmic creep); while vented the clock stops and the force holds its value
    dt = 0.05
    t = np.arange(0.0, 200.0, dt)
    P = np.where(t < 100.0, 0.4e6, 0.0)
    L = np.full(len(t), fam1.rest_length_m)  # x = 0: only d0 and d2 act
    ctx = _ctx(fam1, t, L, P)
    d0, d2, tau = 0.01, 0.05, 150.0
    on = t < 100.0
    u = 0.4 * t[on]  # the clock at the end of every sample (P_MPa dt per step, none at t = 0)
    rate = d0 + d2 * 0.4
    courses = (
        (1.0, tau * (1 - np.exp(-u / tau))),
        (-1.0, tau * (np.exp(u / tau) - 1)),
        (0.0, tau * np.log(1 + u / tau)),
    )
    for course, expected in courses:
        values = dict(d0_N_per_s=d0, d1_N_per_s=0.0, d2_N_per_s_MPa=d2, tau_s=tau, clock=1.0, course=course)
        f = E.get("drift").force(ctx, values)
        np.testing.assert_allclose(f[on], rate * expected, rtol=1e-9, atol=1e-12)
        # vented: the pressure term is gone and the clock holds where it stopped
        np.testing.assert_allclose(f[~on], d0 * expected[-1], rtol=1e-9)
    # the wall clock keeps running while vented
    wall = E.get("drift").force(ctx, dict(d0_N_per_s=d0, d1_N_per_s=0.0, d2_N_per_s_MPa=0.0, tau_s=tau))
    np.testing.assert_allclose(wall, d0 * tau * (1 - np.exp(-t / tau)), rtol=1e-9, atol=1e-12)


def test_an_accelerating_drift_stays_finite_on_a_long_recording(fam1):
    # three hours at 1 Hz: exp(t / 30 s) would overflow its square; the fit settles tau at the
    # clock's span over MAX_EXPONENT, and the columns stay finite
    t = np.arange(0.0, 3 * 3600.0, 1.0)
    ctx = _ctx(fam1, t, np.full(len(t), fam1.rest_length_m), np.full(len(t), 0.2e6))
    drift = E.get("drift")
    settled = drift.settle(ctx, dict(tau_s=30.0, clock=0.0, course=-1.0))
    assert settled["tau_s"] == pytest.approx(t[-1] / drift.MAX_EXPONENT)
    _, cols = drift.design(ctx, settled)
    assert np.all(np.isfinite(cols)) and np.isfinite(np.mean(cols**2))
    assert drift.settle(ctx, dict(tau_s=30.0, clock=0.0, course=1.0))["tau_s"] == 30.0  # saturating: as tried


def test_a_mode_takes_only_its_own_values():
    with pytest.raises(ValueError, match=r"'clock' = 0.5 is not one of 0, 1"):
        E.check_values("drift", dict(VALUES["drift"], clock=0.5))
    with pytest.raises(ValueError, match=r"'course' = 0.5 is not one of -1, 0, 1"):
        E.check_values("drift", dict(VALUES["drift"], course=0.5))
    assert E.check_values("drift", VALUES["drift"])["clock"] == 0.0  # older files: the wall clock
    with pytest.raises(ValueError, match=r"'smooth' = 0.5 is not one of 0, 1"):
        E.check_values("friction", dict(VALUES["friction"], smooth=0.5))


def test_the_search_tries_a_mode_at_its_own_values_only(fam1):
    # a noise floor raises a width's lowest searched value; a mode has none to raise (friction's
    # floor once turned its smooth 0 into 4.7e-4, which the model then refused)
    t = np.linspace(0.0, 10.0, 200)
    L = fam1.rest_length_m * (1 + 0.1 * np.sin(t))
    ctx = _ctx(fam1, t, L, 200e3 + 5e3 * np.random.default_rng(0).standard_normal(200))
    modes = [(e, p) for e in E.LIBRARY.values() for p in e.shapes if p.discrete]
    assert {(e.name, p.key) for e, p in modes} >= {
        ("friction", "smooth"),
        ("drift", "clock"),
        ("drift", "course"),
    }
    for e, p in modes:
        assert e.shape_range(ctx, p)[1] == p.grid, (e.name, p.key)


def test_pressure_lag_at_fixed_length_is_the_lagged_pressure_through_the_model(fam1):
    # at constant length the gas volume is constant, so P_i is the first-order lag of P, and the
    # force is the model's at P_i: analytic for a step (above the dead band, linear in P)
    t = np.linspace(0, 3, 301)
    P = np.where(t > 0.5, 300e3, 100e3)
    L = np.full(len(t), fam1.rest_length_m)
    f = E.get("pressure_lag").force(_ctx(fam1, t, L, P), dict(tau_s=0.25))
    after = t > 0.5
    # the first sample after the step has already moved by (1 - exp(-dt/tau)), dt = 0.01 s
    P_i = 300e3 - 200e3 * np.exp(-(t[after] - t[after][0] + 0.01) / 0.25)
    expected = fam1.push(P_i, fam1.rest_length_m) - fam1.push(300e3, fam1.rest_length_m)
    np.testing.assert_allclose(f[after], expected, rtol=1e-9, atol=1e-9)


def test_pressure_lag_volume_gain_weighs_the_quasi_steady_gas_volume_drop(fam1):
    # a slow stroke at constant supply pressure: the fill dP/dt = (P_s - P)/tau - (P + P_atm) V'/V
    # settles at P = P_s - tau (P + P_atm) V'/V (isothermal gas), which volume_gain 1 reproduces;
    # 0 is a lag without the volume term (no force change at constant pressure); 0.5 half of it
    t = np.linspace(0, 20, 20001)
    rest = fam1.rest_length_m
    L = rest * (1 + 0.3 * t / 20)
    P = np.full(len(t), 300e3)
    ctx = _ctx(fam1, t, L, P)
    tau = 0.01
    R = fam1.outer_radius(L)
    V = np.pi * R**2 * L - fam1.bladder_volume_m3  # the gas inside the bladder
    dVdt = np.gradient(V, t)
    P_i = 300e3 - tau * (300e3 + E.P_ATM) * dVdt / V
    expected = fam1.push(P_i, L) - fam1.push(P, L)
    late = t > 2.0  # 200 time constants: the lag has settled
    assert np.max(np.abs(expected[late])) > 1e-3  # the drop does something here
    for gain in (0.0, 0.5, 1.0):
        f = E.get("pressure_lag").force(ctx, dict(tau_s=tau, volume_gain=gain))
        np.testing.assert_allclose(f[late], gain * expected[late], rtol=2e-3, atol=1e-9)


def test_the_delay_search_starts_at_one_sample_interval_which_stands_for_no_delay(fam1):
    # MuJoCo's ctrl delay reads only earlier samples: any delay up to one interval acts as a whole
    # one, so the search's floor is the interval and a fit at the floor is written as 0 exactly
    lag = E.get("pressure_lag")
    delay = next(p for p in lag.shapes if p.key == "delay_s")
    for hz in (1000.0, 50.0, 25.0):
        t = np.arange(0.0, 10.0, 1.0 / hz)
        ctx = _ctx(fam1, t, np.full(len(t), fam1.rest_length_m), np.full(len(t), 2e5))
        lo, grid, hi = lag.shape_range(ctx, delay)
        assert lo == pytest.approx(max(1e-3, 1.0 / hz)) and grid[0] == lo and hi > lo
        assert all(b > a for a, b in zip(grid, grid[1:]))
        assert lag.settle(ctx, dict(tau_s=0.1, delay_s=lo))["delay_s"] == 0.0
        assert lag.settle(ctx, dict(tau_s=0.1, delay_s=1.02 * lo))["delay_s"] == 0.0
        assert lag.settle(ctx, dict(tau_s=0.1, delay_s=3.0 * lo))["delay_s"] == pytest.approx(3.0 * lo)


def test_a_slack_tension_only_muscle_carries_no_effect_force_but_the_sensor_offset():
    from dataclasses import replace

    m = replace(load_muscle("FAM1"), tension_only=True)
    rest = m.rest_length_m
    t = np.linspace(0, 10, 200)
    L = np.full(200, rest)
    P = np.full(200, 300e3)  # an EFAM at rest length under pressure pushes: slack as tension-only
    ctx = _ctx(m, t, L, P)
    assert np.all(ctx.base == 0)
    for name in E.EFFECT_NAMES:
        f = E.get(name).force(ctx, VALUES[name])
        if name == "force_offset":
            assert np.all(f == 1.5)
        else:
            assert np.all(f == 0)


def test_bad_effect_values_are_named():
    with pytest.raises(ValueError, match="missing parameter 'tau_s'"):
        E.EffectModel(load_muscle("FAM1"), [("viscoelasticity", dict(k0_N=1.0, k1_N_per_MPa=0.0))])
    with pytest.raises(ValueError, match="'slip_strain' = 2 is outside"):
        E.check_values("friction", dict(VALUES["friction"], slip_strain=2.0))
    with pytest.raises(ValueError, match="unknown effect 'stiction'"):
        E.get("stiction")
    with pytest.raises(ValueError, match="unknown parameter 'tau'"):
        E.check_values("pressure_lag", dict(tau_s=0.1, tau=0.2))
