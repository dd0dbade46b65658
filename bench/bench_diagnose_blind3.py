"""The diagnosis on a third blind set: effect forms, protocols and sensors written by an outside
reviewer (stop 54) WITHOUT reading the package's generators (``diagnose/virtual_bench.py``,
``diagnose/synth.py``) or the other two outside sets (``bench_diagnose_forms.py``,
``bench_diagnose_protocols.py``). The generator below is kept exactly as the reviewer wrote it
(same forms, protocols, seeds and draw order), so its figures stay comparable; only this runner
was put in the house style. From the package it uses ``load_muscle``, ``Recording`` and
``StressLaw``; its own Eq. 2 (thread length free) makes the forces.

Truth: the nominal preset (FAM1 or FAM2) perturbed a few per cent (stress coefficients 3 %,
diameter and braid angle 1.5 %, bladder volume 2 %, dead band 4 %) plus ONE effect, sized so
that its 99.5th-percentile |dF| is 4-12 % of the force span; force noise 0.3-1 N, pressure
0.5 kPa, length 5 um. Seven protocols: pressure ramps at four shuffled lengths (100 Hz),
isobaric strokes at five pressures in random order (200 Hz), length sinusoids at 0.05-3 Hz
(400 Hz), 14 length or pressure steps with holds (100 Hz), band-limited random length and
pressure (1 kHz), 20 cycles of growing amplitude (50 Hz), slow strokes and pressure loops at
20 Hz over 400 s. Forms:

* friction: generalised Prandtl-Ishlinskii (8 play widths), LuGre with Stribeck, Coulomb in
  proportion to the braid's normal load;
* viscoelasticity: fractional Kelvin-Voigt, a three-term Prony series on the bladder's force, a
  relaxation time depending on the strain (Schapery);
* end_effects: end caps bulging with pressure, end cones growing with stretch (the active
  length shifts, so the force changes at the resting length too);
* braid_compliance: bilinear thread, thread creep under load, power-law thread;
* softening: Ogden-Roxburgh, Mullins with recovery over 40 s;
* drift: sigmoid warm-up, a load-cell gain step mid-test, logarithmic creep of the rest length;
* pressure_lag: a tube, orifice and volume (pneumatic line), a valve with a slew-rate limit;
* force_offset: a constant zero error; a different zero after re-mounting (two files);
* outside the library: pressure-sensor gain error, pressure cross-talk into the force channel,
  a stick-slip fixture, thermal expansion of the fixture, backlash in the length coupling,
  aliasing at a low sampling rate.

The set: 10 clean, 45 one in-library effect, 10 outside. Each is diagnosed as ``efam diagnose
--muscle <preset> FILE...`` does (the nominal preset, no next experiment) and scored: clean
``ok`` / ``false_alarm`` (an effect named at p >= 0.8); one effect ``right_confident``,
``wrong_confident``, ``ambiguous_with_truth`` / ``_without_truth``, ``tentative_right`` /
``_wrong``; outside ``ok`` or ``FAIL`` (a library effect named at p >= 0.8).

Usage: python bench/bench_diagnose_blind3.py [--only ID ...] [--replicate ID ...] [--out FILE]
Writes bench/results/diagnose_blind3.json (``--replicate``: the same forms and protocols at two
other seeds each, diagnose_blind3_replicates.json).
"""

# ruff: noqa: E741, B007, F841 (the reviewer's generator below is kept exactly as written)
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import collections  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.special import erf  # noqa: E402

from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.musclefile import load_muscle  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402
from efam_mujoco.recordings import Recording  # noqa: E402
from efam_mujoco.stress import StressLaw  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "diagnose_blind3.json"

# ================================================ the reviewer's generator, as written
PA = 101325.0

# ------------------------------------------------------------------ own Eq. 2 (thread length free)


def eq2_parts(m, P, L, B=None):
    """Push-sign (pressure part, bladder part) of Eq. 2 for muscle m; B: thread length per sample."""
    N = m.turns
    B = m.thread_length_m if B is None else B
    V = m.bladder_volume_m3
    L = np.clip(L, m.min_length_m, m.max_length_m)
    r = np.sqrt(np.maximum(B * B - L * L, 0.0)) / (2 * math.pi * N)
    t = r - np.sqrt(np.maximum(r * r - V / (math.pi * L), 0.0))
    ez = L / m.rest_length_m - 1.0
    ec = (r - t / 2) / (m.rest_outer_radius_m - m.rest_wall_thickness_m / 2) - 1.0
    P = np.maximum(P, 0.0)
    gauge = np.maximum(P - m.deadband_Pa, 0.0)
    f_p = gauge / (4 * math.pi * N * N) * (3 * L * L - B * B)
    f_b = m.stress(ez, P) * V / L - m.stress(ec, P) * t * L * L / (2 * math.pi * r * N * N)
    return -f_p, -f_b


def radius(m, L, B=None):
    B = m.thread_length_m if B is None else B
    return np.sqrt(np.maximum(B * B - L * L, 0.0)) / (2 * math.pi * m.turns)


def lag(u, tau, dt):
    a = math.exp(-dt / tau)
    y = np.empty_like(u)
    acc = u[0]
    for k in range(u.size):
        acc = a * acc + (1 - a) * u[k]
        y[k] = acc
    return y


def smooth(u, tau, dt):
    """Forward-backward first-order smoothing of a command (actuator bandwidth)."""
    return lag(lag(u, tau, dt)[::-1], tau, dt)[::-1]


# -------------------------------------------------------------------------------- protocols
# each returns (fs, t, L/L_rest, P_kPa) ; P is the regulator's output (the sensor's truth)


def _seg_ramp(a, b, dur, fs):
    n = max(int(round(dur * fs)), 1)
    return np.linspace(a, b, n, endpoint=False)


def _cat(segs_x, segs_p):
    return np.concatenate(segs_x), np.concatenate(segs_p)


def proto_pramp_multiL(rng):
    fs = 100.0
    lengths = rng.permutation([1.0, 1.07, 1.14, 1.21])
    xs, ps = [], []
    x0 = 1.0
    pmax = rng.uniform(330, 420)
    for l in lengths:
        xs += [
            _seg_ramp(x0, l, 4, fs),
            np.full(int(2 * fs), l),
            _seg_ramp(l, l, 16, fs),
            np.full(int(4 * fs), l),
            _seg_ramp(l, l, 16, fs),
            np.full(int(2 * fs), l),
        ]
        ps += [
            np.zeros(int(4 * fs)),
            np.zeros(int(2 * fs)),
            _seg_ramp(0, pmax, 16, fs),
            np.full(int(4 * fs), pmax),
            _seg_ramp(pmax, 0, 16, fs),
            np.zeros(int(2 * fs)),
        ]
        x0 = l
    return fs, *_cat(xs, ps)


def proto_isobaric_random(rng):
    fs = 200.0
    levels = rng.permutation([80, 160, 240, 320, 400])
    xs, ps = [], []
    p0 = 0.0
    for p in levels:
        xs += [np.full(int(3 * fs), 1.0)]
        ps += [_seg_ramp(p0, p, 0.5, fs)[: int(0.5 * fs)].tolist() + [p] * int(2.5 * fs)]
        per = rng.uniform(6, 10)
        amp = rng.uniform(0.15, 0.22)
        for c in range(2):
            xs += [_seg_ramp(1.0, 1.0 + amp, per / 2, fs), _seg_ramp(1.0 + amp, 1.0, per / 2, fs)]
            ps += [np.full(int(round(per / 2 * fs)), p)] * 2
        p0 = p
    xs = np.concatenate(xs)
    ps = np.concatenate([np.asarray(p, float) for p in ps])
    return fs, xs, ps


def proto_sine_multif(rng):
    fs = 400.0
    freqs = [0.05, 0.2, 1.0, 3.0]
    press = rng.permutation([150, 250, 300, 380])
    xs, ps = [], []
    p0 = 0.0
    for f, p in zip(freqs, press):
        dur = max(2 / f, 6.0)
        xs += [np.full(int(3 * fs), 1.08)]
        ps += [np.concatenate([_seg_ramp(p0, p, 2, fs), np.full(int(fs), p)])]
        tt = np.arange(int(dur * fs)) / fs
        xs += [1.08 + 0.07 * np.sin(2 * np.pi * f * tt)]
        ps += [np.full(tt.size, float(p))]
        p0 = p
    return fs, *_cat(xs, ps)


def proto_step_hold(rng):
    fs = 100.0
    xs, ps = [], []
    x, p = 1.0, 0.0
    for k in range(14):
        if k % 2 == 0:
            x = rng.uniform(0.99, 1.22)
        else:
            p = rng.uniform(40, 420)
        hold = rng.uniform(8, 14)
        xs.append(np.full(int(hold * fs), x))
        ps.append(np.full(int(hold * fs), p))
    xs, ps = np.concatenate(xs), np.concatenate(ps)
    return fs, xs, ps  # actuator smoothing below makes steps ~50 ms


def _bandlimited(rng, n, fs, f_lo, f_hi):
    spec = np.zeros(n // 2 + 1, complex)
    f = np.fft.rfftfreq(n, 1 / fs)
    band = (f >= f_lo) & (f <= f_hi)
    spec[band] = rng.normal(size=band.sum()) + 1j * rng.normal(size=band.sum())
    u = np.fft.irfft(spec, n)
    return u / np.max(np.abs(u))


def proto_random_bl(rng):
    fs = 1000.0
    n = int(25 * fs)
    x = 1.1 + 0.1 * _bandlimited(rng, n, fs, 0.05, 1.5)
    p = 230 + 170 * _bandlimited(rng, n, fs, 0.03, 1.0)
    return fs, x, np.clip(p, 0, 420)


def proto_fatigue20(rng):
    fs = 50.0
    per = 12.0
    tt = np.arange(int(20 * per * fs)) / fs
    cyc = tt / per
    grow = np.minimum(1.0, 0.4 + 0.6 * np.floor(cyc) / 5)  # amplitude grows over the first 5 cycles
    x = 1.0 + 0.2 * grow * 0.5 * (1 - np.cos(2 * np.pi * cyc))
    p = 350 * grow * 0.5 * (1 - np.cos(2 * np.pi * cyc + 0.9))
    return fs, x, p


def proto_slow_lowfs(rng):
    fs = 20.0
    xs, ps = [], []
    for p in rng.permutation([120, 260, 400]):
        xs += [np.full(int(4 * fs), 1.0), _seg_ramp(1.0, 1.24, 40, fs), _seg_ramp(1.24, 1.0, 40, fs)]
        ps += [_seg_ramp(0, p, 4, fs), np.full(int(80 * fs), p)]
        xs += [np.full(int(4 * fs), 1.0)]
        ps += [_seg_ramp(p, 0, 4, fs)]
    for l in (1.04, 1.18):
        xs += [np.full(int(70 * fs), l)]
        ps += [
            np.concatenate(
                [
                    _seg_ramp(0, 400, 30, fs),
                    np.full(int(5 * fs), 400),
                    _seg_ramp(400, 0, 30, fs),
                    np.zeros(int(5 * fs)),
                ]
            )
        ]
    return fs, *_cat(xs, ps)


PROTOCOLS = {
    "pramp_multiL": proto_pramp_multiL,
    "isobaric_random": proto_isobaric_random,
    "sine_multif": proto_sine_multif,
    "step_hold": proto_step_hold,
    "random_bl": proto_random_bl,
    "fatigue20": proto_fatigue20,
    "slow_lowfs": proto_slow_lowfs,
}


def run_protocol(name, rng, m):
    fs, x, p_kpa = PROTOCOLS[name](rng)
    dt = 1 / fs
    x = smooth(x, 0.03, dt) if fs >= 50 else x
    P = lag(p_kpa * 1e3, 0.03, dt) if fs >= 50 else p_kpa * 1e3  # regulator
    t = np.arange(x.size) * dt
    return t, x * m.rest_length_m, np.maximum(P, 0.0), dt


# ------------------------------------------------------------------------------- effects
# each effect: f(ctx, s) -> dict with keys F (true force at the load cell, push), optionally Prec, Lrec
# ctx: m (truth muscle), t, L, P, dt, rng-drawn constants in ctx["k"]


def base(ctx):
    fp, fb = eq2_parts(ctx["m"], ctx["P"], ctx["L"])
    return fp + fb


def play_stop(u, r):
    """stop operator normalised to [-1, 1] (elastic-plastic element of width r)."""
    y = np.empty_like(u)
    z = u[0]
    out = np.empty_like(u)
    for k in range(u.size):
        z = min(max(z, u[k] - r), u[k] + r)
        out[k] = (u[k] - z) / r
    return out


def fr_PI(ctx, s):
    m, L, P = ctx["m"], ctx["L"], ctx["P"]
    x = L / m.rest_length_m - 1
    u = x + 0.02 * P / 1e6  # pressure changes slide the braid too
    rs = np.geomspace(4e-4, 0.02, 8)
    w = np.exp(-rs / 0.006)
    w /= w.sum()
    h = sum(wi * play_stop(u, ri) for wi, ri in zip(w, rs))
    return base(ctx) - s * (1 + 2.5 * P / 1e6) * h


def fr_LuGre(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    x = L / m.rest_length_m - 1
    v = np.gradient(x, dt)
    Fc = s * (1 + 1.5 * P / 1e6)
    Fs = 1.6 * Fc
    vs = 0.004
    sig0 = 1.0 / 3e-4  # per unit Fc: bristle deflects 3e-4 strain at Fc
    z = 0.0
    F = np.empty_like(x)
    for k in range(x.size):
        g = Fc[k] + (Fs[k] - Fc[k]) * math.exp(-((v[k] / vs) ** 2))  # N
        gz = g / (Fc[k] * sig0 + 1e-12) if Fc[k] > 0 else 1e-9  # steady bristle deflection (strain)
        zss = gz * np.sign(v[k])
        rate = abs(v[k]) / max(gz, 1e-12)
        z = zss + (z - zss) * math.exp(-rate * dt)
        F[k] = Fc[k] * sig0 * z + 0.15 * Fc[k] * v[k] / 0.01
    return base(ctx) - F


def fr_coulomb_normal(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    x = L / m.rest_length_m - 1
    v = np.gradient(x, dt)
    R = radius(m, L)
    Nload = (P + 20e3) * R * L  # normal load of the braid on the bladder (+ pre-tension)
    Nload /= 300e3 * m.rest_outer_radius_m * m.rest_length_m
    return base(ctx) - s * Nload * np.tanh(v / 0.002)


def ve_fractional(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    x = L / m.rest_length_m - 1
    alpha = 0.35
    taus = np.geomspace(0.01, 1000, 11)
    w = taus ** (-alpha)
    w /= w.sum()
    dF = np.zeros_like(x)
    for wi, ti in zip(w, taus):
        dF += wi * (x - lag(x, ti, dt))
    return base(ctx) - s * (1 + 1.5 * P / 1e6) * dF / 0.01


def ve_prony3_bladder(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    fp, fb = eq2_parts(m, P, L)
    dF = sum(g * (fb - lag(fb, tau, dt)) for g, tau in ((0.5, 0.3), (0.3, 4.0), (0.2, 60.0)))
    return fp + fb + s * dF


def ve_schapery(ctx, s):
    """nonlinear standard solid: relaxation time depends on strain"""
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    x = L / m.rest_length_m - 1
    w = x[0]
    dF = np.empty_like(x)
    for k in range(x.size):
        tau = 2.0 * math.exp(-x[k] / 0.08)
        a = math.exp(-dt / tau)
        w = a * w + (1 - a) * x[k]
        dF[k] = x[k] - w
    return base(ctx) - s * (1 + P / 1e6) * dF / 0.01


def end_caps_bulge(ctx, s):
    m, L, P = ctx["m"], ctx["L"], ctx["P"]
    Lr = m.rest_length_m
    e0 = s * 0.03 * Lr
    e = e0 * (1 - 0.6 * (1 - np.exp(-P / 150e3)))  # bulging caps draw the end zones shorter
    La = (L - 2 * e) / (Lr - 2 * e0) * Lr
    fp, fb = eq2_parts(m, P, La)
    return fp + fb


def end_cones(ctx, s):
    m, L, P = ctx["m"], ctx["L"], ctx["P"]
    Lr = m.rest_length_m
    x = L / Lr - 1
    e0 = s * 0.03 * Lr
    e = e0 * (1 + 2.0 * x) * (1 + 0.8 * P / 1e6)  # conical ends grow with stretch and pressure
    La = (L - 2 * e) / (Lr - 2 * e0) * Lr
    fp, fb = eq2_parts(m, P, La)
    return fp + fb


def _thread_load(m, P, L):
    R = radius(m, L)
    B = m.thread_length_m
    q = (
        np.maximum(P - m.deadband_Pa, 0)
        / 1e6
        * (R / m.rest_outer_radius_m) ** 2
        * (B / L)
        / (B / m.rest_length_m)
    )
    return q  # MPa-equivalent axial thread load


def braid_bilinear(ctx, s):
    m, L, P = ctx["m"], ctx["L"], ctx["P"]
    q = _thread_load(m, P, L)
    qk = 0.15
    a1 = s * 0.02  # strain per MPa below the knee (crimp)
    eps = np.where(q < qk, a1 * q, a1 * qk + a1 / 4 * (q - qk))
    fp, fb = eq2_parts(m, P, L, m.thread_length_m * (1 + eps))
    return fp + fb


def braid_creep(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    q = _thread_load(m, P, L)
    a = s * 0.01
    eps = a * q + 1.5 * a * lag(q, 40.0, dt)
    fp, fb = eq2_parts(m, P, L, m.thread_length_m * (1 + eps))
    return fp + fb


def braid_power(ctx, s):
    m, L, P = ctx["m"], ctx["L"], ctx["P"]
    q = _thread_load(m, P, L)
    eps = s * 0.01 * q**0.6
    fp, fb = eq2_parts(m, P, L, m.thread_length_m * (1 + eps))
    return fp + fb


def _mullins(ctx, s, tau_rec):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    fp, fb = eq2_parts(m, P, L)
    ez, ec = m.strains(L)
    W = ez**2 + ec**2  # strain-energy proxy
    Wm = W[0]
    eta = np.empty_like(W)
    mu = 0.004
    for k in range(W.size):
        if W[k] >= Wm:
            Wm = W[k]
        elif tau_rec:
            Wm = W[k] + (Wm - W[k]) * math.exp(-dt / tau_rec)
        eta[k] = 1 - s * erf((Wm - W[k]) / mu)
    return fp + eta * fb


def soft_ogden_roxburgh(ctx, s):
    return _mullins(ctx, s, None)


def soft_mullins_recovery(ctx, s):
    return _mullins(ctx, s, 40.0)


def drift_sigmoid_warmup(ctx, s):
    m, L, P, t = ctx["m"], ctx["L"], ctx["P"], ctx["t"]
    T = t[-1]
    sg = 1 / (1 + np.exp(-(t - 0.4 * T) / (0.08 * T)))
    fp, fb = eq2_parts(m, P, L)
    return fp + fb * (1 - 0.5 * s * sg) + s * 40 * sg  # rubber softens and load-cell zero warms


def drift_gain_step(ctx, s):
    t = ctx["t"]
    F = base(ctx)
    return F * np.where(t > 0.55 * t[-1], 1 + s * 0.1, 1.0)


def drift_log_creep(ctx, s):
    m, L, P, t, dt = ctx["m"], ctx["L"], ctx["P"], ctx["t"], ctx["dt"]
    u = np.cumsum(P / 1e6) * dt  # MPa s under pressure
    c = s * 0.01 * np.log1p(u / 5.0)
    fp, fb = eq2_parts(m, P, L / (1 + c))  # bladder rest length creeps longer
    return fp + fb


def _muscle_volume(m, L):
    return math.pi * radius(m, L) ** 2 * L - m.bladder_volume_m3


def lag_tube_volume(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    V = _muscle_volume(m, L) + 15e-6  # + fittings/tube
    dV = np.gradient(V, dt)
    K = 7e-7 / s  # orifice-like flow coefficient
    delay = int(round(0.008 / dt))
    Ps = np.concatenate([np.full(delay, P[0]), P[: P.size - delay]]) if delay else P
    nsub = max(1, int(math.ceil(dt / 5e-4)))
    h = dt / nsub
    Pm = P[0]
    out = np.empty_like(P)
    for k in range(P.size):
        for _ in range(nsub):
            d = Ps[k] - Pm
            Q = K * d / math.sqrt(abs(d) + 2e3)
            Pm += h * 1.2 * (Pm + PA) / V[k] * (Q - dV[k])
            Pm = max(Pm, 0.0)
        out[k] = Pm
    fp, fb = eq2_parts(m, out, L)
    return fp + fb


def lag_valve_saturation(ctx, s):
    m, L, P, dt = ctx["m"], ctx["L"], ctx["P"], ctx["dt"]
    tau = 0.04 * s
    rmax = 900e3 / s  # Pa/s flow saturation
    nsub = max(1, int(math.ceil(dt / 5e-4)))
    h = dt / nsub
    Pm = P[0]
    out = np.empty_like(P)
    for k in range(P.size):
        for _ in range(nsub):
            Pm += h * min(max((P[k] - Pm) / tau, -rmax), rmax)
        out[k] = Pm
    fp, fb = eq2_parts(m, out, L)
    return fp + fb


def off_zero(ctx, s):
    return base(ctx) + s * ctx["k"]["sign"] * 10.0


# outside the library -------------------------------------------------------------------


def out_p_gain(ctx, s):
    k = ctx["k"]
    return {"F": base(ctx), "Prec": ctx["P"] * (1 + k["sign"] * 0.07) + 3e3}


def out_crosstalk(ctx, s):
    F = base(ctx)
    return {"F": F + ctx["k"]["sign"] * 0.035 * ctx["P"] / 1e3}  # N per kPa


def out_stick_slip(ctx, s):
    m, L, dt = ctx["m"], ctx["L"], ctx["dt"]
    F = base(ctx)
    dL = np.diff(L, prepend=L[0])
    kf = 8000.0  # N/m fixture guide compliance
    e = 0.0
    out = np.empty_like(F)
    for k in range(F.size):
        e += kf * dL[k]
        if abs(e) > 6.0:  # breaks loose, slips to the kinetic level of the other side
            e = np.sign(e) * 1.0
        out[k] = e
    return {"F": F - out}


def out_thermal_fixture(ctx, s):
    m, L, P, t = ctx["m"], ctx["L"], ctx["P"], ctx["t"]
    dT = 25.0 * (1 - np.exp(-t / (0.5 * t[-1])))
    Ltrue = L - 6e-5 * dT  # mm-scale frame growth shortens the muscle
    fp, fb = eq2_parts(m, P, Ltrue)
    return {"F": fp + fb}


def out_backlash(ctx, s):
    m, L, P = ctx["m"], ctx["L"], ctx["P"]
    b = 3.0e-3
    F = base(ctx)
    for _ in range(30):  # gap closes one way when the muscle pushes, the other when it pulls
        Lt = L + 0.5 * b * np.tanh(F / 2.0)
        fp, fb = eq2_parts(m, P, Lt)
        F = 0.5 * F + 0.5 * (fp + fb)
    return {"F": F}


def out_aliasing(ctx, s):
    t = ctx["t"]
    F = base(ctx)
    f_vib = ctx["k"]["fvib"]
    return {"F": F + 5.0 * np.sin(2 * np.pi * f_vib * t + 0.3) * (0.5 + 0.5 * ctx["P"] / 4e5)}


EFFECTS = {
    "friction": {
        "PI_generalized": fr_PI,
        "LuGre_Stribeck": fr_LuGre,
        "Coulomb_normal_load": fr_coulomb_normal,
    },
    "viscoelasticity": {
        "fractional_KV": ve_fractional,
        "Prony3_bladder": ve_prony3_bladder,
        "Schapery_strain_tau": ve_schapery,
    },
    "end_effects": {"bulging_caps": end_caps_bulge, "stretch_cones": end_cones},
    "braid_compliance": {
        "bilinear_thread": braid_bilinear,
        "thread_creep": braid_creep,
        "power_law_thread": braid_power,
    },
    "softening": {"Ogden_Roxburgh": soft_ogden_roxburgh, "Mullins_recovery": soft_mullins_recovery},
    "drift": {
        "sigmoid_warmup": drift_sigmoid_warmup,
        "gain_step": drift_gain_step,
        "log_creep_length": drift_log_creep,
    },
    "pressure_lag": {"tube_volume_orifice": lag_tube_volume, "valve_saturation": lag_valve_saturation},
    "force_offset": {"zero_error": off_zero, "remount_two_files": off_zero},
}
OUTSIDE = {
    "p_sensor_gain": out_p_gain,
    "p_crosstalk": out_crosstalk,
    "stick_slip_fixture": out_stick_slip,
    "thermal_fixture": out_thermal_fixture,
    "backlash_coupling": out_backlash,
    "aliasing": out_aliasing,
}

# ------------------------------------------------------------------------------- the set
P_ALL = list(PROTOCOLS)


def build_cases():
    cases = []
    rr = np.random.default_rng(20261203)
    # clean: every protocol once (FAM1/FAM2 alternating), + 3 more
    for i, p in enumerate(P_ALL + ["random_bl", "step_hold", "isobaric_random"]):
        cases.append(dict(kind="clean", effect="none", form="clean", protocol=p))
    plan = {  # effect: list of (form, protocol)
        "friction": [
            ("PI_generalized", "isobaric_random"),
            ("PI_generalized", "fatigue20"),
            ("LuGre_Stribeck", "sine_multif"),
            ("LuGre_Stribeck", "step_hold"),
            ("Coulomb_normal_load", "slow_lowfs"),
            ("Coulomb_normal_load", "random_bl"),
        ],
        "viscoelasticity": [
            ("fractional_KV", "sine_multif"),
            ("fractional_KV", "step_hold"),
            ("Prony3_bladder", "pramp_multiL"),
            ("Prony3_bladder", "random_bl"),
            ("Schapery_strain_tau", "isobaric_random"),
            ("Schapery_strain_tau", "fatigue20"),
        ],
        "end_effects": [
            ("bulging_caps", "pramp_multiL"),
            ("bulging_caps", "isobaric_random"),
            ("bulging_caps", "random_bl"),
            ("stretch_cones", "slow_lowfs"),
            ("stretch_cones", "step_hold"),
        ],
        "braid_compliance": [
            ("bilinear_thread", "pramp_multiL"),
            ("bilinear_thread", "random_bl"),
            ("thread_creep", "step_hold"),
            ("thread_creep", "fatigue20"),
            ("power_law_thread", "isobaric_random"),
            ("power_law_thread", "slow_lowfs"),
        ],
        "softening": [
            ("Ogden_Roxburgh", "fatigue20"),
            ("Ogden_Roxburgh", "step_hold"),
            ("Ogden_Roxburgh", "pramp_multiL"),
            ("Mullins_recovery", "random_bl"),
            ("Mullins_recovery", "slow_lowfs"),
        ],
        "drift": [
            ("sigmoid_warmup", "fatigue20"),
            ("sigmoid_warmup", "pramp_multiL"),
            ("gain_step", "isobaric_random"),
            ("gain_step", "slow_lowfs"),
            ("log_creep_length", "step_hold"),
            ("log_creep_length", "sine_multif"),
        ],
        "pressure_lag": [
            ("tube_volume_orifice", "step_hold"),
            ("tube_volume_orifice", "random_bl"),
            ("tube_volume_orifice", "isobaric_random"),
            ("valve_saturation", "sine_multif"),
            ("valve_saturation", "random_bl"),
            ("valve_saturation", "fatigue20"),
        ],
        "force_offset": [
            ("zero_error", "slow_lowfs"),
            ("zero_error", "random_bl"),
            ("zero_error", "sine_multif"),
            ("remount_two_files", "pramp_multiL"),
            ("remount_two_files", "isobaric_random"),
        ],
    }
    for eff, lst in plan.items():
        for form, p in lst:
            cases.append(dict(kind="library", effect=eff, form=form, protocol=p))
    outs = [
        ("p_sensor_gain", "pramp_multiL"),
        ("p_sensor_gain", "isobaric_random"),
        ("p_crosstalk", "step_hold"),
        ("p_crosstalk", "sine_multif"),
        ("stick_slip_fixture", "isobaric_random"),
        ("thermal_fixture", "slow_lowfs"),
        ("backlash_coupling", "slow_lowfs"),
        ("backlash_coupling", "pramp_multiL"),
        ("aliasing", "slow_lowfs"),
        ("aliasing", "fatigue20"),
    ]
    for form, p in outs:
        cases.append(dict(kind="outside", effect="outside_library", form=form, protocol=p))
    for i, c in enumerate(cases):
        c["id"] = i
        c["seed"] = 7000 + 13 * i
        c["muscle"] = "FAM1" if (i * 7 + 3) % 3 else "FAM2"
        c["target_frac"] = float(rr.uniform(0.04, 0.12))
    return cases


def perturbed(m, rng):
    st = m.stress
    c = list(st.coefficients)
    c[0] *= 1 + rng.normal(0, 0.03)
    c[2] *= 1 + rng.normal(0, 0.03)
    return replace(
        m,
        rest_diameter_m=m.rest_diameter_m * (1 + rng.normal(0, 0.015)),
        theta_rest_deg=m.theta_rest_deg * (1 + rng.normal(0, 0.015)),
        bladder_volume_m3=m.bladder_volume_m3 * (1 + rng.normal(0, 0.02)),
        deadband_Pa=m.deadband_Pa * (1 + rng.normal(0, 0.04)),
        stress=StressLaw(st.name, tuple(c)),
    )


def _apply(fn, ctx, s):
    out = fn(ctx, s)
    return out if isinstance(out, dict) else {"F": out}


def calibrate(fn, ctx, F0, target, lo=1e-3, hi=1e3):
    """scale s so that the 99.5th percentile of |dF| = target (bisection in log s)."""

    def peak(s):
        return np.percentile(np.abs(_apply(fn, ctx, s)["F"] - F0), 99.5)

    a, b = math.log(lo), math.log(hi)
    for _ in range(18):
        mid = 0.5 * (a + b)
        if peak(math.exp(mid)) < target:
            a = mid
        else:
            b = mid
    s = math.exp(0.5 * (a + b))
    return s, peak(s)


INVERSE = {"tube_volume_orifice", "valve_saturation"}  # s grows the effect, all forms


def make_case(c):
    rng = np.random.default_rng(c["seed"])
    nominal = load_muscle(c["muscle"])
    m = perturbed(nominal, rng)
    t, L, P, dt = run_protocol(c["protocol"], rng, nominal)
    ctx = dict(
        m=m, t=t, L=L, P=P, dt=dt, k=dict(sign=float(rng.choice([-1, 1])), fvib=float(rng.uniform(46, 48)))
    )
    F0 = base(ctx)
    span = float(F0.max() - F0.min())
    info = dict(span_N=span, n=int(t.size), duration_s=float(t[-1]), fs=1 / dt)
    if c["kind"] == "clean":
        out = {"F": F0}
    elif c["kind"] == "library":
        fn = EFFECTS[c["effect"]][c["form"]]
        target = c["target_frac"] * span
        if c["effect"] == "force_offset":
            s = target / 10.0
            out = _apply(fn, ctx, s)
            pk = target
        else:
            s, pk = calibrate(fn, ctx, F0, target)
            out = _apply(fn, ctx, s)
        info.update(scale=s, peak_dF_N=float(pk), peak_frac=float(pk / span))
    else:
        out = _apply(OUTSIDE[c["form"]], ctx, 1.0)
        dF = out["F"] - F0
        if "Prec" in out:
            dF = dF + 0  # the force is right; the sensor is wrong
            pk = float(np.percentile(np.abs(nominal.push(out["Prec"], L) - nominal.push(P, L)), 99.5))
        else:
            pk = float(np.percentile(np.abs(dF), 99.5))
        info.update(peak_dF_N=pk, peak_frac=pk / span)
    sF = float(rng.uniform(0.3, 1.0))
    info["force_noise_N"] = sF
    F = out["F"]
    Prec = out.get("Prec", P)
    n = t.size
    Lr = L + rng.normal(0, 5e-6, n)
    Pr = np.maximum(Prec + rng.normal(0, 500, n), 0.0)
    Fr = F + rng.normal(0, sF, n)
    if c["form"] == "remount_two_files":
        half = n // 2
        c2 = ctx["k"]["sign"] * -0.6 * (s * 10.0)  # re-mounted: another zero
        Fr2 = Fr.copy()
        Fr2[half:] = Fr2[half:] - s * ctx["k"]["sign"] * 10.0 + c2
        recs = [
            Recording(t[:half], Lr[:half], Pr[:half], Fr2[:half]),
            Recording(t[half:] - t[half], Lr[half:], Pr[half:], Fr2[half:]),
        ]
        info["offsets_N"] = [s * ctx["k"]["sign"] * 10.0, c2]
    else:
        recs = [Recording(t, Lr, Pr, Fr)]
    return recs, nominal, info


def score(c, v):
    ans, conf, amb, cont = v.answer, bool(v.confident), bool(v.ambiguous), list(v.contenders)
    if c["kind"] == "clean":
        return "false_alarm" if (conf and ans != "none") else "ok"
    if c["kind"] == "outside":
        if conf and ans not in ("outside_library", "none"):
            return "FAIL"
        return "ok"
    truth = c["effect"]
    if amb:
        return "ambiguous_with_truth" if truth in cont else "ambiguous_without_truth"
    if conf:
        return "right_confident" if ans == truth else "wrong_confident"
    return "tentative_right" if ans == truth else "tentative_wrong"


# ================================================ the runner
def run_case(c: dict) -> dict:
    """Make one recording set of case ``c``, diagnose it blind and score the answer."""
    from efam_mujoco.diagnose import diagnose

    t0 = time.perf_counter()
    row = dict(c)
    try:
        recs, nominal, info = make_case(c)
        row.update(info)
        d = diagnose(recs, nominal, next_experiment=False)
        v = d.verdict
        row.update(answer=v.answer, p=float(v.probability), confident=bool(v.confident),
                   ambiguous=bool(v.ambiguous), contenders=list(v.contenders),
                   probabilities={k: round(float(x), 4) for k, x in v.probabilities.items()},
                   names=list(d.names), heldout_rms_before_N=float(d.heldout_rms_before_N),
                   heldout_rms_after_N=float(d.heldout_rms_after_N), noise_N=float(d.noise_N),
                   refit_shift={k: float(x) for k, x in d.refit_shift().items()})  # fmt: skip
        row["score"] = score(c, v)
    except Exception as e:  # noqa: BLE001 - a crash is a scored outcome, not the end of the run
        row.update(error=repr(e), tb=traceback.format_exc()[-1500:], score="crash")
    row["run_s"] = round(time.perf_counter() - t0, 1)
    return row


def summarise(rows: list[dict]) -> dict:
    """Counts per kind, per effect and form, and per protocol; the headline figures."""
    by_kind = collections.defaultdict(collections.Counter)
    by_form = collections.defaultdict(collections.Counter)
    by_protocol = collections.defaultdict(collections.Counter)
    for r in rows:
        by_kind[r["kind"]][r["score"]] += 1
        by_form[f"{r['effect']}/{r['form']}"][r["score"]] += 1
        if r["kind"] == "library":
            by_protocol[r["protocol"]][r["score"]] += 1
    lib = by_kind["library"]
    confident = lib["right_confident"] + lib["wrong_confident"]
    return {
        "headline": {
            "files": len(rows),
            "crashes": sum(r["score"] == "crash" for r in rows),
            "clean": sum(by_kind["clean"].values()),
            "clean_false_alarms": by_kind["clean"]["false_alarm"],
            "library": sum(lib.values()),
            "library_confident": confident,
            "library_right_confident": lib["right_confident"],
            "library_wrong_confident": lib["wrong_confident"],
            "top1_among_confident": lib["right_confident"] / confident if confident else None,
            "library_ambiguous": lib["ambiguous_with_truth"] + lib["ambiguous_without_truth"],
            "outside": sum(by_kind["outside"].values()),
            "outside_named_confident": by_kind["outside"]["FAIL"],
        },  # fmt: skip
        "kinds": {k: dict(v) for k, v in by_kind.items()},
        "forms": {k: dict(v) for k, v in sorted(by_form.items())},
        "protocols": {k: dict(v) for k, v in sorted(by_protocol.items())},
    }


def main(argv=None) -> int:
    """Run the set (or some of it), print a line per file and the summary, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", nargs="+", type=int, metavar="ID", help="case ids to run (0-64)")
    ap.add_argument("--replicate", nargs="+", type=int, metavar="ID",
                    help="the same form and protocol at two other seeds each")  # fmt: skip
    ap.add_argument("--out", help="results JSON (default bench/results/diagnose_blind3[_replicates].json)")
    args = ap.parse_args(argv)
    cases = build_cases()
    out = Path(args.out) if args.out else RESULTS
    if args.replicate:
        ids = set(args.replicate)
        cases = [
            dict(c, seed=c["seed"] + 100003 * r, replicate=r) for c in cases if c["id"] in ids for r in (1, 2)
        ]
        out = Path(args.out) if args.out else RESULTS.with_name("diagnose_blind3_replicates.json")
    elif args.only:
        cases = [c for c in cases if c["id"] in set(args.only)]
    t0 = time.perf_counter()
    rows = []
    for c in progress(cases, "blind3", len(cases)):
        r = run_case(c)
        rows.append(r)
        p = f"{r['p']:.2f}" if "p" in r else "-"
        print(f"[{len(rows):3d}/{len(cases)}] {r['id']:2d} {r['kind']:8s} {r['effect'] + '/' + r['form']:42s} "
              f"{r['protocol']:16s} -> {r.get('answer', 'crash'):16s} p={p} {r['score']:24s} {r['run_s']:5.1f} s",
              flush=True)  # fmt: skip
    summary = summarise(rows)
    wall = time.perf_counter() - t0
    write_json_atomic(out, {"summary": summary, "wall_s": wall, "cases": rows})
    print(summary["headline"])
    print(f"wrote {out} ({wall:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
