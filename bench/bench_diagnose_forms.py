"""The diagnosis on effect forms written by an outside reviewer: a blind set of 60 recordings.

The truth forms in this file were written by an outside reviewer WITHOUT reading the package's own
generator (``diagnose/virtual_bench.py``, ``diagnose/synth.py``) or the other benchmarks; that is
why they are kept here exactly as written (same forms, same protocols, same seeds and draw order,
so the figures are reproducible and comparable with the reviewer's report). From the package they
use only ``load_muscle``, ``Muscle.push`` / ``free_length`` (the base force), ``StressLaw`` and the
CSV format (``time_s,length_m,pressure_kPa,force_N``, force positive = push).

Each recording: a truth muscle (preset FAM1 or FAM2, stress coefficients x(1 + N(0, 3 %)), braid
angle + N(0, 0.12 deg), diameter x(1 + N(0, 1 %)), bladder volume x(1 + N(0, 2 %)), dead band
x(1 + N(0, 6 %))); one of eleven protocols planned on the datasheet muscle (isobaric strokes in
random pressure order, progressive-amplitude strokes, isometric pressure triangles, isometric
pressure staircases, length sinusoid with a mean, triangle strokes at two speeds, length chirp,
pressure chirp, random band-limited length and pressure, pressure sweeps while the length
oscillates, length steps with long holds); truth effects sized to a peak (99.5th percentile of
|dF|) of a share of the force span; load-cell, pressure and length noise; the values rounded as
the reviewer's CSV files were (0.1 ms, 1 um, 0.1 kPa, 1 mN).

Truth forms (the reviewer's own):

* friction: Bouc-Wen (n = 1.5) on strain plus an optional pressure drive, pressure-scaled;
  Maxwell-slip, 4 elasto-slide elements on strain + k P; Stribeck velocity friction
  (tanh-regularised, static/Coulomb 1.3-1.8, a small viscous part);
* viscoelasticity: 3-branch Prony series on strain (tau 0.3-60 s); Burgers element on strain;
  power-law (fractional) relaxation kernel (1 + t/t0)^-alpha on strain; stretched-exponential (KWW)
  relaxation of the total force;
* pressure_lag (the force sees the internal pressure, the file the commanded one): 2nd-order
  underdamped regulator; slew-rate limit + 1st-order lag; orifice-flow fill dP/dt = K sqrt|Pc - P|;
* drift: linear in time; warm-up exponential; gain creep (force loss proportional to P x t);
* force_offset: a constant load-cell zero error;
* softening: Mullins type, the bladder's share of Eq. 2 scaled by 1 - D(xmax)(1 - (x/xmax)^2);
* braid_compliance: thread length B(1 + c (P R_o / P_max R_rest)^n), n 1.3-2, Eq. 2 re-evaluated;
* end_effects: rigid end fittings, the active muscle d = 1.2-2 cm shorter;
* outside the library: fixture inertia -m a; mechanical vibration 5-12 Hz (+ 2nd harmonic); a
  force proportional to dP/dt; a length-sensor scale error of 7 %; a load-cell quadratic
  nonlinearity; the force channel skewed 8-14 ms behind length and pressure; lead-screw ripple
  sin(2 pi L / pitch).

The set: 10 clean, 35 one in-library effect, 5 two effects, 10 outside the library. Each recording
is diagnosed in process as ``efam diagnose --muscle <preset> FILE`` does (the nominal preset,
``diagnose([recording], load_muscle(preset), next_experiment=False)``) and scored: clean
``ok`` / ``FALSE-ALARM-conf|tent``; one or two effects ``right-conf``, ``WRONG-conf``,
``amb-contains``, ``amb-wrong``, ``right-tent``, ``wrong-tent`` (two effects: right = one of the
truths); outside ``ok`` (``outside_library``), ``FAIL-named-conf`` (a library effect named
confidently, p >= 0.8), ``missed(none)``. Counts per group and per truth form.

Usage: python bench/bench_diagnose_forms.py [--variant 0|1] [--only ID ...] [--jobs 2] [--out FILE]
       [--write-csv DIR]   (--variant 1: the reviewer's replica, the same plan with other seeds)
Writes bench/results/diagnose_forms.json (diagnose_forms_v1.json for --variant 1).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from efam_mujoco.diagnose import diagnose  # noqa: E402
from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.musclefile import load_muscle  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402
from efam_mujoco.recordings import Recording  # noqa: E402
from efam_mujoco.stress import StressLaw  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_diagnose import pin_one_core  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "diagnose_forms.json"
LIB = ["friction", "viscoelasticity", "end_effects", "braid_compliance", "softening", "drift",
       "pressure_lag", "force_offset"]  # fmt: skip
GROUPS = ("clean", "single", "two", "outside")
#: the reviewer's seeds: 4700 + k * 7919 (k = the file's place in the plan) + variant * 104729
SEED0, SEED_STEP, SEED_VARIANT = 4700, 7919, 104729


def seed_of(k: int, variant: int) -> int:
    """The seed of the ``k``-th file of the plan in seed set ``variant`` (0: the reviewer's own)."""
    return SEED0 + k * SEED_STEP + variant * SEED_VARIANT


HEADER = "time_s,length_m,pressure_kPa,force_N"


# ----------------------------------------------------------------------------- muscles
def perturbed_muscle(name, rng):
    """The datasheet muscle and the real one: its constants off by a few %."""
    m = load_muscle(name)
    for _ in range(50):
        c = np.array(m.stress.coefficients) * (1 + rng.normal(0, 0.03, len(m.stress.coefficients)))
        try:
            st = StressLaw(m.stress.name, tuple(float(v) for v in c))
            mt = dataclasses.replace(
                m,
                stress=st,
                theta_rest_deg=m.theta_rest_deg + rng.normal(0, 0.12),
                rest_diameter_m=m.rest_diameter_m * (1 + rng.normal(0, 0.01)),
                bladder_volume_m3=m.bladder_volume_m3 * (1 + rng.normal(0, 0.02)),
                deadband_Pa=max(m.deadband_Pa * (1 + rng.normal(0, 0.06)), 0.0),
            )
            return m, mt
        except Exception:
            continue
    raise RuntimeError("no stable perturbation")


def tension_eq2(m, P, L, B=None, N=None):
    """Eq. 2 (paper sign, pull +) re-written here so the thread length B may vary per sample."""
    B = m.thread_length_m if B is None else B
    N = m.turns if N is None else N
    P = np.maximum(P, 0.0)
    r_out = np.sqrt(np.maximum(B * B - L * L, 0.0)) / (2 * math.pi * N)
    V = m.bladder_volume_m3
    t = r_out - np.sqrt(np.maximum(r_out**2 - V / (math.pi * L), 0.0))
    eps_z = L / m.rest_length_m - 1.0
    eps_c = (r_out - t / 2) / (m.rest_outer_radius_m - m.rest_wall_thickness_m / 2) - 1.0
    gauge = np.maximum(P - m.deadband_Pa, 0.0)
    gas = gauge / (4 * math.pi * N * N) * (3 * L * L - B * B)
    blad = m.stress(eps_z, P) * V / L - m.stress(eps_c, P) * t * L * L / (2 * math.pi * r_out * N * N)
    return gas, blad


class FreeLen:
    """Free length vs pressure (nominal datasheet muscle: what a bench designer plans with)."""

    def __init__(self, m, pmax):
        """Tabulate the free length of ``m`` from 0 to 1.02 ``pmax``."""
        self.P = np.linspace(0, pmax * 1.02, 60)
        self.L = np.array(
            [m.free_length(p, check_units=False) if p > 1000 else m.rest_length_m for p in self.P]
        )
        self.L = np.maximum.accumulate(self.L)
        self.Lr = m.rest_length_m

    def __call__(self, P):
        """Free length (m) at pressure ``P`` (Pa)."""
        return np.interp(P, self.P, self.L)

    def p_for(self, L):
        """Lowest pressure whose free length reaches L."""
        return float(np.interp(L, self.L + np.arange(len(self.L)) * 1e-9, self.P))


# ----------------------------------------------------------------------------- signal helpers
def tri(phase):
    """Triangle 0..1..0 over phase in [0,1)."""
    ph = np.mod(phase, 1.0)
    return 1 - np.abs(2 * ph - 1)


def ramp_seq(segments, fs):
    """segments: list of (duration, value_end) piecewise linear from the previous value; returns array."""
    out = []
    cur = segments[0][1]
    for dur, v in segments:
        n = max(int(round(dur * fs)), 1)
        out.append(np.linspace(cur, v, n + 1)[1:])
        cur = v
    return np.concatenate(out)


def smooth_noise(n, fs, fc, rng):
    """Band-limited noise via FFT masking, normalised to [0,1]."""
    x = rng.normal(size=n)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(n, 1 / fs)
    X *= 1 / (1 + (f / fc) ** 6)
    X[0] = 0
    y = np.fft.irfft(X, n)
    y = (y - y.min()) / (y.max() - y.min())
    return y


def smoothstep_join(a, b, n):
    """``n`` samples from ``a`` to ``b`` along a half cosine."""
    s = 0.5 - 0.5 * np.cos(np.linspace(0, math.pi, n))
    return a + (b - a) * s


# ----------------------------------------------------------------------------- protocols
# every protocol returns P_cmd (Pa) and L (m) arrays at fs; every test begins vented at rest
def prefix(fs, Lr, P_first, L_first, fl):
    """Start vented at rest (2 s), pressurise at rest, then move to the first length."""
    n0 = int(2 * fs)
    P = [np.zeros(n0), np.linspace(0, P_first, int(2.5 * fs))]
    L = [np.full(n0, Lr), np.full(int(2.5 * fs), Lr)]
    n2 = int(1.5 * fs)
    P.append(np.full(n2, P_first))
    L.append(smoothstep_join(Lr, L_first, n2))
    return np.concatenate(P), np.concatenate(L)


def length_from_s(s, P, fl, frac=0.88):
    """Length at stroke share ``s``: rest + s (free length at P - rest) x ``frac``."""
    Lr = fl.Lr
    return Lr + np.clip(s, 0, 1) * (fl(P) - Lr) * frac


def proto_isobaric_random(rng, fs, fl, pmax):
    """Triangle strokes at 4-6 pressures in random order, vented between none."""
    levels = rng.permutation([0.27, 0.4, 0.53, 0.67, 0.8, 0.93, 1.0])[: rng.integers(4, 7)] * pmax
    period = rng.uniform(6, 14)
    P, L = [np.zeros(int(2 * fs))], [np.full(int(2 * fs), fl.Lr)]
    p_prev = 0.0
    for p in levels:
        n = int(2.5 * fs)
        P.append(np.linspace(p_prev, p, n))
        L.append(np.full(n, fl.Lr))
        ncyc = rng.integers(2, 4)
        t = np.arange(int(ncyc * period * fs)) / fs
        s = 0.02 + 0.93 * tri(t / period)
        P.append(np.full(t.size, p))
        L.append(length_from_s(s, p, fl))
        p_prev = p
    n = int(2.5 * fs)
    P.append(np.linspace(p_prev, 0, n))
    L.append(np.full(n, fl.Lr))
    desc = f"isobaric strokes at {len(levels)} pressures, random order, T={period:.1f}s"
    return np.concatenate(P), np.concatenate(L), desc


def proto_progressive(rng, fs, fl, pmax):
    """Strokes of growing then shrinking amplitude at 2 pressures (softening probe)."""
    period = rng.uniform(5, 10)
    amps = [0.3, 0.5, 0.7, 0.95, 0.6, 0.95, 0.4]
    P, L = [], []
    plevels = rng.permutation([0.6, 0.85])[:2] * pmax
    p0, l0 = prefix(fs, fl.Lr, plevels[0], fl.Lr, fl)
    P.append(p0)
    L.append(l0)
    for k, p in enumerate(plevels):
        if k:
            n = int(2 * fs)
            P.append(np.linspace(plevels[k - 1], p, n))
            L.append(np.full(n, fl.Lr))
        for a in amps:
            t = np.arange(int(period * fs)) / fs
            s = 0.01 + a * tri(t / period)
            P.append(np.full(t.size, p))
            L.append(length_from_s(s, p, fl))
    desc = f"progressive-amplitude strokes at 2 pressures, T={period:.1f}s"
    return np.concatenate(P), np.concatenate(L), desc


def _iso_lengths(rng, fl, pmax):
    """3-4 test lengths from 0-60 % of the stroke at the top pressure, in random order."""
    span = fl(pmax) - fl.Lr
    fr = rng.permutation([0.0, 0.15, 0.3, 0.45, 0.6])[: rng.integers(3, 5)]
    return fl.Lr + fr * span


def _isometric_start(fs, fl, pmax):
    """2 s vented at rest, then a 2.5 s ramp to the top pressure there: the start of both isometric tests."""
    P, L = [np.zeros(int(2 * fs))], [np.full(int(2 * fs), fl.Lr)]
    n = int(2.5 * fs)
    P.append(np.linspace(0, pmax, n))
    L.append(np.full(n, fl.Lr))
    return P, L


def _move_at_top(P, L, Lprev, Lk, fs, fl, pmax):
    """Append a 2 s move from ``Lprev`` to ``Lk`` at the top pressure; return the lowest pressure
    of the isometric test there (the muscle stays just engaged at that length)."""
    n = int(2 * fs)
    P.append(np.full(n, pmax))
    L.append(smoothstep_join(Lprev, Lk, n))
    return min(fl.p_for(Lk + 0.003) * 1.05, 0.6 * pmax) if Lk > fl.Lr + 1e-4 else 0.0


def proto_isometric_ramps(rng, fs, fl, pmax):
    """Isometric pressure triangles at 3-4 lengths in random order."""
    Ls = _iso_lengths(rng, fl, pmax)
    period = rng.uniform(8, 20)
    P, L = _isometric_start(fs, fl, pmax)
    Lprev = fl.Lr
    for Lk in Ls:
        plo = _move_at_top(P, L, Lprev, Lk, fs, fl, pmax)
        ncyc = 2
        t = np.arange(int(ncyc * period * fs)) / fs
        p = pmax - (pmax - plo) * tri(t / period)
        P.append(p)
        L.append(np.full(t.size, Lk))
        Lprev = Lk
    desc = f"isometric pressure ramps at {len(Ls)} lengths, T={period:.1f}s"
    return np.concatenate(P), np.concatenate(L), desc


def proto_isometric_steps(rng, fs, fl, pmax):
    """Isometric pressure staircases (valve steps, holds) at 3-4 lengths in random order."""
    Ls = _iso_lengths(rng, fl, pmax)
    hold = rng.uniform(3, 6)
    P, L = _isometric_start(fs, fl, pmax)
    Lprev = fl.Lr
    for Lk in Ls:
        plo = _move_at_top(P, L, Lprev, Lk, fs, fl, pmax)
        steps = np.linspace(plo, pmax, 5)
        seq = list(steps[::-1][1:]) + list(steps[1:])
        for v in seq:  # valve steps: 50 ms transitions
            nt = max(int(0.05 * fs), 1)
            nh = int(hold * fs)
            P.append(np.linspace(P[-1][-1], v, nt))
            L.append(np.full(nt, Lk))
            P.append(np.full(nh, v))
            L.append(np.full(nh, Lk))
        Lprev = Lk
    desc = f"isometric pressure staircases at {len(Ls)} lengths, holds {hold:.1f}s"
    return np.concatenate(P), np.concatenate(L), desc


def proto_sine_mean(rng, fs, fl, pmax):
    """A length sinusoid about a non-zero mean at 2 pressures."""
    f = rng.uniform(0.15, 0.5)
    levels = rng.permutation([0.5, 0.75, 1.0])[:2] * pmax
    P, L = [], []
    mean, amp = rng.uniform(0.4, 0.55), rng.uniform(0.25, 0.38)
    p0, l0 = prefix(fs, fl.Lr, levels[0], length_from_s(mean, levels[0], fl), fl)
    P.append(p0)
    L.append(l0)
    for k, p in enumerate(levels):
        if k:
            n = int(3 * fs)
            pp = np.linspace(levels[k - 1], p, n)
            P.append(pp)
            L.append(length_from_s(mean, pp, fl))
        t = np.arange(int(rng.integers(8, 13) / f * fs)) / fs
        s = mean + amp * np.sin(2 * math.pi * f * t)
        P.append(np.full(t.size, p))
        L.append(length_from_s(s, p, fl))
    desc = f"length sinusoid f={f:.2f}Hz, mean s={mean:.2f} at 2 pressures"
    return np.concatenate(P), np.concatenate(L), desc


def proto_triangle_two_speeds(rng, fs, fl, pmax):
    """Triangle strokes at one pressure, fast (T 2.5-4 s) then slow (16-25 s) then fast."""
    p = rng.uniform(0.6, 1.0) * pmax
    T1, T2 = rng.uniform(2.5, 4), rng.uniform(16, 25)
    P, L = [], []
    p0, l0 = prefix(fs, fl.Lr, p, fl.Lr, fl)
    P.append(p0)
    L.append(l0)
    for T, nc in ((T1, 6), (T2, 2), (T1, 4)):
        t = np.arange(int(nc * T * fs)) / fs
        s = 0.02 + 0.9 * tri(t / T)
        P.append(np.full(t.size, p))
        L.append(length_from_s(s, p, fl))
    desc = f"triangle strokes at P={p / 1e3:.0f}kPa, T={T1:.1f}s and {T2:.1f}s"
    return np.concatenate(P), np.concatenate(L), desc


def proto_chirp_length(rng, fs, fl, pmax):
    """A length chirp 0.05 -> 1.5-3 Hz at one pressure."""
    p = rng.uniform(0.6, 1.0) * pmax
    dur = rng.uniform(60, 90)
    f0, f1 = 0.05, rng.uniform(1.5, 3.0)
    t = np.arange(int(dur * fs)) / fs
    ph = 2 * math.pi * (f0 * t + (f1 - f0) * t**2 / (2 * dur))
    s = 0.5 - 0.4 * np.cos(ph)
    s0 = s[0]
    p0, l0 = prefix(fs, fl.Lr, p, length_from_s(s0, p, fl), fl)
    return (
        np.concatenate([p0, np.full(t.size, p)]),
        np.concatenate([l0, length_from_s(s, p, fl)]),
        f"length chirp 0.05-{f1:.1f}Hz at P={p / 1e3:.0f}kPa, {dur:.0f}s",
    )


def proto_chirp_pressure(rng, fs, fl, pmax):
    """A pressure chirp 0.05 -> 1.5-3 Hz at one fixed length."""
    Lk = fl.Lr + rng.uniform(0.0, 0.3) * (fl(pmax) - fl.Lr)
    plo = max(fl.p_for(Lk + 0.003) * 1.1, 0.15 * pmax)
    dur = rng.uniform(60, 90)
    f0, f1 = 0.05, rng.uniform(1.5, 3.0)
    t = np.arange(int(dur * fs)) / fs
    ph = 2 * math.pi * (f0 * t + (f1 - f0) * t**2 / (2 * dur))
    p = plo + (pmax - plo) * (0.5 - 0.5 * np.cos(ph))
    n = int(2 * fs)
    P = np.concatenate([np.zeros(n), np.linspace(0, plo, n), np.full(n, plo), p])
    L = np.concatenate(
        [np.full(n, fl.Lr), np.full(n, fl.Lr), smoothstep_join(fl.Lr, Lk, n), np.full(t.size, Lk)]
    )
    return P, L, f"pressure chirp 0.05-{f1:.1f}Hz at fixed L (+{(Lk / fl.Lr - 1) * 100:.0f}%), {dur:.0f}s"


def proto_random(rng, fs, fl, pmax):
    """Random band-limited length AND pressure."""
    dur = rng.uniform(80, 120)
    n = int(dur * fs)
    fcL, fcP = rng.uniform(0.3, 0.8), rng.uniform(0.1, 0.4)
    s = 0.03 + 0.9 * smooth_noise(n, fs, fcL, rng)
    p = pmax * (0.25 + 0.75 * smooth_noise(n, fs, fcP, rng))
    p0, l0 = prefix(fs, fl.Lr, p[0], length_from_s(s[0], p[0], fl), fl)
    return (
        np.concatenate([p0, p]),
        np.concatenate([l0, length_from_s(s, p, fl)]),
        f"random band-limited L (fc {fcL:.2f}Hz) and P (fc {fcP:.2f}Hz), {dur:.0f}s",
    )


def proto_sweep_moving(rng, fs, fl, pmax):
    """Slow pressure triangles while the length oscillates."""
    Tp = rng.uniform(25, 40)
    fL = rng.uniform(0.2, 0.45)
    dur = 3 * Tp
    t = np.arange(int(dur * fs)) / fs
    p = pmax * (0.2 + 0.8 * tri(t / Tp))
    s = 0.45 + 0.4 * np.sin(2 * math.pi * fL * t)
    p0, l0 = prefix(fs, fl.Lr, p[0], length_from_s(s[0], p[0], fl), fl)
    return (
        np.concatenate([p0, p]),
        np.concatenate([l0, length_from_s(s, p, fl)]),
        f"pressure triangle sweeps T={Tp:.0f}s while length oscillates f={fL:.2f}Hz",
    )


def proto_long_holds(rng, fs, fl, pmax):
    """Length steps in random order with 12-20 s holds at one pressure."""
    p = rng.uniform(0.6, 1.0) * pmax
    levels = rng.permutation([0.1, 0.3, 0.5, 0.7, 0.9, 0.2, 0.6, 0.8])
    hold = rng.uniform(12, 20)
    P, L = [], []
    p0, l0 = prefix(fs, fl.Lr, p, fl.Lr, fl)
    P.append(p0)
    L.append(l0)
    cur = 0.0
    for lv in list(levels) + [0.0]:
        nt = int(1.0 * fs)
        nh = int(hold * fs)
        s = np.concatenate([np.linspace(cur, lv, nt), np.full(nh, lv)])
        P.append(np.full(s.size, p))
        L.append(length_from_s(s, p, fl))
        cur = lv
    desc = f"length steps with {hold:.0f}s holds at P={p / 1e3:.0f}kPa"
    return np.concatenate(P), np.concatenate(L), desc


PROTOCOLS = {
    "isobaric_random": proto_isobaric_random, "progressive": proto_progressive,
    "isometric_ramps": proto_isometric_ramps, "isometric_steps": proto_isometric_steps,
    "sine_mean": proto_sine_mean, "triangle_2speeds": proto_triangle_two_speeds,
    "chirp_length": proto_chirp_length, "chirp_pressure": proto_chirp_pressure,
    "random": proto_random, "sweep_moving": proto_sweep_moving, "long_holds": proto_long_holds,
}  # fmt: skip


# ----------------------------------------------------------------------------- truth effects
def lag1(u, dt, tau):
    """First-order lag of ``u`` with time constant ``tau``, started at ``u[0]``."""
    a = math.exp(-dt / tau)
    y = np.empty_like(u)
    acc = u[0]
    for i in range(u.size):
        acc = a * acc + (1 - a) * u[i]
        y[i] = acc
    return y


def conv_hist(du, kernel):
    """y_k = sum_{j<=k} kernel[k-j] du_j via FFT."""
    n = du.size
    m = 1 << int(math.ceil(math.log2(2 * n)))
    return np.fft.irfft(np.fft.rfft(du, m) * np.fft.rfft(kernel, m), m)[:n]


# pressure paths (what the muscle sees); the CSV keeps the commanded/upstream one
def p_second_order(Pc, dt, fn, zeta):
    """A 2nd-order regulator (natural frequency ``fn`` Hz, damping ``zeta``) following ``Pc``."""
    wn = 2 * math.pi * fn
    sub = max(1, int(math.ceil(dt * wn * 20)))
    h = dt / sub
    p, v = Pc[0], 0.0
    out = np.empty_like(Pc)
    for i in range(Pc.size):
        for _ in range(sub):
            a = wn * wn * (Pc[i] - p) - 2 * zeta * wn * v
            v += a * h
            p += v * h
        out[i] = max(p, 0.0)
    return out


def p_slew(Pc, dt, rate, tau):
    """A slew-rate limit (Pa/s) followed by a first-order lag ``tau`` following ``Pc``."""
    out = np.empty_like(Pc)
    p = Pc[0]
    y = Pc[0]
    a = math.exp(-dt / tau)
    for i in range(Pc.size):
        p += np.clip(Pc[i] - p, -rate * dt, rate * dt)
        y = a * y + (1 - a) * p
        out[i] = y
    return out


def p_orifice(Pc, dt, K):
    """dP/dt = K sign(Pc-P) sqrt(|Pc-P|) (flow through an orifice), Pa/s with K in Pa^0.5/s."""
    out = np.empty_like(Pc)
    p = Pc[0]
    sub = 4
    h = dt / sub
    for i in range(Pc.size):
        for _ in range(sub):
            d = Pc[i] - p
            step = K * math.copysign(math.sqrt(abs(d)), d) * h
            p += step if abs(step) < abs(d) else d
        out[i] = p
    return out


def bouc_wen(u, w, n=1.5, beta=0.6, gamma=0.4):
    """Bouc-Wen hysteretic state driven by ``u`` over width ``w`` (sub-stepped)."""
    z = np.zeros_like(u)
    zz = 0.0
    du = np.diff(u, prepend=u[0]) / w
    for i in range(u.size):
        d = du[i]
        k = max(1, int(abs(d) / 0.05) + 1)
        h = d / k
        for _ in range(k):
            zz += h - beta * abs(h) * abs(zz) ** (n - 1) * zz - gamma * h * abs(zz) ** n
        z[i] = zz
    return z


def maxwell_slip(u, widths, weights):
    """Weighted mean of elasto-slide elements (saturating at +-1 over ``widths``) driven by ``u``."""
    out = np.zeros_like(u)
    for w, g in zip(widths, weights):
        z = 0.0
        zs = np.empty_like(u)
        prev = u[0]
        for i in range(u.size):
            z = min(max(z + (u[i] - prev) / w, -1.0), 1.0)
            prev = u[i]
            zs[i] = z
        out += g * zs
    return out / sum(weights)


def burgers(u, dt, tau_m, tau_k, ratio):
    """Burgers element under strain control, unit E1: sigma = (u - uv - uk)."""
    sig = np.empty_like(u)
    uv = 0.0
    uk = 0.0
    E2 = ratio
    eta1 = tau_m
    eta2 = tau_k * E2
    sub = max(1, int(math.ceil(dt / (0.2 * min(tau_k / (1 + E2), tau_m)))))
    h = dt / sub
    u0 = u[0]
    for i in range(u.size):
        for _ in range(sub):
            s = (u[i] - u0) - uv - uk
            uv += s / eta1 * h
            uk += (s - E2 * uk) / eta2 * h
        sig[i] = (u[i] - u0) - uv - uk
    return sig


class Sim:
    """Holds one recording's true signals and builds the measured force."""

    def __init__(self, m_nom, m_true, t, Pc, L, pmax):
        """The truth muscle's signals: time, commanded pressure, length; the internal pressure starts as the commanded one."""
        self.m_nom, self.m, self.t, self.Pc, self.L, self.pmax = m_nom, m_true, t, Pc, L, pmax
        self.dt = t[1] - t[0]
        self.Pint = Pc.copy()
        self.x = L / m_true.rest_length_m - 1

    def push(self, P=None, L=None, m=None):
        """The base push force (N) of muscle ``m`` (default: the truth) at the internal pressure."""
        m = m or self.m
        return m.push(self.Pint if P is None else P, self.L if L is None else L)


def prel(sim):
    """The internal pressure over the top pressure, clipped to [0, 1.2] (read when called)."""
    return np.clip(sim.Pint / sim.pmax, 0, 1.2)


def lag_path(form, Pc, dt, a, b, k):
    """The pressure the muscle sees under lag ``form`` (parameters ``a``, ``b``), its time scale x ``k``."""
    if form == "second_order":
        return p_second_order(Pc, dt, a / k, b)
    if form == "slew":
        return p_slew(Pc, dt, a / k, b * k)
    return p_orifice(Pc, dt, a / k)


def lag_words(form, a, b, k):
    """The lag ``form`` with its time scale x ``k``, in words."""
    if form == "second_order":
        return f"2nd-order underdamped regulator (fn {a / k:.2f}Hz, zeta {b:.2f})"
    if form == "slew":
        return f"slew-rate limit {a / k / 1e3:.0f} kPa/s + lag {b * k * 1e3:.0f} ms"
    return f"orifice-flow fill dP/dt=K sqrt|Pc-P| (K {a / k:.0f} Pa^0.5/s)"


def lag_peak(sim, form, a, b, k, F0, span):
    """Peak (99.5th percentile) force change over the span from the lag ``form`` at scale ``k``."""
    return np.percentile(np.abs(sim.m.push(lag_path(form, sim.Pc, sim.dt, a, b, k), sim.L) - F0), 99.5) / span


def apply_effect(sim, kind, form, size, rng, span):
    """Returns (dF additive or None, new base force or None, description, param dict). size = target peak/span."""
    t, dt, x, Pc = sim.t, sim.dt, sim.x, sim.Pc
    if kind == "friction":
        if form == "bouc_wen":
            w = rng.uniform(0.008, 0.02)
            kp = rng.choice([0.0, 0.08])
            u = x + kp * sim.Pint / 1e6
            z = bouc_wen(u, w)
            z = z / max(np.max(np.abs(z)), 1e-9)
            g = -(0.35 + 0.65 * prel(sim)) * z
            return g, None, f"Bouc-Wen (n=1.5, width {w:.3f} strain, P-drive {kp})", {"w": w, "kp": kp}
        if form == "maxwell_slip":
            widths = np.array([0.002, 0.006, 0.015, 0.035]) * rng.uniform(0.7, 1.4)
            weights = rng.uniform(0.5, 1.5, 4)
            kp = rng.choice([0.05, 0.12])
            u = x + kp * sim.Pint / 1e6
            z = maxwell_slip(u, widths, weights)
            g = -(0.3 + 0.7 * prel(sim)) * z
            return g, None, f"Maxwell-slip 4 elements (P-drive {kp})", {"widths": widths.tolist(), "kp": kp}
        if form == "stribeck":
            v = np.gradient(lag1(x, dt, 0.02), dt)
            vs = rng.uniform(0.005, 0.02)
            ve = vs / 8
            ratio = rng.uniform(1.3, 1.8)
            bv = rng.uniform(0.0, 0.3)
            g = -((1 + (ratio - 1) * np.exp(-((v / vs) ** 2))) * np.tanh(v / ve) + bv * v / vs) * (
                0.3 + 0.7 * prel(sim)
            )
            desc = f"Stribeck velocity friction (vs {vs:.3f}/s, Fs/Fc {ratio:.2f}, viscous {bv:.2f})"
            return g, None, desc, {"vs": vs}
    if kind == "viscoelasticity":
        if form == "prony3":
            taus = np.array([0.4, 4.0, 40.0]) * rng.uniform(0.6, 1.6)
            gs = rng.uniform(0.5, 1.5, 3)
            g = -(0.4 + 0.6 * prel(sim)) * sum(gi * (x - lag1(x, dt, ti)) for gi, ti in zip(gs, taus))
            return (
                g,
                None,
                f"3-branch Prony on strain, tau {np.round(taus, 2).tolist()} s",
                {"taus": taus.tolist()},
            )
        if form == "burgers":
            tm, tk = rng.uniform(8, 30), rng.uniform(0.5, 3)
            g = -(0.4 + 0.6 * prel(sim)) * burgers(x, dt, tm, tk, rng.uniform(1, 3))
            return g, None, f"Burgers element on strain (tau_M {tm:.1f}s, tau_KV {tk:.1f}s)", {}
        if form == "fractional":
            alpha, t0 = rng.uniform(0.2, 0.45), rng.uniform(0.05, 0.3)
            ker = (1 + t / t0) ** (-alpha) - (1 + t[-1] / t0) ** (-alpha)
            g = -(0.4 + 0.6 * prel(sim)) * conv_hist(np.diff(x, prepend=x[0]), ker)
            return g, None, f"power-law relaxation on strain (alpha {alpha:.2f}, t0 {t0:.2f}s)", {}
        if form == "kww_force":
            tau, beta = rng.uniform(1, 10), rng.uniform(0.4, 0.7)
            F0 = sim.push()
            ker = 1 - np.exp(-((t / tau) ** beta))
            g = -conv_hist(np.diff(F0, prepend=F0[0]), ker)
            desc = f"stretched-exp (KWW) relaxation of the total force (tau {tau:.1f}s, beta {beta:.2f})"
            return g, None, desc, {}
    if kind == "pressure_lag":
        # the lag's time scale k is searched so that the force change peaks at `size` of the span
        if form == "second_order":
            a, b = rng.uniform(0.8, 2.5), rng.uniform(0.3, 0.6)  # fn0 (Hz), zeta
        elif form == "slew":
            a, b = rng.uniform(150e3, 500e3), rng.uniform(0.03, 0.15)  # rate0 (Pa/s), tau0 (s)
        else:
            form, a, b = "orifice", rng.uniform(1500, 4000), 0.0  # K0 (Pa^0.5/s)
        F0 = sim.push()
        lo, hi = math.log(0.02), math.log(200.0)
        for _ in range(18):
            mid = 0.5 * (lo + hi)
            if lag_peak(sim, form, a, b, math.exp(mid), F0, span) > size:
                hi = mid
            else:
                lo = mid
        k = math.exp(0.5 * (lo + hi))
        sim.Pint = lag_path(form, Pc, dt, a, b, k)
        return None, sim.push(), lag_words(form, a, b, k), {"k": k}
    if kind == "drift":
        T = t[-1]
        if form == "linear":
            return np.sign(rng.normal()) * t / T, None, "linear load-cell drift", {}
        if form == "warmup":
            tc = rng.uniform(0.15, 0.4) * T
            return (
                np.sign(rng.normal()) * (1 - np.exp(-t / tc)),
                None,
                f"warm-up exponential (T {tc:.0f}s)",
                {"T_s": tc},
            )
        if form == "gain":
            return -prel(sim) * t / T, None, "gain creep: force loss growing linearly in time x P", {}
    if kind == "force_offset":
        return np.full_like(t, np.sign(rng.normal())), None, "constant load-cell zero offset", {}
    if kind == "softening":
        m = sim.m
        gas, blad = tension_eq2(m, sim.Pint, sim.L)
        xm = np.maximum.accumulate(np.maximum(x, 0.0))
        D = size * 3
        rel = np.where(xm > 1e-4, np.clip(x, 0, None) / np.maximum(xm, 1e-4), 1.0)
        eta = 1 - D * (xm / max(xm[-1], 1e-4)) * (1 - rel**2)
        F = -(gas + eta * blad)
        return None, F, f"Mullins bladder softening, eta=1-D(xmax)(1-(x/xmax)^2), D {D:.2f}", {"D": D}
    if kind == "braid_compliance":
        m = sim.m
        c = size * rng.uniform(0.6, 1.0) * 0.15
        nexp = rng.uniform(1.3, 2.0)
        Tref = sim.pmax * m.rest_outer_radius_m
        B = m.thread_length_m
        F0 = sim.push()
        for _ in range(3):  # rescale c once or twice to the target size
            B = m.thread_length_m
            for _ in range(4):
                r = np.sqrt(np.maximum(B**2 - sim.L**2, 0)) / (2 * math.pi * m.turns)
                B = m.thread_length_m * (1 + c * (np.maximum(sim.Pint, 0) * r / Tref) ** nexp)
            gas, blad = tension_eq2(m, sim.Pint, sim.L, B=B)
            pk = np.percentile(np.abs(-(gas + blad) - F0), 99.5) / span
            c *= size / max(pk, 1e-9)
        c /= size / max(pk, 1e-9)
        return None, -(gas + blad), f"braid thread stretch dB/B = {c:.4f} (P R_o / Tref)^{nexp:.2f}", {"c": c}
    if kind == "end_effects":
        m = sim.m
        d = size
        Lr = m.rest_length_m
        ma = dataclasses.replace(
            m, rest_length_m=Lr - d, bladder_volume_m3=m.bladder_volume_m3 * (Lr - d) / Lr
        )
        return (
            None,
            ma.push(sim.Pint, sim.L - d),
            f"rigid fittings: active length L-{d * 100:.2f}cm",
            {"d_m": d},
        )
    # ---------------- outside the library
    if kind == "inertia":
        Ls = lag1(lag1(sim.L, dt, 0.01), dt, 0.01)
        a = np.gradient(np.gradient(Ls, dt), dt)
        return -a / max(np.max(np.abs(a)), 1e-9), None, "fixture inertia -m*a", {}
    if kind == "vibration":
        f = rng.uniform(5, 12)
        g = np.sin(2 * math.pi * f * t + rng.uniform(0, 6)) + 0.4 * np.sin(4 * math.pi * f * t)
        return g / 1.4, None, f"mechanical vibration {f:.1f} Hz (+2nd harmonic)", {}
    if kind == "pressure_rate":
        dp = np.gradient(lag1(Pc, dt, 0.02), dt)
        return dp / max(np.max(np.abs(dp)), 1e-9), None, "force proportional to dP/dt", {}
    if kind == "ripple":
        lam = rng.uniform(0.004, 0.01)
        return (
            np.sin(2 * math.pi * sim.L / lam),
            None,
            f"lead-screw ripple vs position, pitch {lam * 1e3:.1f}mm",
            {},
        )
    if kind == "loadcell_quadratic":
        F0 = sim.push()
        g = (F0 - F0.min()) ** 2 / max((F0.max() - F0.min()) ** 2, 1e-9) * np.sign(rng.normal())
        return g, None, "load-cell quadratic nonlinearity", {}
    raise ValueError(kind + "/" + form)


def scale_to(shape, span, size):
    """``shape`` scaled so its 99.5th-percentile magnitude is ``size`` x ``span``."""
    pk = np.percentile(np.abs(shape), 99.5)
    return shape * (size * span / max(pk, 1e-12))


# ----------------------------------------------------------------------------- the set
def plan():
    """(id, truth label, [(kind, form, size)], protocol, muscle, fs) for every file, in seed order."""
    P = []

    def add(i, label, eff, proto, mus="FAM1", fs=200):
        """Append one file to the plan."""
        P.append(dict(id=i, truth=label, effects=eff, protocol=proto, muscle=mus, fs=fs))

    # clean
    for i, (pr, mu, fs) in enumerate([
            ("isobaric_random", "FAM1", 100), ("isometric_ramps", "FAM2", 100), ("sine_mean", "FAM1", 200),
            ("chirp_length", "FAM2", 250), ("random", "FAM1", 200), ("sweep_moving", "FAM2", 100),
            ("long_holds", "FAM1", 50), ("triangle_2speeds", "FAM2", 500), ("isometric_steps", "FAM1", 200),
            ("chirp_pressure", "FAM1", 250)]):  # fmt: skip
        add(f"c{i:02d}", "none", [], pr, mu, fs)
    # friction
    for i, (form, pr, mu, fs, sz) in enumerate([
            ("bouc_wen", "chirp_length", "FAM1", 250, 0.07), ("bouc_wen", "isobaric_random", "FAM2", 100, 0.05),
            ("maxwell_slip", "isometric_ramps", "FAM1", 100, 0.06), ("maxwell_slip", "random", "FAM2", 200, 0.06),
            ("stribeck", "triangle_2speeds", "FAM1", 200, 0.05), ("stribeck", "sine_mean", "FAM2", 200, 0.06)]):  # fmt: skip
        add(f"f{i:02d}", "friction", [("friction", form, sz)], pr, mu, fs)
    # viscoelasticity
    for i, (form, pr, mu, fs, sz) in enumerate([
            ("prony3", "long_holds", "FAM1", 100, 0.08), ("prony3", "chirp_length", "FAM2", 250, 0.07),
            ("burgers", "triangle_2speeds", "FAM1", 200, 0.07), ("fractional", "sine_mean", "FAM2", 100, 0.08),
            ("kww_force", "isometric_steps", "FAM1", 200, 0.06), ("kww_force", "random", "FAM2", 200, 0.06)]):  # fmt: skip
        add(f"v{i:02d}", "viscoelasticity", [("viscoelasticity", form, sz)], pr, mu, fs)
    # pressure lag: the lag time scale is searched so the force change peaks at sz of the span
    for i, (form, pr, mu, fs, sz) in enumerate([
            ("second_order", "chirp_pressure", "FAM1", 250, 0.08), ("second_order", "isometric_steps", "FAM2", 500, 0.12),
            ("slew", "random", "FAM1", 200, 0.06), ("slew", "isometric_steps", "FAM1", 200, 0.12),
            ("orifice", "sweep_moving", "FAM2", 200, 0.06)]):  # fmt: skip
        add(f"p{i:02d}", "pressure_lag", [("pressure_lag", form, sz)], pr, mu, fs)
    # drift
    for i, (form, pr, mu, fs, sz) in enumerate([
            ("linear", "isobaric_random", "FAM1", 100, 0.06), ("linear", "chirp_pressure", "FAM2", 200, 0.05),
            ("warmup", "long_holds", "FAM1", 50, 0.06), ("warmup", "random", "FAM2", 200, 0.07),
            ("gain", "sine_mean", "FAM1", 100, 0.06)]):  # fmt: skip
        add(f"d{i:02d}", "drift", [("drift", form, sz)], pr, mu, fs)
    for i, (pr, mu, fs, sz) in enumerate([
            ("isometric_ramps", "FAM1", 100, 0.05), ("sine_mean", "FAM2", 200, 0.04),
            ("chirp_length", "FAM1", 250, 0.06)]):  # fmt: skip
        add(f"o{i:02d}", "force_offset", [("force_offset", "const", sz)], pr, mu, fs)
    for i, (pr, mu, fs, sz) in enumerate([
            ("progressive", "FAM1", 100, 0.12), ("progressive", "FAM2", 200, 0.10),
            ("isobaric_random", "FAM1", 100, 0.12), ("random", "FAM2", 200, 0.10)]):  # fmt: skip
        add(f"s{i:02d}", "softening", [("softening", "mullins", sz)], pr, mu, fs)
    for i, (pr, mu, fs, sz) in enumerate([
            ("isobaric_random", "FAM1", 100, 0.10), ("isometric_ramps", "FAM2", 100, 0.10),
            ("random", "FAM1", 200, 0.10)]):  # fmt: skip
        add(f"b{i:02d}", "braid_compliance", [("braid_compliance", "powerlaw", sz)], pr, mu, fs)
    for i, (pr, mu, fs, sz) in enumerate([
            ("isobaric_random", "FAM2", 100, 0.012), ("isometric_steps", "FAM1", 200, 0.015),
            ("sine_mean", "FAM1", 200, 0.02)]):  # fmt: skip
        add(f"e{i:02d}", "end_effects", [("end_effects", "rigid_fittings", sz)], pr, mu, fs)
    # two-effect files: truth = both names
    for i, (effs, pr, mu, fs) in enumerate([
            ([("friction", "maxwell_slip", 0.05), ("drift", "linear", 0.05)], "isobaric_random", "FAM1", 100),
            ([("viscoelasticity", "prony3", 0.07), ("force_offset", "const", 0.05)], "triangle_2speeds", "FAM2", 200),
            ([("pressure_lag", "second_order", 0.07), ("friction", "bouc_wen", 0.05)], "random", "FAM1", 200),
            ([("softening", "mullins", 0.10), ("drift", "warmup", 0.05)], "progressive", "FAM2", 100),
            ([("braid_compliance", "powerlaw", 0.10), ("force_offset", "const", 0.05)], "isometric_ramps", "FAM1", 100)]):  # fmt: skip
        add(f"m{i:02d}", "+".join(e[0] for e in effs), effs, pr, mu, fs)
    # outside the library
    for i, (kind, pr, mu, fs, sz) in enumerate([
            ("inertia", "chirp_length", "FAM1", 250, 0.06), ("inertia", "random", "FAM2", 500, 0.05),
            ("vibration", "sine_mean", "FAM1", 200, 0.04), ("vibration", "isometric_ramps", "FAM2", 250, 0.05),
            ("pressure_rate", "chirp_pressure", "FAM1", 250, 0.06), ("pressure_rate", "sweep_moving", "FAM2", 200, 0.06),
            ("length_scale", "isobaric_random", "FAM1", 100, 0.07), ("loadcell_quadratic", "isometric_ramps", "FAM1", 100, 0.06),
            ("time_skew", "chirp_length", "FAM2", 250, 0.04), ("ripple", "triangle_2speeds", "FAM1", 200, 0.04)]):  # fmt: skip
        add(f"x{i:02d}", "outside_library", [(kind, "-", sz)], pr, mu, fs)
    return P


def effect_order(effect):
    """Base-replacing effects first (pressure path, then geometry), additive ones after."""
    kind = effect[0]
    return (
        0 if kind == "pressure_lag" else 1 if kind in ("softening", "braid_compliance", "end_effects") else 2
    )


def quantised(values, digits):
    """``values`` as the reviewer's CSV held them (``digits`` decimals) and as read back: text, floats."""
    text = [f"{v:.{digits}f}" for v in values]
    return text, np.fromiter(map(float, text), dtype=float, count=len(text))


def generate_one(spec, seed):
    """One recording of ``spec`` by its truth (the reviewer's generator, same draws): the truth
    entry, the recording in SI as ``efam diagnose`` reads the CSV, and the CSV's lines."""
    rng = np.random.default_rng(seed)
    m_nom, m_true = perturbed_muscle(spec["muscle"], rng)
    pmax = rng.uniform(480e3, 517e3)
    fl = FreeLen(m_nom, pmax)
    fs = spec["fs"]
    Pc, L, pdesc = PROTOCOLS[spec["protocol"]](rng, fs, fl, pmax)
    n = min(Pc.size, L.size)
    Pc, L = Pc[:n], L[:n]
    # mild actuator smoothing of the commanded length (a real rig does not jump)
    L = lag1(L, 1 / fs, 0.01)
    t = np.arange(n) / fs
    sim = Sim(m_nom, m_true, t, Pc, L, pmax)
    F_clean = sim.push()
    span = float(np.percentile(F_clean, 99.5) - np.percentile(F_clean, 0.5))
    F = F_clean.copy()
    L_meas = L.copy()
    descs, sizes, truths = [], [], []
    Fbase = F_clean
    for kind, form, size in sorted(spec["effects"], key=effect_order):
        if kind == "length_scale":
            e = size * rng.choice([-1, 1])
            L_meas = m_true.rest_length_m + (L - m_true.rest_length_m) * (1 + e)
            descs.append(f"length-sensor scale error {e * 100:+.1f}%")
            sizes.append(float(np.percentile(np.abs(F_clean - m_true.push(Pc, L_meas)), 99.5) / span))
            continue
        if kind == "time_skew":
            continue  # applied after noise on the force channel
        g, newF, desc, truth = apply_effect(sim, kind, form, size, rng, span)
        truths.append({"effect": kind, "form": form, **truth})
        if newF is not None:
            # a physical base change: the change of the base force is added to what is there
            dF = newF - Fbase
            Fbase = newF
        else:
            dF = scale_to(g, span, size)
        F = F + dF
        sizes.append(float(np.percentile(np.abs(dF), 99.5) / span))
        descs.append(desc)
    # measurement
    sigF = rng.uniform(0.002, 0.01) * span
    F_meas = F + rng.normal(0, sigF, n)
    q = rng.choice([0.0, 0.05, 0.1])
    if q:
        F_meas = np.round(F_meas / q) * q
    if any(e[0] == "time_skew" for e in spec["effects"]):
        sk = rng.uniform(0.008, 0.014)
        F_meas = np.interp(t - sk, t, F_meas)
        descs.append(f"force channel lags L,P by {sk * 1e3:.0f} ms (acquisition skew)")
        sizes.append(float(np.percentile(np.abs(np.interp(t - sk, t, F_clean) - F_clean), 99.5) / span))
    sigP = rng.uniform(300, 1500)
    P_meas = np.round((Pc + rng.normal(0, sigP, n)) / 100) * 100
    L_meas = L_meas + rng.normal(0, rng.uniform(5e-6, 3e-5), n)
    # the reviewer's CSV rounding, and read back as read_csv does (kPa x 1000.0)
    columns = [quantised(t, 4), quantised(L_meas, 6), quantised(P_meas / 1e3, 1), quantised(F_meas, 3)]
    lines = [",".join(row) for row in zip(*(text for text, _ in columns))]
    (ts, Ls, Pk, Fs) = (values for _, values in columns)
    meta = {"source": f"diagnose_forms {spec['id']} (seed {seed})", "columns": HEADER.split(","),
            "rest_length_m": m_nom.rest_length_m}  # fmt: skip
    recording = Recording(ts, Ls, Pk * 1000.0, Fs, meta)
    entry = dict(spec, seed=seed, protocol_desc=pdesc, forms=descs, truth_params=truths,
                 effect_peak_over_span=[round(s, 4) for s in sizes], span_N=round(span, 1),
                 noise_true_N=round(sigF, 3), quant_N=float(q), n=int(n), duration_s=round(float(t[-1]), 1),
                 pmax_kPa=round(pmax / 1e3, 1))  # fmt: skip
    return entry, recording, lines


def group_of(truth):
    """The scoring group of a truth label: clean, outside, two or single."""
    if truth == "none":
        return "clean"
    if truth == "outside_library":
        return "outside"
    return "two" if "+" in truth else "single"


def form_key(effects):
    """The truth form(s) of a file: ``friction/stribeck``, ``outside/inertia``, ``clean``."""
    if not effects:
        return "clean"
    return "+".join(f"{kind}/{form}" if form != "-" else f"outside/{kind}" for kind, form, _ in effects)


def judge(entry, r):
    """Outcome category for one file (the reviewer's rules)."""
    truth = entry["truth"]
    if r.get("answer") is None:
        return "CRASH"
    ans, conf, amb, tent = r["answer"], r["confident"], r["ambiguous"], r["tentative"]
    cont = r.get("contenders") or [ans]
    if truth == "none":
        if ans == "none":
            return "ok" if (conf or tent) else ("ok-amb" if amb and "none" in cont else "ok-weak")
        if ans in LIB and (conf or tent):
            return "FALSE-ALARM-conf" if conf else "FALSE-ALARM-tent"
        if amb:
            return "amb-" + ("with-none" if "none" in cont else "no-none")
        return f"weak-{ans}"
    if truth == "outside_library":
        if ans in LIB and conf:
            return "FAIL-named-conf"
        if ans == "outside_library":
            return "ok" if conf else "ok-weak"
        if ans == "none":
            return "missed(none)"
        if amb:
            return "amb"
        return "tent-named" if tent else "weak-named"
    truths = set(truth.split("+"))
    if amb:
        return "amb-contains" if truths & set(cont) else "amb-wrong"
    if ans in truths:
        if r.get("both") and set(cont) <= truths and len(truths) > 1:
            return "right-both" if conf else "right-both-weak"
        return "right-conf" if conf else ("right-tent" if tent else "right-weak")
    if conf:
        return "WRONG-conf"
    return "wrong-tent" if tent else "wrong-weak"


def run_case(job):
    """Generate file ``job = (spec, seed, csv_dir)``, diagnose it in process, score the row."""
    spec, seed, csv_dir = job
    start = time.perf_counter()
    entry, recording, lines = generate_one(spec, seed)
    generated = time.perf_counter() - start
    if csv_dir:
        text = f"# diagnose_forms file {spec['id']} (truth withheld from the file)\n{HEADER}\n"
        (Path(csv_dir) / f"{spec['id']}.csv").write_text(text + "\n".join(lines) + "\n")
    row = {**entry, "group": group_of(entry["truth"]), "form_key": form_key(entry["effects"]),
           "generate_seconds": generated}  # fmt: skip
    start = time.perf_counter()
    try:
        d = diagnose([recording], load_muscle(spec["muscle"]), next_experiment=False)
    except Exception:
        row.update(answer=None, error=traceback.format_exc()[-3000:], seconds=time.perf_counter() - start)
    else:
        v = d.verdict
        top = sorted(v.probabilities.items(), key=lambda kv: -kv[1])[:4]
        row.update(
            answer=v.answer, probability=v.probability, confident=v.confident, ambiguous=v.ambiguous,
            tentative=v.tentative, both=v.both, contenders=v.contenders, effects_kept=d.names, top=top,
            **d.rms_summary(), structure=d.structure, samples=d.n_samples, seconds=time.perf_counter() - start,
        )  # fmt: skip
    row["outcome"] = judge(entry, row)
    return row


def flag(r):
    """C confident, A ambiguous, T tentative, - neither."""
    return "C" if r.get("confident") else "A" if r.get("ambiguous") else "T" if r.get("tentative") else "-"


def summarise(rows):
    """Outcome counts per group and per truth form, and the headline figures."""
    groups = {g: {} for g in GROUPS}
    forms: dict[str, dict] = {}
    for r in rows:
        c = r["outcome"]
        groups[r["group"]][c] = groups[r["group"]].get(c, 0) + 1
        forms.setdefault(r["form_key"], {})
        forms[r["form_key"]][c] = forms[r["form_key"]].get(c, 0) + 1
    single = [r for r in rows if r["group"] == "single"]
    sure = [r for r in single if r.get("confident")]
    headline = {
        "files": len(rows),
        "crashes": sum(r["outcome"] == "CRASH" for r in rows),
        "clean": sum(groups["clean"].values()),
        "clean_false_alarms": sum(v for k, v in groups["clean"].items() if k.startswith("FALSE-ALARM")),
        "clean_false_alarms_confident": groups["clean"].get("FALSE-ALARM-conf", 0),
        "single": len(single),
        "single_confident": len(sure),
        "single_right_confident": groups["single"].get("right-conf", 0),
        "single_wrong_confident": groups["single"].get("WRONG-conf", 0),
        "two_answer_a_truth": sum(r["outcome"].startswith("right") for r in rows if r["group"] == "two"),
        "outside": sum(groups["outside"].values()),
        "outside_named_confident": groups["outside"].get("FAIL-named-conf", 0),
        "outside_answered_outside_confident": groups["outside"].get("ok", 0),
    }
    return {"headline": headline, "groups": {g: d for g, d in groups.items() if d}, "forms": forms}


def print_rows(rows):
    """The per-file table: truth, protocol, answer, p, flag, contenders, held-out RMS, outcome."""
    for r in rows:
        ho = ""
        if r.get("heldout_rms_before_N") is not None:
            ho = f"{r['heldout_rms_before_N']:.2f}->{r['heldout_rms_after_N']:.2f} ({r['noise_N']:.2f})"
        p = "" if r.get("probability") is None else f"{r['probability']:.2f}"
        print(f"{r['id']} {r['form_key']:<44s} {r['protocol']:<16s} -> {str(r.get('answer')):<16s} "
              f"p={p:<4s} {flag(r)} {'/'.join(r.get('contenders') or []):<30s} {ho:<22s} {r['outcome']}")  # fmt: skip


def print_summary(summary):
    """Counts per group, per truth form, and the headline."""
    print("\nper group:")
    for g, d in summary["groups"].items():
        print(f"  {g:8s} " + ", ".join(f"{k} {v}" for k, v in sorted(d.items())))
    print("per truth form:")
    for f, d in sorted(summary["forms"].items()):
        print(f"  {f:44s} " + ", ".join(f"{k} {v}" for k, v in sorted(d.items())))
    h = summary["headline"]
    print(
        f"\nclean: {h['clean_false_alarms']} false alarms of {h['clean']} ({h['clean_false_alarms_confident']} confident); "
        f"single: right {h['single_right_confident']} / wrong {h['single_wrong_confident']} of "
        f"{h['single_confident']} confident ({h['single']} files); two: a truth answered {h['two_answer_a_truth']}; "
        f"outside: named at p>=0.8 {h['outside_named_confident']}, outside_library confident "
        f"{h['outside_answered_outside_confident']} of {h['outside']}; crashes {h['crashes']}"
    )


def main(argv=None) -> int:
    """Generate, diagnose and score the set (or the ``--only`` subset); write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--variant", type=int, default=0, help="0: the main seeds; N: the replica with other seeds"
    )
    ap.add_argument("--only", nargs="+", metavar="ID", help="file ids to run (c00 f04 x00 ...)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (each pinned to one core)")
    ap.add_argument("--out", help="results JSON (default bench/results/diagnose_forms[_vN].json)")
    ap.add_argument("--write-csv", metavar="DIR", help="also write each recording as the reviewer's CSV")
    args = ap.parse_args(argv)
    everything = plan()
    known = {s["id"] for s in everything}
    unknown = sorted(set(args.only or ()) - known)
    if unknown:
        ap.error(f"unknown ids {unknown} (known: {sorted(known)})")
    if args.write_csv:
        Path(args.write_csv).mkdir(parents=True, exist_ok=True)
    jobs = [
        (spec, seed_of(k, args.variant), args.write_csv)
        for k, spec in enumerate(everything)
        if not args.only or spec["id"] in args.only
    ]
    out_path = args.out or str(
        RESULTS if not args.variant else RESULTS.with_name(f"diagnose_forms_v{args.variant}.json")
    )
    start = time.perf_counter()
    rows: list[dict] = []

    def keep(row: dict) -> None:
        """Store a finished row and print its line."""
        rows.append(row)
        p = "" if row.get("probability") is None else f"{row['probability']:.2f}"
        print(f"[{len(rows):2d}/{len(jobs)}] {row['id']} {row['form_key']:<44s} -> {str(row.get('answer')):<16s} "
              f"p={p:<4s} {flag(row)} {row['outcome']:<16s} {row['seconds']:.1f} s", flush=True)  # fmt: skip

    if args.jobs > 1 and len(jobs) > 1:
        from multiprocessing import Pool

        with Pool(args.jobs, initializer=pin_one_core) as pool:
            for row in progress(pool.imap_unordered(run_case, jobs), "diagnose", len(jobs)):
                keep(row)
    else:
        pin_one_core()
        for job in progress(jobs, "diagnose", len(jobs)):
            keep(run_case(job))
    order = {s["id"]: k for k, s in enumerate(everything)}
    rows.sort(key=lambda r: order[r["id"]])
    print()
    print_rows(rows)
    summary = summarise(rows)
    print_summary(summary)
    out = {
        "summary": summary,
        "settings": {
            "variant": args.variant,
            "only": args.only,
            "jobs": args.jobs,
            "seeds": f"{SEED0} + k * {SEED_STEP} + variant * {SEED_VARIANT}",
        },  # fmt: skip
        "protocols": {name: f.__doc__ for name, f in PROTOCOLS.items()},
        "wall_s": time.perf_counter() - start,
        "cases": rows,
    }
    print(f"\nwrote {write_json_atomic(out_path, out)} ({out['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
