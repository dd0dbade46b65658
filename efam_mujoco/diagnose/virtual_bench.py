"""A virtual test bench for blind tests of ``diagnose``: any protocol, truth physics in many forms.

This module plays an experimenter and a rig; it imports nothing from the candidate library
(``diagnose.effects``) and writes every truth effect in its own functional form (it shares the
truth muscle's Eq. 2 helpers with ``synth``, which is written the same way).

**Protocol families** (``FAMILIES``), each randomised:

* ``isobaric``: strokes out and back at 2-5 pressures in SHUFFLED order (a repeat of one of them
  at the end half the time), 1-3 cycles per pressure at slow and fast speeds (2-8 mm/s, x2-4),
  stroke 30-98 % of the rest length from the rest length or a pre-strain, holds at both ends;
* ``isometric``: 1-4 held lengths in one file (the length changed at zero pressure between
  them); at each, pressure ramps up and down (linear, 8-40 s) or staircases of 5-12 steps with
  holds, 1-2 sweeps, top pressure 250-600 kPa;
* ``sinusoidal``: at 1-3 pressures (shuffled), sinusoidal strokes about any mean strain with any
  amplitude (never returning to the rest length unless drawn so), random strokes (three
  sinusoids of random phase), or a chirp (0.03 -> 0.4 Hz);
* ``mixed``: pressure ramped up at a length, strokes at that pressure, vented, again at another
  pressure and length: one file with both kinds of test.

**Rig**: the regulator is second order (0.5-3 Hz, damping 0.5-0.95) with a ripple (0.2-1.5 kPa
at 3-40 Hz) and a dip while the muscle draws gas; sampling 25 Hz to 1 kHz (log-uniform, fewer
samples for long tests: at most ``MAX_SAMPLES`` per file), each recorded sample the mean of the
truth samples it spans; load-cell noise 0.3-0.8 N (at most the effect's RMS / 1.2, so that a
concealed effect stands out of the noise), pressure noise 0.7 kPa, length noise 0.01 mm. Each
recording is written to CSV with randomly chosen units (time s or ms; length m, mm, in or a
displacement in mm; pressure Pa, kPa, MPa, bar or psi; force N, kN or lbf, or a tension) and read
back with ``recordings.read_csv``.

**Truth effects** (``FORMS``: effect -> forms; library name in the keys only for scoring):

=================  =======================================================================
friction           ``dahl`` (Dahl with exponent), ``lugre`` (LuGre bristles with a Stribeck
                   curve), ``iwan`` (Iwan: 24 Jenkins elements with spread slip limits); slip
                   driven by the strain and the pressure, normal force ~ P R_o^2
viscoelasticity    ``maxwell2`` (two Maxwell branches in the bladder stresses), ``zener`` (a
                   standard linear solid on the bladder force as a whole), ``qlv`` (Fung's
                   quasi-linear viscoelasticity: a continuous spectrum over two decades)
pressure_lag       ``orifice`` (laminar-turbulent flow into a polytropic gas volume), ``delay``
                   (transport delay 20-150 ms then a first-order fill)
drift              ``thermal`` (bladder modulus falling as (t / T)^gamma, T the duration of the
                   case's first test: ``Case.rig``), ``creep`` (logarithmic
                   creep of the bladder's rest length under its pressure history)
end_effects        ``tapered`` (tapered ends with pinned threads, force from -P dV/dL)
braid_compliance   ``power`` (thread strain ~ (P R_o)^m, self-consistent), ``bilinear`` (crimp
                   then a stiffer thread)
softening          ``ogden_roxburgh`` (erf damage on a pressure-dependent strain energy)
force_offset       ``constant`` (a load-cell zero, per file)
=================  =======================================================================

**Outside the library** (``OUTSIDE``: no library name is right): ``strain_bump`` (a local
buckling of the bladder: a pressure-scaled bump of force at one strain), ``sensor_nonlinearity``
(the pressure transducer's calibration error, a full period of a sine over the pressure range),
``gas_heating`` (compression heats the gas: the muscle's pressure overshoots the supply's while
it is pressurised, then cools back over 2-10 s) and, in the sinusoidal family only, ``inertia``
(a 5-25 kg carriage on a compliant load cell: mass times acceleration with a lightly damped ring).
"""

from __future__ import annotations

import csv
import math
import os
import tempfile
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import lfilter

from ..recordings import Recording, read_csv
from . import synth as S

FAMILIES = ("isobaric", "isometric", "sinusoidal", "mixed")
FORMS = {
    "friction": ("dahl", "lugre", "iwan"),
    "viscoelasticity": ("maxwell2", "zener", "qlv"),
    "pressure_lag": ("orifice", "delay"),
    "drift": ("thermal", "creep"),
    "end_effects": ("tapered",),
    "braid_compliance": ("power", "bilinear"),
    "softening": ("ogden_roxburgh",),
    "force_offset": ("constant",),
}
OUTSIDE = ("strain_bump", "sensor_nonlinearity", "inertia", "gas_heating")
MAX_SAMPLES = 30000
P_ATM = 101325.0


@dataclass
class Plan:
    """A test as set points on a fine time grid: length (m) and pressure set point (Pa)."""

    t: np.ndarray
    L: np.ndarray
    P_set: np.ndarray
    sample_hz: float
    family: str = ""
    words: str = ""


@dataclass
class Case:
    """What is concealed in one benchmark case (kept from the diagnosis until it is scored)."""

    seed: int
    family: str
    effects: list[tuple[str, str]]  # (effect, form); an OUTSIDE effect has form ""
    base_name: str = ""
    muscle: object = None
    params: dict = field(default_factory=dict)
    noise_N: float = 0.0
    effect_rms_N: float = 0.0
    protocol: str = ""
    sample_hz: float = 0.0
    units: list[str] = field(default_factory=list)
    #: the rig's own scales, set by the case's first test and kept for any later test of it (a
    #: next experiment): its top pressure (the transducer's range, the thread's and the
    #: contact's load scale), its duration (the thermal drift's time scale) and the buckling
    #: bump's strain. A later test with another top pressure, length or strain range is the
    #: same muscle on the same rig: its physics must not move with the test
    rig: dict = field(default_factory=dict)
    true_force_N: np.ndarray | None = field(default=None, repr=False)
    #: the length and the transducer's pressure as recorded, without the sensors' noise (scoring only)
    true_length_m: np.ndarray | None = field(default=None, repr=False)
    true_pressure_Pa: np.ndarray | None = field(default=None, repr=False)

    @property
    def names(self) -> list[str]:
        """Names of the concealed truth effects."""
        return [e for e, _ in self.effects]

    @property
    def kind(self) -> str:
        """The case's kind: clean, single, pair or outside the library."""
        if not self.effects:
            return "clean"
        if any(e in OUTSIDE for e in self.names):
            return "outside"
        return "two" if len(self.effects) > 1 else "single"


# ----------------------------------------------------------------------------- protocols
def _fine_grid(duration: float, rng, max_samples: int = MAX_SAMPLES) -> tuple[np.ndarray, float, int]:
    hi = min(1000.0, max_samples / max(duration, 1.0))
    lo = min(25.0, hi)
    fs = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    per = max(1, int(round(200.0 / fs)))
    dt = 1.0 / (fs * per)
    return np.arange(0.0, duration, dt), fs, per


class _Program:
    """Breakpoints (t, L, P) of a piecewise-linear program (steps are 1 ms ramps)."""

    def __init__(self, L0):
        self.t, self.L, self.P = [0.0], [L0], [0.0]

    def go(self, duration, L=None, P=None):
        self.t.append(self.t[-1] + max(duration, 1e-3))
        self.L.append(self.L[-1] if L is None else L)
        self.P.append(self.P[-1] if P is None else P)

    def arrays(self):
        return np.array(self.t), np.array(self.L), np.array(self.P)


def _stroke_range(m, rng):
    rest = m.rest_length_m
    top = min(rest * 1.98, 0.95 * m.max_length_m)
    return rest, top


def plan_isobaric(rng, m) -> Plan:
    """An isobaric MTS-style plan: strokes at 2-5 pressure levels in shuffled order."""
    rest, top = _stroke_range(m, rng)
    levels = list(rng.choice([103.4, 172.4, 206.8, 275.8, 310.3, 379.2, 413.7, 482.6, 517.1],
                             size=int(rng.integers(2, 6)), replace=False))  # fmt: skip
    rng.shuffle(levels)
    if rng.random() < 0.5:
        levels.append(levels[int(rng.integers(len(levels)))])
    start = rest + (top - rest) * (rng.uniform(0.0, 0.3) if rng.random() < 0.4 else 0.0)
    end = start + (top - start) * rng.uniform(0.3, 1.0)
    slow = rng.uniform(2e-3, 8e-3)
    fast = slow * rng.uniform(2.0, 4.0)
    prog = _Program(rest)
    prog.go(rng.uniform(3, 10))
    prog.go(abs(start - rest) / slow + 0.001, L=start)
    for p in levels:
        prog.go(0.001, P=p * 1e3)
        prog.go(rng.uniform(3, 7))
        for _ in range(int(rng.integers(1, 4))):
            v = slow if rng.random() < 0.6 else fast
            prog.go((end - start) / v, L=end)
            prog.go(rng.uniform(1, 6))
            prog.go((end - start) / v, L=start)
            prog.go(rng.uniform(1, 6))
    prog.go(0.001, P=0.0)
    prog.go(rng.uniform(3, 8))
    words = f"isobaric strokes {start / rest - 1:.2f}-{end / rest - 1:.2f} strain at " + ", ".join(
        f"{p:.0f}" for p in levels
    )
    return _finish(prog, rng, "isobaric", words + " kPa")


def plan_isometric(rng, m) -> Plan:
    """An isometric plan: pressure ramps and steps at 1-4 fixed lengths."""
    rest, top = _stroke_range(m, rng)
    n_len = int(rng.integers(1, 5))
    lengths = rest + (top - rest) * np.sort(rng.uniform(0.0, 0.6, n_len))
    rng.shuffle(lengths)
    p_top = rng.uniform(250e3, 600e3)
    staircase = rng.random() < 0.5
    prog = _Program(rest)
    prog.go(rng.uniform(3, 8))
    for L in lengths:
        prog.go(abs(L - prog.L[-1]) / 5e-3 + 0.001, L=L)
        prog.go(rng.uniform(2, 5))
        for _ in range(int(rng.integers(1, 3))):
            if staircase:
                steps = int(rng.integers(5, 13))
                hold = rng.uniform(1.0, 3.0)
                for k in list(range(1, steps + 1)) + list(range(steps - 1, -1, -1)):
                    prog.go(0.001, P=p_top * k / steps)
                    prog.go(hold)
            else:
                ramp = rng.uniform(8, 40)
                prog.go(ramp, P=p_top)
                prog.go(rng.uniform(0.5, 4))
                prog.go(ramp, P=0.0)
            prog.go(rng.uniform(2, 5))
    kind = "staircases" if staircase else "ramps"
    words = f"isometric pressure {kind} to {p_top / 1e3:.0f} kPa at {n_len} length(s)"
    return _finish(prog, rng, "isometric", words)


def plan_sinusoidal(rng, m) -> Plan:
    """A sinusoidal plan: strokes of random mean, amplitude and frequency (chirps included) at several pressures."""
    rest, top = _stroke_range(m, rng)
    span = (top - rest) / rest
    levels = list(
        rng.choice([103.4, 206.8, 310.3, 413.7, 517.1], size=int(rng.integers(1, 4)), replace=False)
    )
    kind = str(rng.choice(["sine", "random", "chirp"]))
    pieces_t, pieces_x, pieces_p = [0.0], [0.0], [0.0]
    t_now = rng.uniform(3, 6)
    pieces_t.append(t_now)
    pieces_x.append(0.0)
    pieces_p.append(0.0)
    chunks = []
    for p in levels:
        amp = span * rng.uniform(0.08, 0.4)
        mean = rng.uniform(amp, span - amp)
        dur = rng.uniform(25, 60)
        chunks.append((p * 1e3, mean, amp, dur))
    duration = t_now + sum(4 + 2 * (mn / 0.01) * 0 + d + 4 for _, mn, _, d in chunks) + 5
    t, fs, per = _fine_grid(duration + 30, rng)
    x = np.zeros_like(t)
    P = np.zeros_like(t)
    c = t_now
    for p, mean, amp, dur in chunks:
        # move to the mean at the pressure, then the oscillation, then back and vent
        ramp_in = np.clip((t - c) / 4.0, 0, 1)
        P[t >= c] = p
        x = np.where((t >= c) & (t < c + 4), mean * ramp_in, x)
        s = t - (c + 4)
        on = (s >= 0) & (s < dur)
        if kind == "sine":
            period = rng.uniform(3, 20)
            wave = np.sin(2 * np.pi * s / period)
        elif kind == "random":
            periods = rng.uniform(2, 25, 3)
            phases = rng.uniform(0, 2 * np.pi, 3)
            wave = sum(np.sin(2 * np.pi * s / T + ph) for T, ph in zip(periods, phases)) / 2.2
        else:
            f0, f1 = 0.03, rng.uniform(0.2, 0.4)
            wave = np.sin(2 * np.pi * (f0 * s + (f1 - f0) * s * s / (2 * dur)))
        taper = np.clip(np.minimum(s, dur - s) / 2.0, 0, 1)
        x = np.where(on, mean + amp * np.clip(wave, -1, 1) * taper, x)
        back = (s >= dur) & (s < dur + 4)
        x = np.where(back, mean * (1 - (s - dur) / 4.0), x)
        c = c + 4 + dur + 4
        P[t >= c] = 0.0
        x[t >= c] = 0.0
    words = f"{kind} strokes at " + ", ".join(f"{p / 1e3:.0f}" for p, *_ in chunks) + " kPa"
    return Plan(t, rest * (1 + x), P, fs, "sinusoidal", words)


def plan_mixed(rng, m) -> Plan:
    """A mixed plan: strokes, holds and pressure ramps in one file."""
    rest, top = _stroke_range(m, rng)
    prog = _Program(rest)
    prog.go(rng.uniform(3, 8))
    for _ in range(int(rng.integers(2, 4))):
        L = rest + (top - rest) * rng.uniform(0.0, 0.4)
        p = rng.uniform(150e3, 550e3)
        prog.go(abs(L - prog.L[-1]) / 5e-3 + 0.001, L=L)
        prog.go(rng.uniform(8, 25), P=p)  # ramp up at a fixed length
        prog.go(rng.uniform(2, 4))
        end = L + (top - L) * rng.uniform(0.4, 1.0)
        v = rng.uniform(3e-3, 12e-3)
        for _ in range(int(rng.integers(1, 3))):
            prog.go((end - L) / v, L=end)
            prog.go(rng.uniform(1, 4))
            prog.go((end - L) / v, L=L)
            prog.go(rng.uniform(1, 4))
        prog.go(rng.uniform(8, 25), P=0.0)  # vented at the length
        prog.go(rng.uniform(2, 4))
    return _finish(prog, rng, "mixed", "pressure ramps at fixed lengths with strokes between")


def _finish(prog: _Program, rng, family, words) -> Plan:
    tb, Lb, Pb = prog.arrays()
    t, fs, _ = _fine_grid(tb[-1], rng)
    return Plan(t, np.interp(t, tb, Lb), np.interp(t, tb, Pb), fs, family, words)


PLANNERS = {"isobaric": plan_isobaric, "isometric": plan_isometric, "sinusoidal": plan_sinusoidal,
            "mixed": plan_mixed}  # fmt: skip


# ----------------------------------------------------------------------------------- rig
def _volume(m, L):
    gas = np.maximum((m.thread_length_m**2 - L * L) * L / (4 * math.pi * m.turns**2), 1e-7)
    return np.maximum(gas - m.bladder_volume_m3, 1e-7)


def regulator(t, setpoint, volume, rng, params) -> np.ndarray:
    """Transducer pressure: a second-order regulator, a ripple, a dip while gas is drawn."""
    dt = float(t[1] - t[0])
    wn = 2 * math.pi * rng.uniform(0.5, 3.0)
    zeta = rng.uniform(0.5, 0.95)
    gain = rng.uniform(0.03, 0.12)
    ripple, f_ripple = rng.uniform(200, 1500), rng.uniform(3, 40)
    params.update(regulator_hz=wn / 2 / math.pi, regulator_damping=zeta, ripple_Pa=ripple, ripple_hz=f_ripple)
    rate = np.gradient(volume, t) / volume
    # semi-implicit integration of p'' = wn^2 (s - p) - 2 zeta wn p' (stable at any dt used here)
    a = np.empty_like(t)
    p, v = float(setpoint[0]), 0.0
    sp = setpoint.tolist()
    for i in range(len(t)):
        v = (v + dt * wn * wn * (sp[i] - p)) / (1 + 2 * zeta * wn * dt + (wn * dt) ** 2)
        p += v * dt
        a[i] = p
    out = (
        a - gain * (setpoint + P_ATM) * rate + ripple * np.sin(2 * np.pi * f_ripple * t + rng.uniform(0, 6.3))
    )
    return np.maximum(out, 0.0)


# -------------------------------------------------------------------------- truth effects
def _lag1(t, u, tau):
    a = math.exp(-(t[1] - t[0]) / tau)
    return lfilter([1 - a], [1, -a], u, zi=[a * u[0]])[0]


def _slip(m, L, P, p_top, rng, params):
    share = rng.uniform(0.02, 0.08)
    sign = -np.sign(np.mean(3 * L * L - m.thread_length_m**2))
    params["slip_share_p"] = share
    return (L / m.rest_length_m - 1.0) + sign * share * P / p_top


def _normal(m, P, L, p_top):
    _, _, _, _, _, Ro = S._eq2_parts(m, P, L)
    return 0.2 + 0.8 * (P / p_top) * (Ro / m.rest_outer_radius_m) ** 2


def _lugre(t, s, delta, stick, vs):
    """LuGre bristle deflection (normalised to [-~1, 1]) with a Stribeck curve, sub-stepped."""
    dt = float(t[1] - t[0])
    v = np.gradient(s, t)
    z = 0.0
    out = np.empty_like(s)
    for i, vi in enumerate(v.tolist()):
        g = 1.0 + (stick - 1.0) * math.exp(-((vi / vs) ** 2))
        n = int(abs(vi) * dt / (0.05 * delta)) + 1
        h = dt / n
        for _ in range(n):
            z += h * (vi - abs(vi) * z / (delta * g) * 1.0)
        out[i] = z / delta
    return out


def _iwan(s, delta_mean, spread, n=24, rng=None):
    """Iwan model: the mean state of n Jenkins elements (play operators) with slip limits spread
    log-normally about ``delta_mean``."""
    widths = delta_mean * np.exp(spread * np.linspace(-1.5, 1.5, n))
    z = np.zeros(n)
    out = np.empty_like(s)
    prev = s[0]
    for i, si in enumerate(s.tolist()):
        z = np.clip(z + (si - prev) / widths, -1.0, 1.0)
        prev = si
        out[i] = z.mean()
    return out


def truth_tension(
    effect, form, rng, m, t, L, P, p_top, params, rig: dict | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(extra tension, paper sign, this effect adds; the pressure the muscle sees)."""
    base = S._tension(m, P, L)
    if effect == "friction":
        F = rng.uniform(3.0, 12.0)
        s = _slip(m, L, P, p_top, rng, params)
        normal = _normal(m, P, L, p_top)
        if form == "dahl":
            delta, expo = rng.uniform(0.004, 0.02), rng.uniform(0.6, 1.5)
            z = S._dahl(s, delta, expo)
            params.update(F_ref_N=F, delta=delta, exponent=expo)
        elif form == "lugre":
            delta, stick, vs = rng.uniform(0.003, 0.015), rng.uniform(1.1, 1.6), rng.uniform(2e-3, 2e-2)
            z = _lugre(t, s, delta, stick, vs)
            params.update(F_ref_N=F, bristle=delta, stick_ratio=stick, stribeck_per_s=vs)
        else:
            delta, spread = rng.uniform(0.003, 0.015), rng.uniform(0.5, 1.2)
            z = _iwan(s, delta, spread)
            params.update(F_ref_N=F, slip_mean=delta, slip_spread=spread)
        return F * normal * z, P
    if effect == "viscoelasticity":
        E = m.stress.coefficients[0]
        pres, fz, fc, ez, ec, _ = S._eq2_parts(m, P, L)
        if form == "maxwell2":
            g = (rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.2))
            taus = (rng.uniform(0.8, 4.0), rng.uniform(10.0, 60.0))
        elif form == "qlv":
            total = rng.uniform(0.15, 0.4)
            t1, t2 = rng.uniform(0.3, 1.5), rng.uniform(40, 200)
            taus = tuple(np.geomspace(t1, t2, 6))
            g = tuple([total / 6] * 6)
            params.update(spectrum_s=(t1, t2), total=total)
        else:  # zener on the whole bladder force
            g1, tau = rng.uniform(0.1, 0.35), rng.uniform(1.0, 20.0)
            bl = base - pres
            params.update(g=g1, tau_s=tau)
            return g1 * (bl - _lag1(t, bl, tau)), P
        vz = sum(gi * E * (ez - _lag1(t, ez, ti)) for gi, ti in zip(g, taus))
        vc = sum(gi * E * (ec - _lag1(t, ec, ti)) for gi, ti in zip(g, taus))
        params.setdefault("g", list(g))
        params.setdefault("tau_s", list(taus))
        return vz * fz - vc * fc, P
    if effect == "pressure_lag":
        if form == "orifice":
            P_int = S._orifice_fill(rng, t, P, _volume(m, L), params)
        else:
            delay, tau = rng.uniform(0.02, 0.15), rng.uniform(0.02, 0.15)
            shifted = np.interp(t - delay, t, P, left=P[0])
            P_int = _lag1(t, shifted, tau)
            params.update(delay_s=delay, tau_s=tau)
        return S._tension(m, P_int, L) - base, P_int
    if effect == "drift":
        if form == "thermal":
            loss, gamma = rng.uniform(0.04, 0.15), rng.uniform(0.6, 1.6)
            scale = 1.0 - loss * (t / (rig or {}).get("duration_s", t[-1])) ** gamma
            params.update(modulus_loss=loss, gamma=gamma)
            return S._tension(m, P, L, scale_z=scale, scale_c=scale) - base, P
        c, t0 = rng.uniform(0.01, 0.04), rng.uniform(5.0, 60.0)
        load = np.cumsum(P / p_top) * float(t[1] - t[0])
        shift = c * np.log1p(load / t0)  # the bladder's rest length creeps under pressure
        pres, fz, fc, ez, ec, _ = S._eq2_parts(m, P, L)
        params.update(creep=c, creep_time_s=t0)
        return (m.stress(ez - shift, P) - m.stress(ez, P)) * fz, P
    if effect == "end_effects":
        end = rng.uniform(0.6, 1.5) * m.rest_outer_radius_m
        half, shrink = rng.uniform(30e3, 100e3), rng.uniform(0.5, 0.9)
        params.update(end_length_m=end, shrink=shrink, half_kPa=half / 1e3)
        return S._tapered_ends(m, P, L, end * (1.0 - shrink * P / (P + half))) - base, P
    if effect == "braid_compliance":
        strain_top = rng.uniform(0.008, 0.025)
        expo = rng.uniform(0.5, 0.9)
        knee = rng.uniform(0.2, 0.5)
        B = np.full_like(L, m.thread_length_m)
        for _ in range(6):
            _, _, _, _, _, Ro = S._eq2_parts(m, P, L, thread=B)
            load = np.maximum(P / p_top * Ro / m.rest_outer_radius_m, 0.0)
            if form == "power":
                stretch = strain_top * load**expo
            else:  # crimp straightens (soft), then the thread itself (stiff)
                stretch = strain_top * np.where(
                    load < knee, load / knee * 0.7, 0.7 + 0.3 * (load - knee) / (1 - knee)
                )
            B = m.thread_length_m * (1.0 + stretch)
        params.update(thread_strain_at_top=strain_top, exponent=expo, knee=knee)
        return S._tension(m, P, L, thread=B) - base, P
    if effect == "softening":
        r = rng.uniform(3.0, 8.0)
        c = m.stress.coefficients
        _, _, _, ez, ec, _ = S._eq2_parts(m, P, L)
        energy = 0.5 * (c[0] + c[1] * P) * (ez * ez + ec * ec)
        peak = np.maximum.accumulate(energy)
        width = rng.uniform(0.05, 0.3) * energy.max()
        from scipy.special import erf

        eta = 1.0 - erf((peak - energy) / (width + 0.1 * peak)) / r
        params.update(r=r, width_frac=width / max(energy.max(), 1e-30))
        return S._tension(m, P, L, scale_z=eta, scale_c=eta) - base, P
    if effect == "force_offset":
        offset = rng.choice([-1, 1]) * rng.uniform(1.5, 8.0)
        params.update(offset_N=offset)
        return np.full_like(t, -offset), P
    if effect == "strain_bump":
        x = L / m.rest_length_m - 1
        here = float(np.percentile(x, rng.uniform(30, 70)))  # drawn every time: the stream replays
        x0 = here if rig is None else rig.setdefault("bump_strain", here)
        w = rng.uniform(0.03, 0.1)
        A = rng.uniform(3.0, 10.0)
        params.update(bump_N=A, bump_strain=x0, bump_width=w)
        return -A * (0.3 + P / p_top) * np.exp(-(((x - x0) / w) ** 2)), P
    if effect == "sensor_nonlinearity":
        a = rng.uniform(0.015, 0.04) * p_top
        params.update(transducer_error_Pa=a)
        # the muscle sees P_true; the transducer reads P_true + a sin(pi P / p_top): so the
        # muscle's pressure is the reading less that error (applied by the caller to the reading)
        return np.zeros_like(t), -a * np.sin(2 * np.pi * np.clip(P / p_top, 0, 1.2))
    if effect == "gas_heating":
        k, tau = rng.uniform(0.08, 0.25), rng.uniform(2.0, 10.0)
        params.update(heating=k, cooling_s=tau)
        # compression heats the gas: the muscle's pressure overshoots the supply, then cools back
        return np.zeros_like(t), k * (P - _lag1(t, P, tau))
    if effect == "inertia":
        mass, fn, zeta = rng.uniform(5, 25), rng.uniform(3, 12), rng.uniform(0.05, 0.2)
        acc = np.gradient(np.gradient(L, t), t)
        wn = 2 * math.pi * fn
        dt = float(t[1] - t[0])
        # the load cell rings: a second-order response to m * a (semi-implicit)
        y, v = 0.0, 0.0
        out = np.empty_like(t)
        for i, f in enumerate((mass * acc).tolist()):
            v = (v + dt * wn * wn * (f - y)) / (1 + 2 * zeta * wn * dt + (wn * dt) ** 2)
            y += v * dt
            out[i] = y
        params.update(mass_kg=mass, ring_hz=fn, ring_damping=zeta)
        return -out, P
    raise ValueError(f"unknown truth effect '{effect}'")


# ------------------------------------------------------------------------------ a case
UNIT_CHOICES = {
    "time": (("time_s", 1.0), ("time_ms", 1e-3)),
    "length": (("length_m", 1.0), ("length_mm", 1e-3), ("length_in", 0.0254), ("displacement_mm", 1e-3)),
    "pressure": (("pressure_Pa", 1.0), ("pressure_kPa", 1e3), ("pressure_MPa", 1e6), ("pressure_bar", 1e5),
                 ("pressure_psi", 6894.757293168361)),
    "force": (("force_N", 1.0), ("force_kN", 1e3), ("force_lbf", 4.4482216152605), ("tension_N", -1.0)),
}  # fmt: skip


def _write_and_read(recording: Recording, rest: float, rng, path: str) -> tuple[Recording, list[str]]:
    """Write with random units, read back with the package's reader (as a user's file is)."""
    cols = {k: v[int(rng.integers(len(v)))] for k, v in UNIT_CHOICES.items()}
    length = recording.length_m - (rest if cols["length"][0].startswith("displacement") else 0.0)
    data = np.column_stack([recording.time_s / cols["time"][1], length / cols["length"][1],
                            recording.pressure_Pa / cols["pressure"][1], recording.force_N / cols["force"][1]])  # fmt: skip
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([c[0] for c in cols.values()])
        for row in data:
            w.writerow([f"{v:.9g}" for v in row])
    return read_csv(path, rest_length_m=rest), [c[0] for c in cols.values()]


def simulate(case: Case, plan: Plan, rng, force_noise_N: float | None = None) -> Recording:
    """The recording the rig makes of ``plan`` with the case's truth (muscle and effects). The
    effects' random parameters come from ``rng`` (the same seed gives the same truth)."""
    m = case.muscle
    t, L = plan.t, plan.L
    params: dict = {}
    P_tr = regulator(t, plan.P_set, _volume(m, L), rng, params)
    # the first test of the case sets the rig's scales (``Case.rig``)
    p_top = case.rig.setdefault("p_top_Pa", max(float(np.max(plan.P_set)), 100e3))
    case.rig.setdefault("duration_s", float(t[-1]))
    P_muscle = P_tr.copy()
    extra = np.zeros_like(t)
    # effects that change the pressure the muscle sees act first, then the rest add tension
    for effect, form in case.effects:
        sub: dict = {}
        if effect in ("sensor_nonlinearity", "gas_heating"):
            _, error = truth_tension(effect, form, rng, m, t, L, P_tr, p_top, sub, case.rig)
            P_muscle = np.maximum(P_muscle + error, 0.0)
        elif effect == "pressure_lag":
            _, P_muscle = truth_tension(effect, form, rng, m, t, L, P_muscle, p_top, sub, case.rig)
        params[effect] = sub
    for effect, form in case.effects:
        if effect in ("sensor_nonlinearity", "gas_heating", "pressure_lag"):
            continue
        sub = {}
        dT, _ = truth_tension(effect, form, rng, m, t, L, P_muscle, p_top, sub, case.rig)
        extra += dT
        params[effect] = sub
    clean = S._tension(m, P_tr, L)
    tension = S._tension(m, P_muscle, L) + extra
    per = max(1, int(round(1.0 / (plan.sample_hz * (t[1] - t[0])))))
    n = len(t) // per

    def record(u):
        return u[: n * per].reshape(n, per).mean(axis=1)

    t_rec = t[: n * per].reshape(n, per)[:, 0]
    effect_part = -(record(tension) - record(clean))
    effect_rms = float(np.sqrt(np.mean((effect_part - (effect_part.mean() if False else 0.0)) ** 2)))
    noise = force_noise_N if force_noise_N is not None else rng.uniform(0.3, 0.8)
    if case.effects and force_noise_N is None:
        noise = min(noise, max(effect_rms / 1.2, 0.1))
    case.true_force_N = -record(tension)  # noise-free, for scoring only
    case.true_length_m, case.true_pressure_Pa = record(L), record(P_tr)
    force = -record(tension) + rng.normal(0.0, noise, n)
    force = np.round(force / 0.02) * 0.02
    pressure = record(P_tr) + rng.normal(0.0, 700.0, n)
    length = record(L) + rng.normal(0.0, 1e-5, n)
    case.params.update(params)
    case.noise_N = noise
    case.effect_rms_N = effect_rms
    return Recording(t_rec, length, pressure, force, meta={"source": f"virtual bench seed {case.seed}"})


def draw_case(seed: int, family: str | None = None, kind: str | None = None) -> Case:
    """The concealed truth of one case: the muscle, the family, the effects and their forms."""
    rng = np.random.default_rng([seed, 7])
    family = family or str(rng.choice(FAMILIES))
    kind = kind or str(rng.choice(["clean", "single", "single", "two", "outside"]))
    names = list(FORMS)
    if kind == "clean":
        effects = []
    elif kind == "single":
        e = names[int(rng.integers(len(names)))]
        effects = [(e, str(rng.choice(FORMS[e])))]
    elif kind == "two":
        a, b = rng.choice(names, size=2, replace=False)
        effects = [(str(a), str(rng.choice(FORMS[a]))), (str(b), str(rng.choice(FORMS[b])))]
    else:  # the carriage's inertia only shows where the length accelerates (oscillating strokes)
        options = OUTSIDE if family == "sinusoidal" else tuple(o for o in OUTSIDE if o != "inertia")
        effects = [(str(rng.choice(options)), "")]
    muscle, base = S.random_truth_muscle(rng)
    return Case(seed=seed, family=family, effects=effects, base_name=base, muscle=muscle)


def make(case: Case, workdir: str | None = None) -> Recording:
    """Draw the case's protocol, simulate it and pass the file through CSV with random units."""
    rng = np.random.default_rng([case.seed, 11])
    plan = PLANNERS[case.family](rng, case.muscle)
    recording = simulate(case, plan, rng)
    case.protocol, case.sample_hz = plan.words, plan.sample_hz
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        recording, case.units = _write_and_read(recording, case.muscle.rest_length_m, rng,
                                                os.path.join(tmp, f"case_{case.seed}.csv"))  # fmt: skip
    recording.meta["source"] = f"virtual bench seed {case.seed} ({case.family})"
    return recording


def _noise_free(case: Case, recording: Recording) -> Recording:
    """The recording as noise-free sensors would make it: the truth's force at the length and
    the transducer's pressure as recorded (the supply's ripple and the regulator's transients
    included), without the sensors' white noise. Scoring must see the effect, not the pressure
    sensor's noise passed into the force through dF/dP: that error is in every recording, clean
    ones too, and no hypothesis can take it up (on clean 85 Hz strokes it left 0.21 N after the
    re-fit, a quarter of the force noise)."""
    L, P, F = case.true_length_m, case.true_pressure_Pa, case.true_force_N
    # no fallback to the recorded inputs: that is the noisy scoring this function exists to avoid
    if L is None or P is None or F is None:
        raise ValueError(f"seed {case.seed}: no noise-free truth (the case was not simulated)")
    if not len(L) == len(P) == len(F) == len(recording.time_s):
        raise ValueError(f"seed {case.seed}: the noise-free inputs do not match the recording's samples")
    return Recording(recording.time_s, np.asarray(L, float), np.asarray(P, float), F)


def identifiable(
    case: Case, recording: Recording | None, nominal, share: float = 0.25, more: tuple[Recording, ...] = ()
) -> tuple[bool, float]:
    """Whether the concealed effects show in this recording at all: the noise-free truth force is
    fitted by the model's own parameters alone (``model.refit``, the re-fit the diagnosis starts
    with) on noise-free inputs (:func:`_noise_free`), and what is left must stand above ``share``
    x the force noise. An effect the model's own parameters reproduce is parameter error by
    design; for scoring, its right answer is ``none``. ``more``: further noise-free recordings of
    the same truth diagnosed with it (``run_plan``'s ``meta["noise_free"]``): a next experiment
    can make an effect show that the first recording hid; with ``recording`` None, those alone
    (a test of another protocol run by ``run_plan``). Returns (identifiable, RMS left in N)."""
    from .model import refit

    truths = [*([] if recording is None else [_noise_free(case, recording)]), *more]
    fitted = refit(nominal, truths)
    residual = np.concatenate([fitted.muscle.push(r.pressure_Pa, r.length_m) - r.force_N for r in truths])
    left = float(np.sqrt(np.mean(residual**2)))
    return left >= share * case.noise_N, left


def left_after_baseline(case: Case, recording: Recording, nominal) -> float:
    """RMS (N) of the noise-free truth force left by the diagnosis's own no-effect model: the
    re-fit (``model.refit``) followed by the linearised corrections of the model's parameters and
    the input-noise column that every hypothesis is fitted with (``select.Engine.baseline``), on
    all samples. A second, stricter reading of "the model's own parameters reproduce it" than
    :func:`identifiable` (which stops after the re-fit); reported beside it, not scored."""
    from . import SPAN
    from .effects import Context
    from .model import linearise, refit
    from .segment import label
    from .select import Engine

    truth = _noise_free(case, recording)
    fitted = refit(nominal, [truth])
    ctx = Context.from_recordings([truth], fitted.muscle)
    labels = label(ctx.t, ctx.x, ctx.P, ctx.starts)
    lin = linearise(fitted.muscle, ctx.P, ctx.L, nominal, span=SPAN)
    base = Engine(ctx, lin, np.asarray(case.true_force_N, float), labels).candidate([], [], folds=False)
    return float(np.sqrt(base.rss / ctx.n))


def run_plan(case: Case, t, L, P_set, sample_hz: float, seed: int) -> Recording:
    """The truth's recording of an arbitrary program (e.g. a recommended next experiment): the
    same muscle and effect forms; the effects' parameters redrawn from the case's own stream, so
    they equal the first recording's (the stream is replayed up to them)."""
    rng = np.random.default_rng([case.seed, 11])
    first = PLANNERS[case.family](rng, case.muscle)  # replay the stream to the same draws
    del first
    dt = 1.0 / max(sample_hz, 200.0)
    tf = np.arange(0.0, float(t[-1]), dt)
    plan = Plan(tf, np.interp(tf, t, L), np.interp(tf, t, P_set), sample_hz, "next", "next experiment")
    twin = replace(case, params={})
    recording = simulate(twin, plan, rng, force_noise_N=case.noise_N)
    recording.meta["source"] = f"virtual bench seed {case.seed}: next experiment"
    # for scoring only (``identifiable``'s ``more``); the diagnosis never reads it
    recording.meta["noise_free"] = _noise_free(twin, recording)
    return recording
