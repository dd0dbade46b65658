"""Candidate physics the force-balance model (Eq. 2) leaves out, as small causal terms.

Every candidate adds a force ``dF`` (N, MuJoCo sign: positive pushes the ends apart) to the
model's ``Muscle.push(P, L)``. It is computed from what a simulation step knows: the gauge pressure
P, the length L, their previous values (so their rates), the time t since the start, and a small
state. Each term is written so that its amplitudes enter linearly (fitted by bounded linear least
squares together with small corrections of the model's own parameters) and a few *shape*
parameters (slip widths, a relaxation rate, a time constant) enter non-linearly (searched on a
grid, then refined), with at most two *modes* (a clock, a course, a corner's form) taken from
their values only.

Notation: x = L / L_rest - 1 (axial strain), P_MPa = P / 1e6, B and N the thread length and turns,
F(P, L) the model's push force, play(u, w) the play operator (a backlash of half-width w whose
output z in [-1, 1] moves only while u keeps moving the same way: z_k = clip(z_{k-1} + du_k / w,
-1, 1); friction's may also relax toward 0 in time), lag(u, tau) the first-order lag
y_k = y_{k-1} + (1 - exp(-dt / tau)) (u_k - y_{k-1}) (MuJoCo's ``filterexact``).

A tension-only muscle that the model calls slack carries no effect force except the sensor's
(``force_offset``): the terms are multiplied by ``engaged`` = (model force != 0).

The reference per-sample implementation (:meth:`Effect.step`) is what a C plugin would run; the
vectorised one (:meth:`Effect.design`) is what the diagnosis fits; a test holds them equal.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter

from ..muscle import Muscle
from ..recordings import Recording

P_ATM = 101325.0


# ------------------------------------------------------------------------ causal primitives
def segments(starts: np.ndarray, n: int):
    """(begin, end) index pairs of the recordings concatenated in one array."""
    edges = list(starts) + [n]
    return [(int(edges[i]), int(edges[i + 1])) for i in range(len(starts))]


def lag(t: np.ndarray, u: np.ndarray, tau: float, starts=(0,)) -> np.ndarray:
    """First-order lag, exact for a held input (MuJoCo ``filterexact``): y_0 = u_0 at each start,
    y_k = a_k y_{k-1} + (1 - a_k) u_k with a_k = exp(-(t_k - t_{k-1}) / tau).

    Uniform sampling runs as a linear filter; otherwise the step into each block is taken alone
    (it may be a pause of any length in the recording) and, within the block, spanning at most
    500 tau from its first sample b, y_k = A_k (y_b + sum_j (1 - a_j) u_j / A_j) with
    A_k = exp(-(t_k - t_b) / tau)."""
    out = np.empty_like(u, dtype=float)
    for b, e in segments(np.asarray(starts), len(u)):
        tt, uu, yy = t[b:e], u[b:e], out[b:e]
        dt = np.diff(tt)
        if len(dt) and np.ptp(dt) <= 1e-6 * abs(dt[0]):
            a = math.exp(-float(dt.mean()) / tau)
            yy[:] = lfilter([1.0 - a], [1.0, -a], uu, zi=[a * uu[0]])[0]
            continue
        y = float(uu[0])
        yy[0] = y
        k = 1
        while k < len(tt):
            # the step into the block by itself: measured from the block's previous sample, a
            # pause over ~745 tau (a 40 s gap at tau 50 ms) underflows A to 0, and u / A to inf
            a0 = math.exp(-float(tt[k] - tt[k - 1]) / tau)
            y = a0 * y + (1.0 - a0) * float(uu[k])
            yy[k] = y
            stop = max(int(np.searchsorted(tt, tt[k] + 500.0 * tau, side="right")), k + 1)
            if stop > k + 1:
                s = slice(k + 1, stop)
                A = np.exp(-(tt[s] - tt[k]) / tau)
                a = np.exp(-np.diff(tt[k:stop]) / tau)
                yy[s] = A * (y + np.cumsum((1.0 - a) * uu[s] / A))
                y = float(yy[stop - 1])
            k = stop
    return out


DELAY_FLOOR_S = 1e-3  # the smallest transport delay searched on data sampled faster than 1 kHz
#: the longest time the errors-in-variables window may span: pressure content slower than
#: ~10 Hz is the rig's own (a regulator settles in 0.1-1 s), not the sensor's noise
EIV_SPAN_S = 0.1
#: a window deviation beyond this many times the pressure noise's own is a real step, not noise
EIV_OUTLIER = 4.0


def delayed(t: np.ndarray, u: np.ndarray, delay: float, starts=(0,)) -> np.ndarray:
    """``u`` delayed by ``delay`` seconds within each recording, linearly interpolated between
    samples, the first sample held before the start: MuJoCo's ctrl delay with ``interp="linear"``
    and its history filled with the first value. MuJoCo reads the history before it stores the
    current sample, so a delay shorter than the last interval gives the previous sample (at least
    one step of delay). ``delay <= 0``: ``u`` itself."""
    u = np.asarray(u, dtype=float)
    if delay <= 0:
        return u.copy()
    out = np.empty_like(u)
    for b, e in segments(np.asarray(starts), len(u)):
        tt, uu = t[b:e], u[b:e]
        seg = np.interp(tt - delay, tt, uu)
        previous_t = np.r_[-np.inf, tt[:-1]]
        short = tt - delay > previous_t
        seg[short] = np.r_[uu[0], uu[:-1]][short]
        out[b:e] = seg
    return out


def play(
    u: np.ndarray, width: float, starts=(0,), t=None, relax_per_s: float = 0.0, smooth: bool = False
) -> np.ndarray:
    """Play operator output z in [-1, 1] (0 at each start): z_k = clip(a_k z_{k-1} + du_k/width,
    -1, 1) with a_k = exp(-relax_per_s (t_k - t_{k-1})): 1 (no relaxation) unless times ``t`` and
    a rate are given. ``smooth``: Dahl's operator instead, dz = (1 - z sign(du)) du/width, whose
    corner is rounded: z approaches +-1 exponentially in the slip (:func:`dahl_step`)."""
    out = np.empty(len(u))
    values = (np.asarray(u, dtype=float) / width).tolist()
    if relax_per_s > 0.0 and t is not None:
        dt = np.diff(np.asarray(t, dtype=float), prepend=float(t[0]))
        # each recording's clock starts again: the step into a start is not a time step (going
        # back hundreds of seconds it would overflow exp, and 0 x inf would poison the file)
        dt[np.asarray(starts, dtype=int)] = 0.0
        keep = np.exp(-relax_per_s * dt).tolist()
    else:
        keep = [1.0] * len(values)
    for b, e in segments(np.asarray(starts), len(u)):
        z = 0.0
        prev = values[b]
        if smooth:  # two loops: this one runs for every shape the search tries
            for i in range(b, e):
                v = values[i]
                z = dahl_step(z * keep[i], v - prev)
                prev = v
                out[i] = z
            continue
        for i in range(b, e):
            v = values[i]
            z = z * keep[i] + v - prev
            prev = v
            z = 1.0 if z > 1.0 else (-1.0 if z < -1.0 else z)
            out[i] = z
    return out


def dahl_step(z: float, du: float) -> float:
    """Dahl's friction state after a slip ``du`` (in widths) from ``z``: dz/du = 1 - z sign(du),
    integrated exactly over the step, so z stays inside [-1, 1] at any step size."""
    if du > 0.0:
        return 1.0 - (1.0 - z) * math.exp(-du)
    if du < 0.0:
        return -1.0 + (1.0 + z) * math.exp(du)
    return z


def running_max(u: np.ndarray, starts=(0,)) -> np.ndarray:
    """Running maximum of ``u`` restarted at every recording start in ``starts``."""
    out = np.empty_like(u, dtype=float)
    for b, e in segments(np.asarray(starts), len(u)):
        out[b:e] = np.maximum.accumulate(u[b:e])
    return out


def backward_rate(t: np.ndarray, u: np.ndarray, starts=(0,)) -> np.ndarray:
    """(u_k - u_{k-1}) / (t_k - t_{k-1}), zero at each start (causal)."""
    out = np.zeros(len(u))
    for b, e in segments(np.asarray(starts), len(u)):
        if e - b > 1:
            out[b + 1 : e] = np.diff(u[b:e]) / np.maximum(np.diff(t[b:e]), 1e-12)
    return out


def high_frequency_noise(u: np.ndarray, starts=(0,)) -> float:
    """Robust white-noise level of a signal: the MAD of its second differences / sqrt(6)
    (a smooth signal has small second differences; noise has variance 6 sigma^2 there)."""
    parts = [np.diff(u[b:e], 2) for b, e in segments(np.asarray(starts), len(u)) if e - b > 2]
    if not parts:
        return 0.0
    d2 = np.concatenate(parts)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


# ----------------------------------------------------------------------- model quantities
def tension_with_thread(muscle: Muscle, P, L, thread_scale):
    """Eq. 2 with the thread length B scaled (threads that stretch), N and the resting state
    unchanged. Equal to ``muscle.tension`` at scale 1 inside the admissible range."""
    P = np.maximum(np.asarray(P, dtype=float), 0.0)
    L = np.clip(np.asarray(L, dtype=float), muscle.min_length_m, muscle.max_length_m)
    B = muscle.thread_length_m * np.asarray(thread_scale, dtype=float)
    N = muscle.turns
    r_out = np.sqrt(np.maximum(B * B - L * L, 0.0)) / (2 * math.pi * N)
    wall = r_out - np.sqrt(np.maximum(r_out * r_out - muscle.bladder_volume_m3 / (math.pi * L), 0.0))
    eps_z = L / muscle.rest_length_m - 1.0
    eps_c = (r_out - wall / 2) / (muscle.rest_outer_radius_m - muscle.rest_wall_thickness_m / 2) - 1.0
    gauge = np.maximum(P - muscle.deadband_Pa, 0.0)
    return (
        gauge / (4 * math.pi * N * N) * (3 * L * L - B * B)
        + muscle.stress(eps_z, P) * muscle.bladder_volume_m3 / L
        - muscle.stress(eps_c, P) * wall * L * L / (2 * math.pi * r_out * N * N)
    )


THREAD_SECANT = 0.01  # the thread stretch the braid term's slope spans (threads stretch 0.1-3 %)


def braid_slope(muscle: Muscle, P, L):
    """The push force's change per relative thread stretch, N: the secant of Eq. 2 from the
    thread length B to B (1 + ``THREAD_SECANT``), divided by that stretch. Not the tangent: at the
    resting length the circumferential strain is zero, where a stress law such as the exponent
    law has no finite slope, and there the tangent stood 4-13 times the secant of a 0.3-2 %
    stretch (FAM1 with E3 0.52, 150-517 kPa: the braid term then could not follow a thread stretch
    on strokes from rest). Threads
    only lengthen, so the secant runs one way, towards a longer B."""
    lengthened = tension_with_thread(muscle, P, L, 1.0 + THREAD_SECANT)
    return -(lengthened - tension_with_thread(muscle, P, L, 1.0)) / THREAD_SECANT


def bladder_tension(muscle: Muscle, P, L):
    """The bladder's share of Eq. 2 (the two stress terms), paper sign."""
    L = np.clip(np.asarray(L, dtype=float), muscle.min_length_m, muscle.max_length_m)
    P = np.maximum(np.asarray(P, dtype=float), 0.0)
    eps_z, eps_c = muscle.strains(L)
    wall = muscle.wall_thickness(L)
    r_out = muscle.outer_radius(L)
    N = muscle.turns
    return muscle.stress(eps_z, P) * muscle.bladder_volume_m3 / L - muscle.stress(eps_c, P) * wall * L * L / (
        2 * math.pi * r_out * N * N
    )


def gas_volume(muscle: Muscle, L):
    """Gas inside the muscle: the sleeve cylinder pi R_o(L)^2 L less the bladder wall V_B."""
    L = np.clip(np.asarray(L, dtype=float), muscle.min_length_m, muscle.max_length_m)
    return np.maximum(math.pi * muscle.outer_radius(L) ** 2 * L - muscle.bladder_volume_m3, 1e-9)


class Context:
    """The inputs of the effect terms for concatenated recordings, with the base model."""

    def __init__(self, t, L, P, starts, muscle: Muscle):
        self.t = np.asarray(t, dtype=float)
        self.L = np.asarray(L, dtype=float)
        self.P = np.asarray(P, dtype=float)
        self.starts = np.asarray(starts, dtype=int)
        self.muscle = muscle
        self.n = len(self.t)
        self.x = self.L / muscle.rest_length_m - 1.0
        self.P_MPa = self.P / 1e6
        self.base = muscle.push(self.P, self.L)
        self.engaged = (self.base != 0.0) if muscle.tension_only else np.ones(self.n, dtype=bool)
        self.pressure_noise_Pa = high_frequency_noise(self.P, self.starts)
        self.strain_noise = high_frequency_noise(self.x, self.starts)
        self._cache: dict = {}

    @classmethod
    def from_recordings(cls, recordings: list[Recording], muscle: Muscle) -> Context:
        """The context of several recordings joined end to end (each keeps its own start)."""
        starts = np.cumsum([0] + [len(r) for r in recordings[:-1]])
        return cls(
            np.concatenate([r.time_s - r.time_s[0] for r in recordings]),
            np.concatenate([r.length_m for r in recordings]),
            np.concatenate([r.pressure_Pa for r in recordings]),
            starts,
            muscle,
        )

    def cached(self, key, make):
        """``make()`` computed once per context and kept under ``key``."""
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def dF_dL(self):
        """Slope of the muscle's push with length at every sample (N/m), central difference."""
        h = 1e-6 * self.muscle.rest_length_m
        m = self.muscle
        return self.cached("dL", lambda: (m.push(self.P, self.L + h) - m.push(self.P, self.L - h)) / (2 * h))

    def dF_dP(self):
        """Slope of the muscle's push with pressure at every sample (N/Pa), central difference."""
        m = self.muscle
        return self.cached(
            "dP", lambda: (m.push(self.P + 100.0, self.L) - m.push(self.P - 100.0, self.L)) / 200.0
        )

    def input_noise(self):
        """The force error the model inherits from the pressure sensor's noise (errors in
        variables): dF/dP times the pressure's deviation from its centred mean over 5 samples,
        or over 3 where 5 would span more than ``EIV_SPAN_S`` (under 40 Hz). Real pressure
        changes (a regulator settling, a valve's transient) must stay out of the window: at
        25-30 Hz a 5-sample window spans 0.15-0.2 s, takes in a transient the muscle does feel,
        and the column's fitted coefficient then cancels part of the model's true response (a
        data-driven correction found 3-4 % of held-out gain on clean files there, and none at
        100 Hz). A deviation over ``EIV_OUTLIER`` times what the pressure's own white noise
        gives is a real step (a regulator's, a stroke's volume change) and is left out: on clean
        48 Hz strokes the few samples at pressure steps held 53 % of the column's variance and
        pulled its coefficient to 0.43 of the sensor noise's; left out, 0.95, and the force
        error the noise leaves fell from 0.32 to 0.24 N RMS."""

        def make():
            out = np.zeros(self.n)
            for b, e, sigma, width in self._eiv_recordings():
                u = self.P[b:e]
                if e - b >= width:
                    half = width // 2
                    padded = np.r_[u[:half][::-1], u, u[-half:][::-1]]
                    dev = u - np.convolve(padded, np.ones(width) / width, mode="valid")
                    # white noise of level s deviates from the window mean by s sqrt(1 - 1/w);
                    # far beyond that the deviation is a real step or transient, not noise
                    cut = EIV_OUTLIER * sigma * math.sqrt(1.0 - 1.0 / width)
                    out[b:e] = np.where(np.abs(dev) > cut, 0.0, dev) if cut > 0 else dev
            return out * self.dF_dP()

        return self.cached("eiv", make)

    def recording_steps(self) -> list[tuple[int, int, float]]:
        """Per recording: its sample range ``b, e`` and its median time step (s; 0 with fewer
        than two samples), computed once for every feature that needs a recording's rate."""

        def make():
            return [
                (b, e, float(np.median(np.diff(self.t[b:e]))) if e - b >= 2 else 0.0)
                for b, e in segments(self.starts, self.n)
            ]

        return self.cached("recording_steps", make)

    def _eiv_recordings(self) -> list[tuple[int, int, float, int]]:
        """Per recording: its sample range ``b, e``, its pressure's white-noise level (Pa) and the
        samples in its errors-in-variables window (see ``input_noise``), computed once."""

        def make():
            return [
                (b, e, high_frequency_noise(self.P[b:e]), 5 if 4 * dt <= EIV_SPAN_S else 3)
                for b, e, dt in self.recording_steps()
            ]

        return self.cached("eiv_recordings", make)

    def input_noise_floor(self) -> float:
        """RMS force error (N) the pressure sensor's noise leaves in any prediction after the
        errors-in-variables column: that column takes out the noise's deviation from its window
        mean, and the window mean's own noise (variance sigma^2 / w) passes into the model
        force through dF/dP. No hypothesis can predict it, so it belongs to the noise floor;
        being smooth it is invisible to the high-frequency noise estimate of the force (clean
        48 Hz strokes: 0.15 N beside a 0.59 N force noise)."""
        dFdP = self.dF_dP()
        total = 0.0
        for b, e, sigma, width in self._eiv_recordings():
            total += float(np.sum(dFdP[b:e] ** 2)) * sigma**2 / width
        return math.sqrt(total / max(self.n, 1))

    def bladder_push(self):
        """The bladder's share of the push force at every sample (N): minus its Eq. 2 tension terms."""
        return self.cached("bladder", lambda: -bladder_tension(self.muscle, self.P, self.L))

    def pressure_clock(self):
        """Seconds at 1 MPa borne since each recording's start: the sum of P_MPa (t_k - t_{k-1})
        over the samples so far (``Drift.step``'s own rule, so that replay and plugin agree)."""

        def make():
            u = np.zeros(self.n)
            for b, e in segments(self.starts, self.n):
                u[b + 1 : e] = np.cumsum(np.maximum(self.P_MPa[b + 1 : e], 0.0) * np.diff(self.t[b:e]))
            return u

        return self.cached("pressure_clock", make)

    def braid_slope(self):
        """The push force's change per relative thread stretch, as a secant over a stretch of
        ``THREAD_SECANT`` (:func:`braid_slope`)."""
        return self.cached("dB", lambda: braid_slope(self.muscle, self.P, self.L))

    def pressure_sign(self):
        """Sign of d push / d P from Eq. 2's pressure term: +1 where 3 L^2 < B^2 (pressure pushes)."""
        m = self.muscle
        return self.cached("sP", lambda: -np.sign(3 * self.L**2 - m.thread_length_m**2))


# ---------------------------------------------------------------------------- the library
@dataclass(frozen=True)
class Param:
    """A parameter, its unit in the key. ``shape``: searched non-linearly on ``grid`` (log)."""

    key: str
    lo: float
    hi: float
    shape: bool = False
    grid: tuple[float, ...] = ()
    meaning: str = ""
    default: float | None = None  # an optional key's value when it is not given (older files)
    discrete: bool = False  # a shape that takes its grid's values only (a mode), never refined

    def value_in(self, values: dict) -> float:
        """This parameter's value in ``values``, its default when it is optional and absent."""
        return values[self.key] if self.key in values or self.default is None else self.default


@dataclass
class Effect:
    """A candidate term. Subclasses give ``_design`` (vectorised) and ``step`` (per sample)."""

    name: str = ""
    summary: str = ""
    equation: str = ""
    params: tuple[Param, ...] = ()
    state: tuple[str, ...] = ()
    plugin: str = ""
    signature: str = ""  # what it leaves in the residual, in words
    per_recording: bool = False  # one amplitude per recording (its single linear parameter)

    @property
    def linear(self) -> tuple[Param, ...]:
        """The parameters that enter the force linearly (solved exactly by least squares)."""
        return tuple(p for p in self.params if not p.shape)

    @property
    def shapes(self) -> tuple[Param, ...]:
        """The parameters that shape the force non-linearly (searched over their grid)."""
        return tuple(p for p in self.params if p.shape)

    def shape_range(self, ctx: Context, p: Param) -> tuple[float, tuple[float, ...], float]:
        """(lowest value, grid, highest value) of a shape parameter for these recordings."""
        return p.lo, p.grid, p.hi

    def settle(self, ctx: Context, shape: dict[str, float]) -> dict[str, float]:
        """The shape values as the model uses and writes them, from the values the (log-space)
        search over ``ctx`` tried; by default the same. Applied where the search fits (``select``),
        not in :meth:`design`: fitted values simulated on other data keep their meaning."""
        return dict(shape)

    def fit_basis(self, ctx: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """How the fit solves for the linear values on ``ctx``, when not directly: (T, lo, hi),
        the linear values being ``T @ k`` with ``lo <= k <= hi``. A physical law that bounds a
        combination of the values (a thread that does not shorten under more load) is a box
        on ``k``; None (the default): the values themselves, within their own bounds."""
        return None

    def design(self, ctx: Context, shape: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """(fixed force, columns): dF = fixed + columns @ linear values, both zero where the
        muscle is slack (except the sensor offset)."""
        key = (self.name, tuple(sorted(shape.items())))
        return ctx.cached(key, lambda: self._design(ctx, shape))

    def _design(self, ctx: Context, shape):  # pragma: no cover - abstract
        raise NotImplementedError

    def force(self, ctx: Context, values: dict[str, float]) -> np.ndarray:
        """The effect's added push force (N) at every sample of ``ctx`` for parameter ``values``."""
        shape = {p.key: p.value_in(values) for p in self.shapes}
        fixed, cols = self.design(ctx, shape)
        if self.per_recording:
            key = self.linear[0].key
            a = np.array(values.get(f"{key}_by_recording") or [values[key]] * cols.shape[1])
        else:
            a = np.array([p.value_in(values) for p in self.linear])
        return fixed + (cols @ a if len(a) else 0.0)

    def initial_state(self) -> list[float]:
        """The effect's state before the first sample (zeros), for stepwise replay."""
        return [0.0] * len(self.state)

    def step(self, values, state, sample) -> float:  # pragma: no cover - abstract
        """Advance the effect by one sample and return its added push force (N); updates ``state`` in place."""
        raise NotImplementedError


def _gate(ctx, cols):
    return cols * ctx.engaged[:, None] if cols.ndim == 2 else cols * ctx.engaged


@dataclass
class Sample:
    """What the per-sample reference step sees (the plugin sees the same)."""

    t: float
    P: float
    L: float
    P_prev: float
    L_prev: float
    dt: float
    first: bool
    muscle: Muscle

    @property
    def x(self) -> float:
        """The muscle's axial strain at this sample, L / L_rest - 1."""
        return self.L / self.muscle.rest_length_m - 1.0

    @property
    def bladder_push(self) -> float:
        """The bladder's share of the push force at this sample (N), as :meth:`Context.bladder_push`."""
        return -float(bladder_tension(self.muscle, self.P, self.L))

    @property
    def engaged(self) -> bool:
        """Whether the muscle carries force at this sample (a slack tension-only muscle does not)."""
        return (not self.muscle.tension_only) or self.muscle.push(self.P, self.L) != 0.0


class Friction(Effect):
    """Rate-independent friction at one sliding contact: a play operator on a slip that the strain
    and the pressure both drive, its stick force growing with pressure and able to relax in holds.
    The operator's corner is sharp (elastic, then sliding: Prandtl's) or rounded (``smooth``:
    Dahl's, the stuck share nearing the full force exponentially in the slip). Real contacts
    are mostly rounded (bristles, a spread of asperities: Dahl, LuGre, Iwan), and a rounded
    loop that only the sharp corner could follow was taken by the viscoelastic branches."""

    def __init__(self):
        super().__init__(
            name="friction",
            summary=(
                "direction-dependent, rate-independent hysteresis (braid/bladder/tube friction); "
                "a stroke and a pressure change slide the same contact"
            ),
            equation=(
                "dF = -(f0 + f1 P_MPa) z,  z = play(x / w_x + s_P P / w_P) relaxing at rate r: "
                "z_k = clip(exp(-r dt) z_{k-1} + du_k, -1, 1), or rounded (smooth 1, Dahl): "
                "dz/du = 1 - z sign(du);  s_P = sign(B^2 - 3 L^2)"
            ),
            params=(
                Param("f0_N", 0.0, 100.0, meaning="friction force opposing the slip at zero pressure"),
                Param("f1_N_per_MPa", 0.0, 300.0, meaning="its growth with pressure (the contact's load)"),
                Param(
                    "slip_strain",
                    5e-4,
                    0.05,
                    shape=True,
                    grid=(1e-3, 3e-3, 6e-3, 0.012, 0.025),
                    meaning="pre-sliding strain: the stroke that slides the contact through its stick range",
                ),
                Param(
                    "slip_kPa",
                    0.0,
                    1e4,
                    shape=True,
                    grid=(5.0, 20.0, 80.0, 300.0, 1500.0),
                    meaning="the pressure change (at a fixed length) that does the same; 0: pressure slides nothing",
                ),
                Param(
                    "relax_per_s",
                    0.0,
                    10.0,
                    shape=True,
                    grid=(1e-3, 0.03, 0.3),
                    meaning="rate at which the stuck force relaxes in a hold (the supply's dither, creep of "
                    "the contact); 0 (when absent): it persists",
                    default=0.0,
                ),
                Param(
                    "smooth",
                    0.0,
                    1.0,
                    True,
                    (0.0, 1.0),
                    "0: a sharp stick-slip corner (play operator); 1: a rounded one (Dahl: the stuck "
                    "share nears the full force exponentially in the slip)",
                    default=0.0,
                    discrete=True,
                ),
            ),
            state=("z",),
            plugin="efam.muscle keys friction.*; 1 play state (and the shared previous L and P)",
            signature=(
                "a force step with the direction of motion, the same at any speed, held (or slowly "
                "relaxed) in holds"
            ),
        )

    #: the search's lowest relaxation rate (a log-space search cannot reach 0): 1e-4/s moves a
    #: stuck force by under 3 % in a 300 s test
    RELAX_FLOOR_PER_S = 1e-4
    #: the search's narrowest pressure width (slip_kPa = 0, no pressure slip, is the user's to set)
    SLIP_FLOOR_KPA = 0.5

    def shape_range(self, ctx, p):
        if p.key == "relax_per_s":
            return self.RELAX_FLOOR_PER_S, p.grid, p.hi
        if p.discrete:  # a mode has no width for a noise floor to raise
            return super().shape_range(ctx, p)
        # a pre-sliding width below a few sensor-noise steps would let the play operator follow
        # the measured noise (and "explain" the noise the model inherits from its inputs)
        if p.key == "slip_kPa":
            lo = max(self.SLIP_FLOOR_KPA, 8.0 * ctx.pressure_noise_Pa / 1e3)
        else:
            lo = max(p.lo, 8.0 * ctx.strain_noise)
        grid = tuple(sorted({max(g, lo) for g in p.grid}))
        return lo, grid, max(p.hi, lo)

    def _design(self, ctx, shape):
        # the state depends on every shape parameter, so design()'s cache (per shape) holds it
        wx, wp, rate = shape["slip_strain"], shape["slip_kPa"] * 1e3, shape["relax_per_s"]
        slip = ctx.x / wx + (ctx.pressure_sign() * ctx.P / wp if wp > 0 else 0.0)
        z = play(slip, 1.0, ctx.starts, ctx.t, rate, smooth=shape.get("smooth", 0.0) == 1.0)
        return np.zeros(ctx.n), _gate(ctx, -np.column_stack([z, ctx.P_MPa * z]))

    def step(self, v, state, s: Sample) -> float:
        """One sample of the play operator on the slip; see :class:`Effect.step`."""
        if s.first:
            state[0] = 0.0
        slip = (s.L - s.L_prev) / s.muscle.rest_length_m / v["slip_strain"]
        if v["slip_kPa"] > 0:
            b2 = s.muscle.thread_length_m**2
            sign_now = -math.copysign(1.0, 3 * s.L**2 - b2)
            sign_prev = -math.copysign(1.0, 3 * s.L_prev**2 - b2)
            slip += (sign_now * s.P - sign_prev * s.P_prev) / (v["slip_kPa"] * 1e3)
        z = state[0] * math.exp(-v["relax_per_s"] * s.dt)
        if v.get("smooth", 0.0) == 1.0:
            state[0] = dahl_step(z, slip)
        else:
            state[0] = min(1.0, max(-1.0, z + slip))
        force = -(v["f0_N"] + v["f1_N_per_MPa"] * s.P / 1e6) * state[0]
        return force if s.engaged else 0.0


class Viscoelasticity(Effect):
    """Viscoelasticity: Maxwell branches. One on the strain (a stiffness that grows with pressure
    acting on x minus its lagged value); one on the bladder's own force, Fung's quasi-linear form
    (the share g of each change of the elastic force relaxes), which a pressure change moves at a
    fixed length as well: without it an isometric test's relaxation had no viscoelastic term to
    take it (a Zener solid on isometric ramps was answered `friction`), only friction's relaxing
    stuck force, a drift or a pressure lag. A second bladder branch relaxes ``SLOW_RATIO`` times
    slower (at most ``SLOW_MAX_S``): rubber relaxes over decades of time, not at one rate, and
    a spectrum that broad loads and unloads almost independently of the rate, as friction does.
    With one branch, relaxation spread over 0.4-160 s at fixed lengths was answered `friction`
    at p 0.86-0.96; two branches a decade and more apart span it (Prony series, as rubber's
    relaxation is fitted in practice), for one linear amplitude more."""

    #: the slow bladder branch's relaxation time over the fast one's, and its ceiling (s): a
    #: slower branch over a test of minutes is a drift, which the library names apart
    SLOW_RATIO = 20.0
    SLOW_MAX_S = 1000.0

    def __init__(self):
        super().__init__(
            name="viscoelasticity",
            summary="rate-dependent stiffness that relaxes during holds (Maxwell branches on the strain and the bladder)",
            equation=(
                "dF = -(k0 + k1 P_MPa) (x - w) + g (F_b - lag(F_b, tau)) + g_slow (F_b - lag(F_b, tau_slow)),  "
                "w = lag(x, tau),  tau_slow = min(20 tau, 1000 s)"
            ),
            params=(
                Param("k0_N", 0.0, 5000.0, meaning="Maxwell branch stiffness per unit strain"),
                Param("k1_N_per_MPa", 0.0, 10000.0, meaning="its growth with pressure"),
                Param(
                    "g_bladder",
                    0.0,
                    1.0,
                    meaning="share of a change of the bladder's force that relaxes (at any length)",
                    default=0.0,
                ),
                Param("tau_s", 0.1, 500.0, True, (0.5, 1.5, 4.0, 10.0, 25.0, 60.0, 150.0), "relaxation time"),
                Param(
                    "g_slow_bladder", 0.0, 1.0, meaning="share relaxing at 20 tau (<= 1000 s)", default=0.0
                ),
            ),
            state=("w", "b", "b_slow"),
            plugin="efam.muscle keys viscoelasticity.*; lag states on the strain and on the bladder's force (two)",
            signature="hysteresis that grows with the rate and relaxes during holds",
        )

    @classmethod
    def slow_tau(cls, tau_s: float) -> float:
        """The slow bladder branch's relaxation time (s) for a fast one of ``tau_s``."""
        return min(cls.SLOW_RATIO * tau_s, cls.SLOW_MAX_S)

    def _design(self, ctx, shape):
        tau = shape["tau_s"]
        d = ctx.x - lag(ctx.t, ctx.x, tau, ctx.starts)
        bladder = ctx.bladder_push()
        db = bladder - lag(ctx.t, bladder, tau, ctx.starts)
        db_slow = bladder - lag(ctx.t, bladder, self.slow_tau(tau), ctx.starts)
        return np.zeros(ctx.n), _gate(ctx, np.column_stack([-d, -ctx.P_MPa * d, db, db_slow]))

    def step(self, v, state, s: Sample) -> float:
        """One sample of the Maxwell branches; see :class:`Effect.step`."""
        bladder = s.bladder_push
        if s.first:
            state[0], state[1], state[2] = s.x, bladder, bladder
        else:
            a = 1.0 - math.exp(-s.dt / v["tau_s"])
            a_slow = 1.0 - math.exp(-s.dt / self.slow_tau(v["tau_s"]))
            state[0] += a * (s.x - state[0])
            state[1] += a * (bladder - state[1])
            state[2] += a_slow * (bladder - state[2])
        force = -(v["k0_N"] + v["k1_N_per_MPa"] * s.P / 1e6) * (s.x - state[0])
        force += v.get("g_bladder", 0.0) * (bladder - state[1])
        force += v.get("g_slow_bladder", 0.0) * (bladder - state[2])
        return force if s.engaged else 0.0


class EndEffects(Effect):
    """End effects: the fittings shorten the active length, a correction proportional to the length slope of the force."""

    def __init__(self):
        super().__init__(
            name="end_effects",
            summary="non-cylindrical ends near the fittings: the cylinder strains more than the "
            "muscle (Tondu's strain factor k = 1 + kappa, falling with pressure)",
            equation="dF = (kappa0 + kappa1 exp(-P/P_e)) (L - L_rest) dF/dL",
            params=(
                Param("kappa0", 0.0, 0.5, meaning="strain amplification at high pressure"),
                Param("kappa1", -0.5, 0.5, meaning="its excess at low pressure"),
                Param("P_e_kPa", 10.0, 1000.0, True, (30.0, 80.0, 200.0, 500.0), "pressure scale"),
            ),
            plugin="efam.muscle keys end_effects.*; stateless, evaluates the model at L +- h",
            signature="a static error growing with the stroke, changing with pressure",
        )

    def _design(self, ctx, shape):
        base = (ctx.L - ctx.muscle.rest_length_m) * ctx.dF_dL()
        decay = np.exp(-ctx.P / (shape["P_e_kPa"] * 1e3))
        return np.zeros(ctx.n), _gate(ctx, np.column_stack([base, decay * base]))

    def step(self, v, state, s: Sample) -> float:
        """One sample of the end-effect correction; see :class:`Effect.step`."""
        m = s.muscle
        h = 1e-6 * m.rest_length_m
        slope = (m.push(s.P, s.L + h) - m.push(s.P, s.L - h)) / (2 * h)
        kappa = v["kappa0"] + v["kappa1"] * math.exp(-s.P / (v["P_e_kPa"] * 1e3))
        force = kappa * (s.L - m.rest_length_m) * slope
        return force if s.engaged else 0.0


class BraidCompliance(Effect):
    """Braid compliance: threads that stretch with the hoop load P R_o, lengthening the thread length B."""

    def __init__(self):
        super().__init__(
            name="braid_compliance",
            summary="threads that stretch under their load (thread tension ~ hoop force ~ P R_o)",
            equation=(
                "dF = (b1 q + b2 q^2) [F(B (1 + s)) - F(B)] / s with s = 1 % (the secant per thread stretch),  "
                "q = max(P - P_db, 0)[MPa] R_o(L)/R_rest "
                "(the thread strain is b1 q + b2 q^2)"
            ),
            params=(
                Param("b1_per_MPa", 0.0, 0.2, meaning="thread strain per MPa of hoop load"),
                Param("b2_per_MPa2", -0.2, 0.2, meaning="its curvature (crimp, stiffening)"),
            ),
            plugin="efam.muscle keys braid_compliance.*; stateless, Eq. 2 with the thread length scaled by 1.01",
            signature="a static error growing with pressure, shaped like a braid-angle change",
        )

    @staticmethod
    def hoop_load(muscle: Muscle, P, L):
        """The threads' load q in MPa: gauge pressure above the dead band times the sleeve radius
        over its resting radius (one formula for the fit's columns and the replay's samples)."""
        return (
            np.maximum(P - muscle.deadband_Pa, 0.0)
            / 1e6
            * muscle.outer_radius(L)
            / muscle.rest_outer_radius_m
        )

    def _design(self, ctx, shape):
        q = self.hoop_load(ctx.muscle, ctx.P, ctx.L)
        d = ctx.braid_slope()
        return np.zeros(ctx.n), _gate(ctx, np.column_stack([q * d, q * q * d]))

    def fit_basis(self, ctx):
        """A thread does not shorten under more load: its strain b1 q + b2 q^2 is fitted as
        non-decreasing over the loads these data reach (0 <= q <= q_top). Written as
        k_c (2u - u^2) + k_x u^2 with u = q / q_top, both k >= 0 (every non-decreasing quadratic
        through zero on [0, q_top], and nothing else): b1 = 2 k_c / q_top, b2 = (k_x - k_c) / q_top^2.
        Without it, a quadratic that falls with the load (b1 0, b2 -0.2: threads shortening as the
        pressure rises) mimicked a pressure transducer's calibration error on the benchmark.
        The upper bounds keep b1 and b2 inside their own ranges."""
        return ctx.cached("braid_compliance.fit_basis", lambda: self._monotone_basis(ctx))

    def _monotone_basis(self, ctx):
        """:meth:`fit_basis` computed (the fit reads it twice: to build and to read back)."""
        q = self.hoop_load(ctx.muscle, ctx.P, ctx.L)[ctx.engaged]
        top = float(q.max()) if q.size else 0.0
        if top <= 1e-9:
            return None  # no load above the dead band: the columns are empty anyway
        T = np.array([[2.0 / top, 0.0], [-1.0 / top**2, 1.0 / top**2]])
        return T, np.zeros(2), np.array([min(0.1 * top, 0.2 * top * top), 0.2 * top * top])

    def step(self, v, state, s: Sample) -> float:
        """One sample of the braid-stretch correction; see :class:`Effect.step`."""
        m = s.muscle
        q = float(self.hoop_load(m, s.P, s.L))
        force = (v["b1_per_MPa"] * q + v["b2_per_MPa2"] * q * q) * float(braid_slope(m, s.P, s.L))
        return force if s.engaged else 0.0


class Softening(Effect):
    """Softening (Mullins effect): the bladder is stiffer on first loading to a new extreme than afterwards."""

    def __init__(self):
        super().__init__(
            name="softening",
            summary="Mullins effect: the bladder is stiffer on the first loading to a new extreme "
            "than on later ones",
            equation=(
                "dF = a h F_bladder(P, L),  h = exp(-(m - u)/width),  u = |x| (1 + P/0.5 MPa),  "
                "m = max u so far"
            ),
            params=(
                Param("a", 0.0, 1.0, meaning="extra bladder stiffness on the virgin curve (fraction)"),
                Param("width", 1e-3, 0.5, True, (0.005, 0.015, 0.04, 0.1, 0.25), "how fast it fades"),
            ),
            state=("m",),
            plugin="efam.muscle keys softening.*; 1 running-maximum state on the bladder part of Eq. 2",
            signature="the first cycle at each new pressure or strain carries extra force",
        )

    def _design(self, ctx, shape):
        u = np.abs(ctx.x) * (1.0 + ctx.P / 0.5e6)
        h = np.exp(-(running_max(u, ctx.starts) - u) / shape["width"])
        return np.zeros(ctx.n), _gate(ctx, (h * ctx.bladder_push())[:, None])

    def step(self, v, state, s: Sample) -> float:
        """One sample of the softening; see :class:`Effect.step`."""
        u = abs(s.x) * (1.0 + s.P / 0.5e6)
        state[0] = u if s.first else max(state[0], u)
        bladder = s.bladder_push
        force = v["a"] * math.exp(-(state[0] - u) / v["width"]) * bladder
        return force if s.engaged else 0.0


class Drift(Effect):
    """Drift: a force that builds up slowly (temperature, creep of the bladder or the set-up),
    depending on strain and pressure. Its clock is the time since the start, or the time spent
    under pressure (seconds at 1 MPa: rubber creeps under load, not while vented); its course
    saturates (a warm-up, primary creep), accelerates (a warming that is still building,
    tertiary creep) or grows as a logarithm of the clock (rubber's logarithmic creep, which no
    single time constant follows over decades)."""

    #: the clocks: wall time, or the pressure-time integral in seconds at 1 MPa
    WALL, PRESSURE = 0.0, 1.0
    #: the courses: saturating (1 - exp), accelerating (exp - 1) or logarithmic (log(1 + u/tau))
    SATURATING, ACCELERATING, LOGARITHMIC = 1.0, -1.0, 0.0
    #: an accelerating course's tau is at least the clock's span over this (its square stays
    #: finite in double precision: a numerical guard, not a physical bound)
    MAX_EXPONENT = 300.0

    def __init__(self):
        super().__init__(
            name="drift",
            summary="slow change over time or under load (temperature, creep of the bladder or set-up)",
            equation="dF = (d0 + d1 x + d2 P_MPa) s(u),  s = tau (1 - exp(-u/tau)) saturating, "
            "tau (exp(u/tau) - 1) accelerating or tau log(1 + u/tau) logarithmic;  u = t, or u = int P_MPa dt "
            "(time under pressure)",
            params=(
                Param("d0_N_per_s", -1.0, 1.0, meaning="initial drift rate of the force (per clock second)"),
                Param("d1_N_per_s", -10.0, 10.0, meaning="its growth with strain"),
                Param("d2_N_per_s_MPa", -10.0, 10.0, meaning="its growth with pressure"),
                Param(
                    "tau_s",
                    10.0,
                    1e6,
                    True,
                    (20.0, 100.0, 300.0, 1000.0, 3000.0, 1e5),
                    "time constant (clock seconds)",
                ),
                Param(
                    "clock",
                    0.0,
                    1.0,
                    True,
                    (0.0, 1.0),
                    "0: time since the start; 1: time under pressure (seconds at 1 MPa)",
                    default=0.0,
                    discrete=True,
                ),
                Param(
                    "course",
                    -1.0,
                    1.0,
                    True,
                    (1.0, -1.0, 0.0),
                    "1: saturating; -1: accelerating; 0: logarithmic",
                    default=1.0,
                    discrete=True,
                ),
            ),
            state=("u",),
            plugin="efam.muscle keys drift.*; state: the pressure clock (the wall clock is the time since the first step)",
            signature="a residual that changes steadily with time or with the load borne, across pressures and cycles",
        )

    @staticmethod
    def course(u, tau: float, course: float):
        """s(u): tau (1 - exp(-u/tau)) when saturating, tau (exp(u/tau) - 1) when accelerating,
        tau log(1 + u/tau) when logarithmic (all three start at slope 1)."""
        if course == Drift.ACCELERATING:
            return tau * np.expm1(u / tau)
        if course == Drift.LOGARITHMIC:
            return tau * np.log1p(u / tau)
        return tau * -np.expm1(-u / tau)

    def _clock(self, ctx, shape):
        return ctx.pressure_clock() if shape.get("clock", self.WALL) == self.PRESSURE else ctx.t

    def settle(self, ctx, shape):
        """An accelerating course's tau at least the clock's span / ``MAX_EXPONENT``."""
        out = dict(shape)
        if out.get("course", self.SATURATING) == self.ACCELERATING and ctx.n:
            out["tau_s"] = max(out["tau_s"], float(np.max(self._clock(ctx, out))) / self.MAX_EXPONENT)
        return out

    def _design(self, ctx, shape):
        s = self.course(self._clock(ctx, shape), shape["tau_s"], shape.get("course", self.SATURATING))
        return np.zeros(ctx.n), _gate(ctx, np.column_stack([s, ctx.x * s, ctx.P_MPa * s]))

    def step(self, v, state, s: Sample) -> float:
        """One sample of the drift; see :class:`Effect.step`."""
        if s.first:
            state[0] = 0.0
        else:
            state[0] += max(s.P, 0.0) / 1e6 * s.dt
        u = state[0] if v.get("clock", self.WALL) == self.PRESSURE else s.t
        ramp = float(self.course(u, v["tau_s"], v.get("course", self.SATURATING)))
        force = (v["d0_N_per_s"] + v["d1_N_per_s"] * s.x + v["d2_N_per_s_MPa"] * s.P / 1e6) * ramp
        return force if s.engaged else 0.0


class PressureLag(Effect):
    """Pressure lag: the internal pressure follows the measured one after a transport delay, through a
    first-order fill, less the pressure a change of the gas volume takes while the fill catches up.

    How much of the volume change shows depends on where the lag sits: all of it (``volume_gain``
    1, isothermal gas; up to 1.4 for a fast, adiabatic compression) when the lag is the flow into
    the muscle, none (0) when it is a transducer's or a regulator's filter with the muscle refilled
    at once. The gain weighs the force the volume term makes, so it enters linearly."""

    def __init__(self):
        super().__init__(
            name="pressure_lag",
            summary="the internal pressure lags the measured one (a line's transport delay, then valve, tube, gas volume)",
            equation=(
                "dF = F(P_l, L) - F(P, L) + k [F(P_l - G, L) - F(P_l, L)],  P_l = lag(P(t - d), tau), "
                "G = lag(tau (P + P_atm) dV/dt / V, tau), V = pi R_o(L)^2 L - V_B"
            ),
            params=(
                Param(
                    "tau_s", 0.002, 3.0, True, (0.01, 0.03, 0.08, 0.15, 0.3, 0.6, 1.2), "fill time constant"
                ),
                Param(
                    "delay_s",
                    0.0,
                    0.5,
                    True,
                    (DELAY_FLOOR_S, 0.03, 0.08, 0.2),  # the first: no delay (the floor, see delay_floor)
                    "transport delay of the line",
                    default=0.0,
                ),
                Param(
                    "volume_gain",
                    0.0,
                    1.5,
                    meaning="share of the gas-volume change's pressure drop that reaches the force",
                    default=1.0,
                ),
            ),
            state=("P_l", "G", "V_prev"),
            plugin=(
                "efam.muscle keys pressure_lag.tau_s, pressure_lag.delay_s and pressure_lag.volume_gain on an "
                "actuator with dyntype filterexact, dynprm = tau_s, actearly, and MuJoCo's own ctrl delay = "
                "delay_s (interp linear); 2 states for the gas-volume term"
            ),
            signature="force lagging pressure changes, and an error while the volume changes",
        )

    @staticmethod
    def delay_floor(ctx) -> float:
        """The smallest transport delay searched: one sample interval (at least a millisecond).
        MuJoCo's ctrl delay reads only earlier samples, so any delay up to one interval acts as a
        whole one; the floor therefore stands for no delay at all (see :meth:`settle`)."""
        return ctx.cached("delay_floor", lambda: max(DELAY_FLOOR_S, float(np.median(np.diff(ctx.t)))))

    def shape_range(self, ctx, p):
        # the search runs in log space, so "no delay" is its floor, written as exactly 0
        if p.key == "delay_s":
            floor = self.delay_floor(ctx)
            grid = (floor,) + tuple(g for g in p.grid if g > 1.5 * floor)
            return floor, grid, max(p.hi, 2.0 * floor)
        return p.lo, p.grid, p.hi

    def settle(self, ctx, shape):
        """A delay at (or, after refinement, within 5 % of) the floor is no delay: 0 exactly."""
        out = dict(shape)
        if out.get("delay_s", 0.0) <= 1.05 * self.delay_floor(ctx):
            out["delay_s"] = 0.0
        return out

    def _design(self, ctx, shape):
        tau, d = shape["tau_s"], shape.get("delay_s", 0.0)
        m = ctx.muscle
        V = ctx.cached("V", lambda: gas_volume(m, ctx.L))
        dVdt = ctx.cached("dV", lambda: backward_rate(ctx.t, V, ctx.starts))
        P_line = ctx.cached(("delayed_P", d), lambda: delayed(ctx.t, ctx.P, d, ctx.starts))
        P_l = lag(ctx.t, P_line, tau, ctx.starts)
        G = lag(ctx.t, tau * (ctx.P + P_ATM) * dVdt / V, tau, ctx.starts)
        lagged = m.push(P_l, ctx.L)
        volume = m.push(P_l - G, ctx.L) - lagged
        return _gate(ctx, lagged - ctx.base), _gate(ctx, volume[:, None])

    def initial_state(self) -> list:
        """The two lag states, the volume, and the pressure history the delay reads (times, values)."""
        return [0.0, 0.0, 0.0, [], []]

    def step(self, v, state, s: Sample) -> float:
        """One sample of the delayed, lagged internal pressure and the force change it makes; see :class:`Effect.step`."""
        m = s.muscle
        tau, d = v["tau_s"], v.get("delay_s", 0.0)
        V = float(gas_volume(m, s.L))
        times, values = state[3], state[4]
        if s.first:
            times.clear()
            values.clear()
        # the history as MuJoCo reads it: the samples before this one (the first: its own value)
        P_line = _interpolate(times, values, s.t - d) if d > 0 and times else s.P
        times.append(s.t)
        values.append(s.P)
        if s.first:
            state[0], state[1], state[2] = P_line, 0.0, V
            return 0.0
        g = tau * (s.P + P_ATM) * (V - state[2]) / max(s.dt, 1e-12) / V
        alpha = 1.0 - math.exp(-s.dt / tau)
        state[0] += alpha * (P_line - state[0])
        state[1] += alpha * (g - state[1])
        state[2] = V
        lagged = m.push(state[0], s.L)
        force = (
            lagged
            + v.get("volume_gain", 1.0) * (m.push(state[0] - state[1], s.L) - lagged)
            - m.push(s.P, s.L)
        )
        return force if s.engaged else 0.0


def _interpolate(times: list, values: list, at: float) -> float:
    """Linear interpolation in a growing history (MuJoCo's ``interp="linear"`` ctrl delay); before
    its first sample the first value, after its last the last."""
    k = bisect.bisect_right(times, at)
    if k == 0:
        return values[0]
    if k >= len(times):
        return values[-1]
    t0, t1 = times[k - 1], times[k]
    w = (at - t0) / (t1 - t0) if t1 > t0 else 1.0
    return values[k - 1] + w * (values[k] - values[k - 1])


class ForceOffset(Effect):
    """Force offset: the load cell's zero error, one constant per recording."""

    def __init__(self):
        super().__init__(
            name="force_offset",
            summary="load-cell zero error (a sensor effect, not a muscle force)",
            equation="dF = c",
            params=(Param("offset_N", -100.0, 100.0, meaning="load-cell reading at zero force"),),
            plugin="not an actuator force: add it to the simulated load-cell reading",
            signature="a constant residual, visible where the model force is zero",
            per_recording=True,  # a load cell is zeroed (or not) before each test
        )

    def _design(self, ctx, shape):
        cols = np.zeros((ctx.n, len(ctx.starts)))
        for r, (b, e) in enumerate(segments(ctx.starts, ctx.n)):
            cols[b:e, r] = 1.0
        return np.zeros(ctx.n), cols

    def step(self, v, state, s: Sample) -> float:
        """The constant offset (N); see :class:`Effect.step`."""
        return v["offset_N"]


LIBRARY: dict[str, Effect] = {
    e.name: e
    for e in (
        Friction(), Viscoelasticity(), EndEffects(), BraidCompliance(), Softening(), Drift(),
        PressureLag(), ForceOffset(),
    )
}  # fmt: skip
EFFECT_NAMES = tuple(LIBRARY)


def get(name: str) -> Effect:
    """The library effect called ``name``; an unknown name is a ValueError listing the known ones."""
    if name not in LIBRARY:
        raise ValueError(f"unknown effect '{name}' (known: {', '.join(EFFECT_NAMES)})")
    return LIBRARY[name]


def check_values(name: str, values: dict) -> dict[str, float]:
    """Every parameter of the effect present, numeric, inside its bounds (a clear error if not)."""
    effect = get(name)
    out = {}
    for p in effect.params:
        if p.key not in values and p.default is not None:
            out[p.key] = float(p.default)
            continue
        if p.key not in values:
            raise ValueError(f"effect '{name}': missing parameter '{p.key}'")
        v = values[p.key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"effect '{name}': parameter '{p.key}' must be a finite number, got {v!r}")
        if not p.lo <= v <= p.hi:
            raise ValueError(
                f"effect '{name}': parameter '{p.key}' = {v:.10g} is outside [{p.lo:g}, {p.hi:g}]"
            )
        if p.discrete and v not in p.grid:
            choices = ", ".join(f"{g:g}" for g in sorted(p.grid))
            raise ValueError(
                f"effect '{name}': parameter '{p.key}' = {v:g} is not one of {choices} ({p.meaning})"
            )
        out[p.key] = float(v)
    if effect.per_recording and f"{effect.linear[0].key}_by_recording" in values:
        per = values[f"{effect.linear[0].key}_by_recording"]
        if not isinstance(per, (list, tuple)) or not all(isinstance(v, (int, float)) for v in per):
            raise ValueError(
                f"effect '{name}': '{effect.linear[0].key}_by_recording' must be a list of numbers"
            )
        out[f"{effect.linear[0].key}_by_recording"] = [float(v) for v in per]
    unknown = sorted(set(values) - set(out))
    if unknown:
        raise ValueError(f"effect '{name}': unknown parameter '{unknown[0]}'")
    return out


# ------------------------------------------------------------------------- switching on
@dataclass
class EffectModel:
    """A muscle with identified effects switched on: the Python path of the plugin's effects.

    ``effects`` is a list of (name, parameters). :meth:`push` replays a recording's length and
    pressure (vectorised); :meth:`push_stepwise` runs the per-sample reference a plugin runs.
    """

    muscle: Muscle
    effects: list[tuple[str, dict]] = field(default_factory=list)

    def __post_init__(self):
        self.effects = [(name, check_values(name, values)) for name, values in self.effects]

    def push(self, time_s, length_m, pressure_Pa) -> np.ndarray:
        """Push force (N, MuJoCo sign) of the muscle with its effects for one recording's arrays (vectorised)."""
        ctx = Context(np.asarray(time_s) - time_s[0], length_m, pressure_Pa, [0], self.muscle)
        return ctx.base + sum((get(n).force(ctx, v) for n, v in self.effects), np.zeros(ctx.n))

    def push_recording(self, recording: Recording) -> np.ndarray:
        """Push force (N) of the muscle with its effects over ``recording``."""
        return self.push(recording.time_s, recording.length_m, recording.pressure_Pa)

    def push_stepwise(self, time_s, length_m, pressure_Pa) -> np.ndarray:
        """Push force (N) computed sample by sample with each effect's state, as the C plugin does."""
        states = [get(n).initial_state() for n, _ in self.effects]
        out = np.empty(len(time_s))
        t0 = float(time_s[0])
        for k in range(len(time_s)):
            s = Sample(
                t=float(time_s[k]) - t0, P=float(pressure_Pa[k]), L=float(length_m[k]),
                P_prev=float(pressure_Pa[k - 1] if k else pressure_Pa[0]),
                L_prev=float(length_m[k - 1] if k else length_m[0]),
                dt=float(time_s[k] - time_s[k - 1]) if k else 0.0, first=k == 0, muscle=self.muscle,
            )  # fmt: skip
            force = float(self.muscle.push(s.P, s.L))
            for (name, values), state in zip(self.effects, states):
                force += get(name).step(values, state, s)
            out[k] = force
        return out


def apply(recording: Recording, muscle: Muscle, effects: list[tuple[str, dict]]) -> np.ndarray:
    """Push force (N) the muscle with ``effects`` switched on gives for a recording's L and P."""
    return EffectModel(muscle, effects).push_recording(recording)
