"""Realistic synthetic bench recordings with one concealed effect, for blind tests of ``diagnose``.

The generator plays the experimenter of the paper's Sec. 3: the muscle is mounted in a test
machine at its resting length; for each test pressure, in ascending order (103.4 ... 517.1 kPa),
the pressure is set at the resting length and left to settle (the blocked force), then the
machine strokes the muscle out and back (5.1 mm/s, and one cycle three times faster), holding at
both ends of every stroke; finally the muscle is vented. Sensors add noise: load cell, pressure
transducer (the paper's 0.7 kPa), displacement. The pressure regulator reaches a new set point in
about a second and the measured pressure dips slightly while the muscle changes volume.

The truth is a randomised muscle (FAM1 or FAM2 constants perturbed within what the paper reports
as measurement spread, a stress law drawn from the paper's four with perturbed coefficients) plus
at most ONE concealed effect of random magnitude. The truth effects below are written
independently of ``diagnose.effects`` (this module imports nothing from it) and, wherever physics
allows, in a different functional form from the candidate library's terms:

================  ==========================================================================
effect            truth form (library form in brackets)
================  ==========================================================================
friction          Dahl model with exponent, one slip variable driven by strain and pressure,
                  normal force growing with P R_o(L)^2 (play operator per channel, linear in P)
viscoelasticity   generalised Maxwell, two branches, in the bladder stresses sigma_z and
                  sigma_c of Eq. 2 (one branch on strain, force linear in P)
end_effects       tapered ends of fixed axial length whose threads are pinned at the fitting:
                  gas volume, thread length and turns shared between cylinder and ends,
                  pressure force from -P dV/dL (Tondu's strain factor, linearised)
braid_compliance  threads stretch with thread tension ~ (P R_o)^m, solved self-consistently
                  (linear in P, linearised in B)
softening         Ogden-Roxburgh damage on the bladder stresses with a pressure-dependent
                  energy (virgin-curve indicator times strain)
drift             bladder modulus falls with a warming that grows as t^gamma (offset, strain
                  and pressure terms times a first-order approach)
pressure_lag      flow through the fitting, laminar at small pressure drops and turbulent
                  (square-root) at large ones, into a polytropic gas volume with a dead volume
                  (first-order lag with an isothermal volume term)
force_offset      constant load-cell zero error (a constant is a constant)
================  ==========================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import lfilter
from scipy.special import erf

from ..muscle import Muscle
from ..musclefile import load_muscle
from ..recordings import Recording
from ..stress import StressLaw

TRUTH_EFFECTS = (
    "none", "friction", "viscoelasticity", "end_effects", "braid_compliance",
    "softening", "drift", "pressure_lag", "force_offset",
)  # fmt: skip

PSI = 6894.757293168361
P_ATM = 101325.0


@dataclass(frozen=True)
class Protocol:
    """The test schedule (paper Sec. 3) and the sensors."""

    pressures_kPa: tuple[float, ...] = (103.4, 206.8, 310.3, 413.7, 517.1)
    cycles: tuple[str, ...] = ("slow", "fast", "slow")  # per pressure, in this order
    passive_cycles: tuple[str, ...] = ("slow",)  # first, unpressurised (the bladder alone)
    repeat_first: bool = True  # a last cycle at the first pressure: the repeatability check
    slow_speed_m_per_s: float = 5.1e-3
    fast_speed_m_per_s: float = 15.3e-3
    stroke_fraction: float = 0.98  # of the resting length (the MTS stopped at 198 %)
    hold_s: float = 4.0  # dwell at each end of every stroke
    settle_s: float = 5.0  # after each pressure change, at the resting length
    start_s: float = 10.0  # unpressurised at the resting length, before anything moves
    sample_hz: float = 20.0
    fine_hz: float = 200.0  # truth integration rate; recorded samples average fine ones
    force_noise_N: tuple[float, float] = (0.3, 0.8)  # drawn per recording
    pressure_noise_Pa: float = 700.0
    length_noise_m: float = 1e-5
    force_resolution_N: float = 0.02
    isometric: bool = False  # a pressure sweep at a fixed length instead (Festo-like)
    isometric_sweeps: int = 3
    isometric_sweep_s: float = 40.0


@dataclass
class Truth:
    """What the generator concealed (kept away from the diagnosis until it is scored)."""

    effect: str
    params: dict
    muscle: Muscle
    base_name: str
    law: str
    effect_rms_N: float = 0.0
    noise_N: float = 0.0
    notes: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------- the muscle
def random_truth_muscle(rng: np.random.Generator, base: str | None = None) -> tuple[Muscle, str]:
    """FAM1 or FAM2 with constants perturbed within the paper's measured spread and one of the
    paper's four stress laws with perturbed coefficients."""
    base = base or rng.choice(["FAM1", "FAM2"])
    law = str(rng.choice(["linear", "polynomial", "exponential_decay", "exponent"]))
    nominal = load_muscle(base, law=law)
    for _ in range(50):
        coeffs = list(nominal.stress.coefficients)
        coeffs[0] *= rng.uniform(0.85, 1.15)
        coeffs[1] *= rng.uniform(0.85, 1.15)
        if law in ("polynomial", "exponential_decay"):
            coeffs[2] *= rng.uniform(0.85, 1.15)
            coeffs[3] *= rng.uniform(0.9, 1.1)
        elif law == "exponent":
            coeffs[2] = float(np.clip(coeffs[2] * rng.uniform(0.9, 1.1), 0.1, 0.95))
            coeffs[3] = float(max(coeffs[3] * rng.uniform(0.95, 1.05), 1.05))
        try:
            muscle = replace(
                nominal,
                theta_rest_deg=nominal.theta_rest_deg * rng.uniform(0.975, 1.025),
                rest_diameter_m=nominal.rest_diameter_m * rng.uniform(0.98, 1.02),
                bladder_volume_m3=nominal.bladder_volume_m3 * rng.uniform(0.95, 1.05),
                deadband_Pa=nominal.deadband_Pa * rng.uniform(0.7, 1.3),
                stress=StressLaw(law, tuple(coeffs)),
            )
        except ValueError:
            continue
        return muscle, base
    raise RuntimeError("could not draw a stable truth muscle")


# -------------------------------------------------------------------------- the schedule
def _schedule(protocol: Protocol, rest_length: float, stroke: float, rng):
    """Breakpoints (time, length, pressure set point) of the experimenter's program."""
    t, L, P = [0.0], [rest_length], [0.0]

    def go(duration, length, pressure):
        t.append(t[-1] + duration)
        L.append(length)
        P.append(pressure)

    go(protocol.start_s * rng.uniform(0.8, 1.2), rest_length, 0.0)
    if protocol.isometric:
        top = protocol.pressures_kPa[-1] * 1e3
        for _ in range(protocol.isometric_sweeps):
            half = protocol.isometric_sweep_s * rng.uniform(0.8, 1.2) / 2
            go(half, rest_length, top)  # ramped up and down; synthesize() makes it a staircase
            go(half, rest_length, 0.0)
            go(protocol.hold_s, rest_length, 0.0)
        return np.array(t), np.array(L), np.array(P)
    plan = [(0.0, protocol.passive_cycles)] if protocol.passive_cycles else []
    plan += [(p, protocol.cycles) for p in protocol.pressures_kPa]
    if protocol.repeat_first:
        plan.append((protocol.pressures_kPa[0], protocol.cycles[:1]))
    for pressure_kPa, cycles in plan:
        pressure = pressure_kPa * 1e3
        go(1e-3, rest_length, pressure)  # set point step at the resting length
        go(protocol.settle_s * rng.uniform(0.9, 1.3), rest_length, pressure)
        for kind in cycles:
            speed = protocol.slow_speed_m_per_s if kind == "slow" else protocol.fast_speed_m_per_s
            go(stroke / speed, rest_length + stroke, pressure)
            go(protocol.hold_s * rng.uniform(0.9, 1.2), rest_length + stroke, pressure)
            go(stroke / speed, rest_length, pressure)
            go(protocol.hold_s * rng.uniform(0.9, 1.2), rest_length, pressure)
    go(1e-3, rest_length, 0.0)
    go(protocol.settle_s * 2, rest_length, 0.0)
    return np.array(t), np.array(L), np.array(P)


def _step_hold(t_break, values, t):
    """Set point held until the next breakpoint changes it (a zero-order hold on breakpoints)."""
    idx = np.searchsorted(t_break, t, side="right") - 1
    return values[np.clip(idx, 0, len(values) - 1)]


def _regulator(t, setpoint, volume_rate, volume, rng):
    """Transducer pressure: the PI-regulated response to the set point (about 1 s to settle,
    slightly under-damped) and the dip while the muscle draws gas (volume increasing)."""
    dt = t[1] - t[0]
    wn = 2 * math.pi * rng.uniform(0.6, 1.0)
    zeta = rng.uniform(0.7, 0.95)
    disturbance_gain = rng.uniform(0.05, 0.15)  # s: pressure dip per relative volume rate
    p, v = 0.0, 0.0
    out = np.empty_like(t)
    for i in range(len(t)):
        dip = disturbance_gain * (setpoint[i] + P_ATM) * volume_rate[i] / volume[i]
        acc = wn * wn * (setpoint[i] - p) - 2 * zeta * wn * v
        v += acc * dt
        p += v * dt
        out[i] = max(p - dip, 0.0)
    return out


# ------------------------------------------------------------------- truth force, Eq. 2
def _eq2_parts(m: Muscle, P, L, thread=None, turns=None):
    """Terms of Eq. 2 for a muscle whose thread length or turns may differ from the resting
    ones: (pressure term, sigma_z factor, sigma_c factor, eps_z, eps_c, R_o)."""
    B = m.thread_length_m if thread is None else thread
    N = m.turns if turns is None else turns
    Ro = np.sqrt(np.maximum(B * B - L * L, 1e-12)) / (2 * math.pi * N)
    wall = Ro - np.sqrt(np.maximum(Ro * Ro - m.bladder_volume_m3 / (math.pi * L), 0.0))
    eps_z = L / m.rest_length_m - 1.0
    eps_c = (Ro - wall / 2) / (m.rest_outer_radius_m - m.rest_wall_thickness_m / 2) - 1.0
    gauge = np.maximum(P - m.deadband_Pa, 0.0)
    pressure_term = gauge / (4 * math.pi * N * N) * (3 * L * L - B * B)
    factor_z = m.bladder_volume_m3 / L
    factor_c = wall * L * L / (2 * math.pi * Ro * N * N)
    return pressure_term, factor_z, factor_c, eps_z, eps_c, Ro


def _tension(m: Muscle, P, L, scale_z=1.0, scale_c=1.0, extra_z=0.0, extra_c=0.0, **kw):
    pres, fz, fc, ez, ec, _ = _eq2_parts(m, P, L, **kw)
    return pres + (scale_z * m.stress(ez, P) + extra_z) * fz - (scale_c * m.stress(ec, P) + extra_c) * fc


def _first_order(t, u, tau):
    a = math.exp(-(t[1] - t[0]) / tau)
    return lfilter([1 - a], [1, -a], u, zi=[a * u[0]])[0]


def _dahl(s, delta, exponent):
    """Dahl friction state z in [-1, 1] driven by the slip s (sub-stepped for accuracy)."""
    z = 0.0
    out = np.empty_like(s)
    prev = s[0]
    for i in range(len(s)):
        ds = s[i] - prev
        prev = s[i]
        n = int(abs(ds) / (0.05 * delta)) + 1
        h = ds / n
        sgn = 1.0 if h > 0 else -1.0
        for _ in range(n):
            z += h / delta * max(1.0 - z * sgn, 0.0) ** exponent
        out[i] = z
    return out


def _truth_effect(effect, rng, m: Muscle, t, L, P_tr, volume, volume_rate, p_top):
    """Truth tension (paper sign) with the concealed effect, the internal pressure, and params."""
    base = _tension(m, P_tr, L)
    P_int = P_tr
    params: dict = {}
    if effect == "none":
        return base, P_int, params
    if effect == "friction":
        F_ref = rng.uniform(3.0, 12.0)
        delta = rng.uniform(0.004, 0.02)
        exponent = rng.uniform(0.6, 1.5)
        share_p = rng.uniform(0.02, 0.08)  # slip per full pressure swing, in strain units
        # slip rises with strain, and with pressure in the direction that makes the force lag
        # the pressure (tension lags: higher while pressurising where pressure lowers it)
        pressure_sign = -np.sign(np.mean(3 * L * L - m.thread_length_m**2))
        slip = (L / m.rest_length_m - 1.0) + pressure_sign * share_p * P_tr / p_top
        z = _dahl(slip, delta, exponent)
        _, _, _, _, _, Ro = _eq2_parts(m, P_tr, L)
        normal = 0.2 + 0.8 * (P_tr / p_top) * (Ro / m.rest_outer_radius_m) ** 2
        params = dict(F_ref_N=F_ref, delta=delta, exponent=exponent, share_p=share_p)
        return base + F_ref * normal * z, P_int, params
    if effect == "viscoelasticity":
        E = m.stress.coefficients[0]
        g = (rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.2))
        tau = (rng.uniform(0.8, 4.0), rng.uniform(10.0, 60.0))
        pres, fz, fc, ez, ec, _ = _eq2_parts(m, P_tr, L)
        vz = sum(gi * E * (ez - _first_order(t, ez, ti)) for gi, ti in zip(g, tau))
        vc = sum(gi * E * (ec - _first_order(t, ec, ti)) for gi, ti in zip(g, tau))
        params = dict(g1=g[0], g2=g[1], tau1_s=tau[0], tau2_s=tau[1])
        return base + vz * fz - vc * fc, P_int, params
    if effect == "end_effects":
        # once in contact with the braid, the bladder bulges into the ends as the pressure
        # rises: the tapers shorten, most of it over the first hundred kPa
        end = rng.uniform(0.6, 1.5) * m.rest_outer_radius_m
        half = rng.uniform(30e3, 100e3)
        shrink = rng.uniform(0.5, 0.9)
        end_P = end * (1.0 - shrink * P_tr / (P_tr + half))
        params = dict(end_length_m=end, shrink=shrink, half_kPa=half / 1e3)
        return _tapered_ends(m, P_tr, L, end_P), P_int, params
    if effect == "braid_compliance":
        strain_top = rng.uniform(0.008, 0.025)
        exponent = rng.uniform(0.5, 0.9)
        B = np.full_like(L, m.thread_length_m)
        for _ in range(6):  # thread stretch depends on the radius it sets: fixed point
            _, _, _, _, _, Ro = _eq2_parts(m, P_tr, L, thread=B)
            load = np.maximum(P_tr / p_top * Ro / m.rest_outer_radius_m, 0.0)
            B = m.thread_length_m * (1.0 + strain_top * load**exponent)
        params = dict(thread_strain_at_top=strain_top, exponent=exponent)
        return _tension(m, P_tr, L, thread=B), P_int, params
    if effect == "softening":
        r = rng.uniform(3.0, 8.0)
        beta = 0.1
        c = m.stress.coefficients
        _, _, _, ez, ec, _ = _eq2_parts(m, P_tr, L)
        energy = 0.5 * (c[0] + c[1] * P_tr) * (ez * ez + ec * ec)
        peak = np.maximum.accumulate(energy)
        width = rng.uniform(0.05, 0.3) * energy.max()
        eta = 1.0 - erf((peak - energy) / (width + beta * peak)) / r
        params = dict(r=r, width_frac=width / energy.max(), beta=beta)
        return _tension(m, P_tr, L, scale_z=eta, scale_c=eta), P_int, params
    if effect == "drift":
        loss = rng.uniform(0.04, 0.15)  # fractional modulus loss at the end of the test
        gamma = rng.uniform(0.6, 1.6)
        warm = (t / t[-1]) ** gamma
        scale = 1.0 - loss * warm
        params = dict(modulus_loss=loss, gamma=gamma)
        return _tension(m, P_tr, L, scale_z=scale, scale_c=scale), P_int, params
    if effect == "pressure_lag":
        P_int = _orifice_fill(rng, t, P_tr, volume, params)
        return _tension(m, P_int, L), P_int, params
    if effect == "force_offset":
        offset = rng.choice([-1, 1]) * rng.uniform(1.5, 8.0)
        params = dict(offset_N=offset)
        return base - offset, P_int, params  # tension = -push: a push offset
    raise ValueError(f"unknown truth effect '{effect}' (known: {', '.join(TRUTH_EFFECTS)})")


def _orifice_fill(rng, t, P_tr, volume, params):
    """Gas flows from the transducer's side through the fitting into the muscle's gas volume
    plus a dead volume: laminar at small pressure drops, turbulent (square-root) at large ones;
    polytropic compression when the muscle changes volume."""
    tau = rng.uniform(0.08, 0.4)  # small-signal fill time constant
    knee = rng.uniform(50e3, 200e3)  # pressure drop where turbulence takes over
    polytropic = rng.uniform(1.0, 1.4)
    dead = rng.uniform(0.0, 0.3) * float(np.mean(volume))
    dt = t[1] - t[0]
    p = P_tr[0]
    out = np.empty_like(P_tr)
    P_list, V_list = P_tr.tolist(), volume.tolist()
    for i in range(len(t)):
        v = V_list[i] + dead
        dv = (V_list[i] - V_list[i - 1]) if i else 0.0
        for _ in range(4):
            drop = P_list[i] - p
            rate = 2 * knee / tau * (math.sqrt(1.0 + abs(drop) / knee) - 1.0)
            p += math.copysign(rate, drop) * dt / 4
        p = max(p - polytropic * (p + P_ATM) * dv / v, 0.0)
        out[i] = p
    params.update(
        tau_s=tau, knee_kPa=knee / 1e3, polytropic=polytropic, dead_volume_frac=dead / float(np.mean(volume))
    )
    return out


def _tapered_ends(m: Muscle, P, L, end):
    """A muscle whose ends keep the fitting radius over an axial length ``end`` each, tapering
    linearly to the cylinder. Threads are pinned in the ends (their turns there fixed at the
    resting value); the cylinder takes the rest. Force from -P dV/dL plus the bladder stresses
    of the cylinder."""
    R_f = m.rest_outer_radius_m
    turns_end = m.turns * end / m.rest_length_m

    def geometry(Lx):
        Lc = Lx - 2 * end
        Ro = np.full_like(Lx, R_f)
        for _ in range(30):  # thread in a taper depends on the cylinder radius: fixed point
            mean_r = (R_f + Ro) / 2
            b_end = np.sqrt(end**2 + (2 * math.pi * turns_end * mean_r) ** 2)
            Bc = m.thread_length_m - 2 * b_end
            Nc = m.turns - 2 * turns_end
            Ro_new = np.sqrt(np.maximum(Bc * Bc - Lc * Lc, 1e-12)) / (2 * math.pi * Nc)
            if np.max(np.abs(Ro_new - Ro)) < 1e-12:
                break
            Ro = 0.5 * Ro + 0.5 * Ro_new
        cone = math.pi * end * (R_f * R_f + R_f * Ro + Ro * Ro) / 3
        return Lc, Ro, math.pi * Ro * Ro * Lc + 2 * cone, Nc

    h = 1e-6
    _, _, V_hi, _ = geometry(L + h)
    _, _, V_lo, _ = geometry(L - h)
    Lc, Ro, _, Nc = geometry(L)
    gauge = np.maximum(P - m.deadband_Pa, 0.0)
    pressure_term = -gauge * (V_hi - V_lo) / (2 * h)
    # bladder of the cylinder: its share of the volume, strains against its own rest state
    share = (m.rest_length_m - 2 * end) / m.rest_length_m
    Vc = m.bladder_volume_m3 * share
    wall = Ro - np.sqrt(np.maximum(Ro * Ro - Vc / (math.pi * Lc), 0.0))
    eps_z = Lc / (m.rest_length_m - 2 * end) - 1.0
    eps_c = (Ro - wall / 2) / (m.rest_outer_radius_m - m.rest_wall_thickness_m / 2) - 1.0
    return (
        pressure_term
        + m.stress(eps_z, P) * Vc / Lc
        - m.stress(eps_c, P) * wall * Lc * Lc / (2 * math.pi * Ro * Nc * Nc)
    )


# ----------------------------------------------------------------------------- generator
def synthesize(
    seed: int,
    effect: str | None = None,
    protocol: Protocol | None = None,
    base: str | None = None,
) -> tuple[Recording, Truth]:
    """One recording and its concealed truth. ``effect=None`` draws one of TRUTH_EFFECTS
    (``none`` included) at random."""
    rng = np.random.default_rng(seed)
    protocol = protocol or Protocol()
    if effect is None:
        effect = str(rng.choice(TRUTH_EFFECTS))
    if effect not in TRUTH_EFFECTS:
        raise ValueError(f"unknown truth effect '{effect}' (known: {', '.join(TRUTH_EFFECTS)})")
    muscle, base_name = random_truth_muscle(rng, base)
    rest = muscle.rest_length_m
    if protocol.isometric:
        held = rest * rng.uniform(1.0, 1.3)
        t_b, L_b, P_b = _schedule(protocol, held, 0.0, rng)
    else:
        stroke = min(protocol.stroke_fraction * rest, 0.95 * (muscle.max_length_m - rest))
        t_b, L_b, P_b = _schedule(protocol, rest, stroke, rng)
    dt = 1.0 / protocol.fine_hz
    t = np.arange(0.0, t_b[-1], dt)
    L = np.interp(t, t_b, L_b)
    setpoint = _step_hold(t_b, P_b, t)
    if protocol.isometric:  # a staircase of 12 set points up and down
        step = P_b.max() / 12
        setpoint = np.round(np.interp(t, t_b, P_b) / step) * step
    gas = np.maximum((muscle.thread_length_m**2 - L * L) * L / (4 * math.pi * muscle.turns**2), 1e-7)
    volume = np.maximum(gas - muscle.bladder_volume_m3, 1e-7)
    volume_rate = np.gradient(volume, t)
    P_tr = _regulator(t, setpoint, volume_rate, volume, rng)
    p_top = max(protocol.pressures_kPa) * 1e3
    tension, _, params = _truth_effect(effect, rng, muscle, t, L, P_tr, volume, volume_rate, p_top)
    clean = _tension(muscle, P_tr, L)
    # the data acquisition averages the fine samples into the recorded ones
    per = max(int(round(protocol.fine_hz / protocol.sample_hz)), 1)
    n = len(t) // per

    def record(x):
        return x[: n * per].reshape(n, per).mean(axis=1)

    t_rec = t[: n * per].reshape(n, per)[:, 0]
    force_true = -record(tension)
    effect_part = force_true + record(clean)
    noise = rng.uniform(*protocol.force_noise_N)
    force = force_true + rng.normal(0.0, noise, n)
    force = np.round(force / protocol.force_resolution_N) * protocol.force_resolution_N
    pressure = record(P_tr) + rng.normal(0.0, protocol.pressure_noise_Pa, n)
    length = record(L) + rng.normal(0.0, protocol.length_noise_m, n)
    recording = Recording(
        t_rec - t_rec[0], length, pressure, force, meta={"source": f"synthetic seed {seed}"}
    )
    truth = Truth(
        effect=effect,
        params=params,
        muscle=muscle,
        base_name=base_name,
        law=muscle.stress.name,
        effect_rms_N=float(np.sqrt(np.mean(effect_part**2))),
        noise_N=noise,
    )
    return recording, truth
