"""An unnamed, data-driven correction for what the library leaves: sparse regression on features.

When structured residual remains above the noise after the best library terms, a correction
that no physical name is given to may still predict it. The features are generic functions of
the states and their histories (``features``): radial bumps over the strain and over the
pressure (each also scaled by the other; for the reported correction also by the model's own
sensitivity to that input: an error of a measured input as a function of its value), the rates and their saturated signs (direction), the
strain's acceleration and its resonances (the acceleration through lightly damped second-order
filters at 2-64 Hz, in phase and in quadrature: a load cell or fixture that rings when the
carriage accelerates), the strain and the pressure less their first-order lags at time constants
from 0.05 to 30 s (memory; for the reported correction the pressure's also scaled by the model's sensitivity
to it), the time, and the distance below the running maximum of the loading
(first-loading memory). Every column is causal, as a simulation step could compute it.

The correction is fitted jointly with the model's parameter corrections and the library terms
kept (``Engine`` normal equations): forward stepwise selection (orthogonal matching pursuit) on
each fold's TRAINING folds alone, the number of features (at most ``MAX_TERMS``) chosen by an
inner cross-validation over those training folds (the fewest within ``MIN_STEP`` of the best);
the held-out RMS pools the folds. The held-out data
choose nothing: not the features, not their number, not their coefficients. The result is reported
as data-driven, never under a physical name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.signal import bilinear, lfilter

from .effects import Context, get, lag, segments
from .select import Engine, Fit

MAX_TERMS = 10
MIN_STEP = 0.01
RIDGE = 0.02  # of a feature's mean Gram diagonal: shrinks a well-seen feature by ~2 %
#: natural frequencies (Hz) of the resonance features: a rig's load cell and fixture ring above the
#: strokes' own frequencies. Half an octave apart with damping 0.2, a ring between two is taken up
#: by the pair: a 6 Hz ring of damping 0.1 after each stroke reversal, R^2 0.73 of the 0.8 its
#: noise leaves (an octave apart at damping 0.3: 0.56; a sixth of an octave at 0.1: 0.75)
RESONANCE_HZ = tuple(2.0 * 2.0 ** (k / 2) for k in range(11))  # 2 to 64 Hz
RESONANCE_DAMPING = 0.2
RESONANCE_NYQUIST_SHARE = 1.0 / 6.0  # a filter is built only below this share of the sample rate


@dataclass
class Correction:
    """The data-driven correction on top of a model: held-out RMS before and after, its terms."""

    heldout_rms_before_N: float
    heldout_rms_after_N: float
    terms: list[str]  # selected on all data (the per-fold choices are in ``fold_terms``)
    coefficients_N: list[float]
    fold_terms: list[list[str]] = field(default_factory=list)
    prediction: np.ndarray | None = field(default=None, repr=False)  # in-sample, N
    spec: dict | None = field(default=None, repr=False)  # rebuilds the features on other data
    #: held-out residual per sample (N, sample order) of the model before and after the
    #: correction, each fold fitted without it: the paired test of ``confidence`` reads them
    heldout_residual_before: np.ndarray | None = field(default=None, repr=False)
    heldout_residual_after: np.ndarray | None = field(default=None, repr=False)
    #: the held-out gain the correction reached before the report's check (negative: it
    #: predicted unseen data worse than the model alone, so it is not reported)
    raw_gain: float = 0.0

    def _selected(self, ctx: Context) -> list[tuple[np.ndarray, float]]:
        """The selected features rebuilt on ``ctx`` (with the centres and scales of the data
        they were fitted on), each with its coefficient; a term the new data cannot build is
        left out."""
        if not self.terms:
            return []
        X, names, _ = features(ctx, self.spec)
        index = {n: i for i, n in enumerate(names)}
        return [(X[:, index[t]], c) for t, c in zip(self.terms, self.coefficients_N) if t in index]

    def predict(self, ctx: Context) -> np.ndarray:
        """The correction (N, push sign) on other data, e.g. a proposed experiment."""
        return sum((c * x for x, c in self._selected(ctx)), np.zeros(ctx.n))

    def columns(self, ctx: Context) -> np.ndarray:
        """The selected features on other data (n x terms), each free to take another amplitude:
        what a re-fit of the correction could make there."""
        picked = [x for x, _ in self._selected(ctx)]
        return np.column_stack(picked) if picked else np.zeros((ctx.n, 0))

    @property
    def gain(self) -> float:
        """Fraction of the held-out RMS that the correction removes (0 when there was nothing to remove)."""
        b = self.heldout_rms_before_N
        return 1.0 - self.heldout_rms_after_N / b if b > 0 else 0.0

    def to_json(self) -> dict:
        """The correction's summary as plain JSON types."""
        return {
            "heldout_rms_before_N": self.heldout_rms_before_N,
            "heldout_rms_after_N": self.heldout_rms_after_N, "heldout_gain": self.gain,
            "terms": self.terms, "coefficients_N": self.coefficients_N, "fold_terms": self.fold_terms,
            "note": "data-driven (unnamed): sparse regression on features of the states and their "
            "histories; no physical meaning is claimed",
        }  # fmt: skip


@dataclass
class Corrected:
    """A model with the data-driven correction added: something the next-experiment design can
    simulate as the 'outside the library' hypothesis (``push`` like ``EffectModel.push``)."""

    model: object  # an EffectModel
    correction: Correction

    def push(self, time_s, length_m, pressure_Pa) -> np.ndarray:
        """Push force (N, MuJoCo sign) of the named model plus the data-driven correction for a new test."""
        ctx = Context(np.asarray(time_s) - time_s[0], length_m, pressure_Pa, [0], self.model.muscle)
        return self.model.push(time_s, length_m, pressure_Pa) + self.correction.predict(ctx)


def _bumps(u, count, given=None):
    """Gaussian bumps over ``u``: centres spread over its 1-99 % range (or ``given`` centres)."""
    if given is None:
        lo, hi = float(np.percentile(u, 1)), float(np.percentile(u, 99))
        if hi - lo < 1e-12:
            return [], [], (np.array([]), 1.0)
        given = (np.linspace(lo, hi, count), (hi - lo) / (count - 1))
    centres, width = given
    return [np.exp(-(((u - c) / width) ** 2)) for c in centres], [f"{c:.3g}" for c in centres], given


def _resonance(x: np.ndarray, step_s: float, hz: float, quadrature: bool) -> np.ndarray:
    """``x`` (one recording, from its first sample) through a second-order resonance at ``hz``
    driven by its acceleration: wn^2 s^2 / (s^2 + 2 zeta wn s + wn^2) (``quadrature``: wn^3 s /
    (...), the same ring a quarter period on), discretised by Tustin's rule at the recording's
    median time step ``step_s``. Filtering the strain itself, not a twice-differentiated one,
    keeps the sensor's noise flat: the filter tends to wn^2 x far above the resonance."""
    fs = 1.0 / step_s
    wn = 2.0 * math.pi * hz
    num = [0.0, wn**3, 0.0] if quadrature else [wn**2, 0.0, 0.0]
    bz, az = bilinear(num, [1.0, 2.0 * RESONANCE_DAMPING * wn, wn * wn], fs)
    return lfilter(bz, az, x - x[0])


def _by_recording(ctx, fn):
    out = np.zeros(ctx.n)
    for s0, s1 in segments(ctx.starts, ctx.n):
        if s1 - s0 > 2:
            out[s0:s1] = fn(slice(s0, s1))
    return out


def _resonances_built(ctx) -> list[float]:
    """The resonance frequencies these data can carry: below ``RESONANCE_NYQUIST_SHARE`` of the
    slowest recording's sample rate."""
    steps = [step for s0, s1, step in ctx.recording_steps() if s1 - s0 > 2]
    fs = 1.0 / max(steps) if steps else 0.0
    return [hz for hz in RESONANCE_HZ if hz <= RESONANCE_NYQUIST_SHARE * fs]


def features(
    ctx: Context, spec: dict | None = None, sensitivity: bool = False
) -> tuple[np.ndarray, list[str], dict]:
    """Causal feature columns (n x m) and their names, each scaled to unit RMS over the data it
    was first built on; ``spec`` (returned) rebuilds the same columns on other data (a new
    protocol), with the same centres, scales and order. ``sensitivity``: also the input-error
    columns (bumps and pressure histories times the model's sensitivity to that input)."""
    fit = spec is None
    spec = {"rms": {}, "sensitivity": sensitivity} if fit else spec
    sensitivity = spec.get("sensitivity", False)
    x, P, t = ctx.x, ctx.P_MPa, ctx.t
    if fit:
        spec["p_top"] = max(float(np.percentile(P, 99)), 1e-3)
        spec["t_max"] = max(float(t.max()), 1e-9)
    p = P / spec["p_top"]
    cols, names = [], []

    def add(col, name):
        col = np.asarray(col, dtype=float)
        if fit:
            rms = math.sqrt(float(np.mean(col * col)))
            if not (rms > 1e-12 and np.isfinite(rms)):
                return
            spec["rms"][name] = rms
        elif name not in spec["rms"]:
            return
        cols.append(col / spec["rms"][name])
        names.append(name)

    # the model's own sensitivities: an error in a measured input (a transducer's nonlinearity,
    # a gas pressure above the supply's) moves the force by the sensitivity times that error
    dF_dP, dF_dL = (ctx.dF_dP(), ctx.dF_dL()) if sensitivity else (None, None)
    bx, cx, spec["bx"] = _bumps(x, 8, spec.get("bx"))
    for b, c in zip(bx, cx):
        add(b, f"bump(strain @ {c})")
        add(b * p, f"bump(strain @ {c}) * P")
        if sensitivity:
            add(b * dF_dL, f"bump(strain @ {c}) * dF/dL")
    bp, cp, spec["bp"] = _bumps(P, 8, spec.get("bp"))
    for b, c in zip(bp, cp):
        add(b, f"bump(P @ {c} MPa)")
        add(b * x, f"bump(P @ {c} MPa) * strain")
        if sensitivity:
            add(b * dF_dP, f"bump(P @ {c} MPa) * dF/dP")
    for name, u in (("strain", x), ("P", p)):
        rate = _by_recording(ctx, lambda s, u=u: np.gradient(lag(t[s], u[s], 0.1), t[s]))
        if fit:
            spec[f"typical_{name}"] = float(np.percentile(np.abs(rate), 90)) + 1e-12
        typical = spec[f"typical_{name}"]
        add(rate, f"d{name}/dt")
        add(rate * p, f"d{name}/dt * P")
        add(np.tanh(rate / (0.2 * typical)), f"sign(d{name}/dt)")
        add(np.tanh(rate / (0.2 * typical)) * p, f"sign(d{name}/dt) * P")
        if name == "strain":
            add(_by_recording(ctx, lambda s, rate=rate: np.gradient(rate[s], t[s])), "d2strain/dt2")
            # (on other data, a filter those data cannot carry is not built: the term is left out)
            for hz in _resonances_built(ctx):
                for quadrature in (False, True):
                    ring = np.zeros(ctx.n)
                    for s0, s1, step in ctx.recording_steps():
                        if s1 - s0 > 2:
                            ring[s0:s1] = _resonance(x[s0:s1], step, hz, quadrature)
                    add(ring, f"resonance({hz:.3g} Hz) of {'dstrain/dt' if quadrature else 'd2strain/dt2'}")
        for tau in (0.05, 0.3, 3.0, 30.0):
            if name == "strain" and tau < 0.3:
                continue
            d = u - lag(t, u, tau, ctx.starts)
            other = "P" if name == "strain" else "strain"
            add(d, f"{name} - lag({name}, {tau:g} s)")
            add(d * (p if name == "strain" else x), f"({name} - lag({name}, {tau:g} s)) * {other}")
            if name == "P" and sensitivity:
                add(d * dF_dP, f"(P - lag(P, {tau:g} s)) * dF/dP")
    add(t / spec["t_max"], "time")
    add((t / spec["t_max"]) ** 2, "time^2")
    load = np.abs(x) * (1 + p)
    peak = _by_recording(ctx, lambda s: np.maximum.accumulate(load[s]))
    if fit:
        spec["load_scale"] = max(0.05 * float(np.ptp(load)), 1e-9)
    add(np.exp(-(peak - load) / spec["load_scale"]), "first-loading memory")
    X = np.column_stack(cols) * ctx.engaged[:, None] if cols else np.zeros((ctx.n, 0))
    return X, names, spec


def _path(G, b, yy, k0: int, max_terms: int) -> list[tuple[list[int], np.ndarray]]:
    """Orthogonal matching pursuit on normal equations: the model's columns (0..k0-1) always in,
    then the feature that lowers the residual sum of squares most, one at a time. Returns
    [(column indices, coefficients)] for 0..max_terms features (least squares, a tiny ridge)."""
    ridge_all = RIDGE * float(np.mean(np.diag(G))) + 1e-300
    idx = list(range(k0))
    out = []
    m = G.shape[0]
    for _ in range(max_terms + 1):
        # a ridge on the features (unit RMS over the whole test): a feature whose training data
        # are few (a bump where the training folds hardly go) stays small where it is unseen
        Ga = (
            G[np.ix_(idx, idx)]
            + ridge_all * np.diag([0.0 if i < k0 else 1.0 for i in idx])
            + 1e-10 * ridge_all * np.eye(len(idx))
        )
        try:
            c = cho_factor(Ga)
        except np.linalg.LinAlgError:
            break
        theta = cho_solve(c, b[idx])
        out.append((list(idx), theta))
        rest = [j for j in range(k0, m) if j not in idx]
        if len(out) > max_terms or not rest:
            break
        Gra = G[np.ix_(rest, idx)]
        r = b[rest] - Gra @ theta
        d = np.diag(G)[rest] - np.einsum("ij,ji->i", Gra, cho_solve(c, Gra.T))
        gain = r * r / (np.maximum(d, 0.0) + ridge_all)
        idx = idx + [rest[int(np.argmax(gain))]]
    return out


def _rss(G, b, yy, idx, theta) -> float:
    Ga = G[np.ix_(idx, idx)]
    return float(yy - 2 * theta @ b[idx] + theta @ Ga @ theta)


def correction(engine: Engine, fit: Fit, sensitivity: bool = False) -> Correction:
    """The data-driven correction on top of ``fit`` (the model with its kept library terms);
    ``sensitivity``: with the input-error features too (``features``).

    For each held-out fold, the model's parameter corrections and the kept terms are fitted on the
    training folds only (bounded, as in ``select``); the features are then fitted to that model's
    residual on the same training folds, their number chosen by an inner leave-one-fold-out over
    those training folds (the fewest within ``MIN_STEP`` of the best inner error); the held-out
    fold scores both, before and after the correction."""
    effects = [get(name) for name in fit.names]
    shapes = [fit.shapes[name] for name in fit.names]
    fixed, C, clo, chi, owner = engine._design(effects, shapes)
    Xf, names, spec = engine.ctx.cached(
        ("dd_features", sensitivity), lambda: features(engine.ctx, sensitivity=sensitivity)
    )
    X = Xf[engine.order]
    A0 = np.hstack([engine.Jn, C])
    lo = np.r_[engine.jlo * engine.Jscale, clo]
    hi = np.r_[engine.jhi * engine.Jscale, chi]
    y = engine.y - fixed
    G0, b0, _ = engine._blocks(A0, y)
    GX = np.stack([X[s].T @ X[s] for s in engine.slices])
    K = len(engine.slices)

    def residual_blocks(theta):
        r = y - A0 @ theta
        return np.stack([X[s].T @ r[s] for s in engine.slices]), np.array(
            [r[s] @ r[s] for s in engine.slices]
        )

    def choose(train: list[int], bX, rr) -> int:
        """Number of features by leave-one-fold-out inside ``train``: the fewest within
        ``MIN_STEP`` of the best inner error. (A ridge grid 0.02, 0.3, 3 chosen here too
        changed no held-out gain on the bench's failures: the ridge stays ``RIDGE``.)"""
        err = np.zeros(MAX_TERMS + 1)
        for j in train:
            inner = [i for i in train if i != j]
            path = _path(GX[inner].sum(0), bX[inner].sum(0), rr[inner].sum(), 0, MAX_TERMS)
            for m in range(MAX_TERMS + 1):
                idx, th = path[min(m, len(path) - 1)]
                err[m] += _rss(GX[j], bX[j], rr[j], idx, th)
        best = float(err.min())
        return int(np.flatnonzero(err <= best * (1.0 + MIN_STEP))[0])

    before = after = 0.0
    fold_terms = []
    res_before = np.zeros(engine.n)
    res_after = np.zeros(engine.n)
    if K > 2:
        for k in range(K):
            train = [i for i in range(K) if i != k]
            theta = engine._solve(G0[train].sum(0), b0[train].sum(0), lo, hi)
            theta = engine._fill_unseen(theta, G0[train].sum(0), owner, engine.Jn.shape[1])
            bX, rr = residual_blocks(theta)
            m = choose(train, bX, rr)
            idx, th = _path(GX[train].sum(0), bX[train].sum(0), rr[train].sum(), 0, m)[-1]
            before += rr[k]
            after += _rss(GX[k], bX[k], rr[k], idx, th)
            fold_terms.append([names[j] for j in idx])
            s = engine.slices[k]
            res_before[s] = y[s] - A0[s] @ theta
            res_after[s] = res_before[s] - (X[s][:, idx] @ th if idx else 0.0)
    theta = engine._solve(G0.sum(0), b0.sum(0), lo, hi)
    bX, rr = residual_blocks(theta)
    m = choose(list(range(K)), bX, rr) if K > 2 else 0
    active, coef = _path(GX.sum(0), bX.sum(0), rr.sum(), 0, m)[-1]
    dd = np.zeros(engine.n)
    if active:
        dd[engine.order] = X[:, active] @ coef
    rms_before = math.sqrt(before / engine.n) if fold_terms else fit.heldout_rms
    rms_after = math.sqrt(after / engine.n) if fold_terms else fit.heldout_rms
    raw_gain = 1.0 - rms_after / rms_before if rms_before > 0 else 0.0
    held_before = np.empty(engine.n)
    held_before[engine.order] = res_before
    held_after = np.empty(engine.n)
    held_after[engine.order] = res_after
    if not fold_terms or rms_after >= rms_before:
        # reported only when it predicts unseen data better than the model alone: a correction
        # that extrapolates badly where its training folds never went is no correction
        return Correction(
            heldout_rms_before_N=rms_before, heldout_rms_after_N=rms_before, terms=[], coefficients_N=[],
            fold_terms=fold_terms, prediction=np.zeros(engine.n), spec=spec,
            heldout_residual_before=held_before if fold_terms else None,
            heldout_residual_after=held_before if fold_terms else None, raw_gain=raw_gain,
        )  # fmt: skip
    return Correction(
        heldout_rms_before_N=rms_before, heldout_rms_after_N=rms_after,
        terms=[names[j] for j in active], coefficients_N=[float(c) for c in coef],
        fold_terms=fold_terms, prediction=dd, spec=spec,
        heldout_residual_before=held_before, heldout_residual_after=held_after, raw_gain=raw_gain,
    )  # fmt: skip
