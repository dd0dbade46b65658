"""An unnamed, data-driven correction for what the library leaves: sparse regression on features.

When structured residual remains above the noise after the best library terms, a correction
that no physical name is given to may still predict it. The features are generic functions of
the states and their histories (``features``): radial bumps over the strain and over the
pressure (each also scaled by the other), the rates and their saturated signs (direction), the
strain's acceleration, the strain and the pressure less their first-order lags at time constants
from 0.05 to 30 s (memory), the time, and the distance below the running maximum of the loading
(first-loading memory). Every column is causal, as a simulation step could compute it.

The correction is fitted jointly with the model's parameter corrections and the library terms
kept (``Engine`` normal equations): forward stepwise selection (orthogonal matching pursuit) on
each fold's TRAINING blocks alone, a feature added while it lowers the training error by at least
``MIN_STEP`` of it, at most ``MAX_TERMS``; the held-out RMS pools the folds. The held-out data
choose nothing: not the features, not their number, not their coefficients. The result is reported
as data-driven, never under a physical name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .effects import Context, get, lag
from .select import Engine, Fit

MAX_TERMS = 10
MIN_STEP = 0.01


@dataclass
class Correction:
    """The data-driven correction on top of a model: held-out RMS before and after, its terms."""

    heldout_rms_before_N: float
    heldout_rms_after_N: float
    terms: list[str]  # selected on all data (the per-fold choices are in ``fold_terms``)
    coefficients_N: list[float]
    fold_terms: list[list[str]] = field(default_factory=list)
    prediction: np.ndarray | None = field(default=None, repr=False)  # in-sample, N

    @property
    def gain(self) -> float:
        b = self.heldout_rms_before_N
        return 1.0 - self.heldout_rms_after_N / b if b > 0 else 0.0

    def to_json(self) -> dict:
        return {
            "heldout_rms_before_N": self.heldout_rms_before_N,
            "heldout_rms_after_N": self.heldout_rms_after_N, "heldout_gain": self.gain,
            "terms": self.terms, "coefficients_N": self.coefficients_N, "fold_terms": self.fold_terms,
            "note": "data-driven (unnamed): sparse regression on features of the states and their "
            "histories; no physical meaning is claimed",
        }  # fmt: skip


def _bumps(u, count):
    lo, hi = float(np.percentile(u, 1)), float(np.percentile(u, 99))
    if hi - lo < 1e-12:
        return [], []
    centres = np.linspace(lo, hi, count)
    width = (hi - lo) / (count - 1)
    return [np.exp(-(((u - c) / width) ** 2)) for c in centres], [f"{c:.3g}" for c in centres]


def features(ctx: Context) -> tuple[np.ndarray, list[str]]:
    """Causal feature columns (n x m, each scaled to unit RMS) and their names."""
    x, P = ctx.x, ctx.P_MPa
    p_top = max(float(np.percentile(P, 99)), 1e-3)
    p = P / p_top
    cols, names = [], []

    def add(col, name):
        col = np.asarray(col, dtype=float)
        rms = math.sqrt(float(np.mean(col * col)))
        if rms > 1e-12 and np.isfinite(rms):
            cols.append(col / rms)
            names.append(name)

    bx, cx = _bumps(x, 8)
    for b, c in zip(bx, cx):
        add(b, f"bump(strain @ {c})")
        add(b * p, f"bump(strain @ {c}) * P")
    bp, cp = _bumps(P, 8)
    for b, c in zip(bp, cp):
        add(b, f"bump(P @ {c} MPa)")
        add(b * x, f"bump(P @ {c} MPa) * strain")
    t = ctx.t
    for name, u, scale in (("strain", x, max(np.ptp(x), 1e-6)), ("P", p, 1.0)):
        rate = np.zeros(ctx.n)
        for s0, s1 in zip(ctx.starts, list(ctx.starts[1:]) + [ctx.n]):
            if s1 - s0 > 2:
                rate[s0:s1] = np.gradient(lag(t[s0:s1], u[s0:s1], 0.1), t[s0:s1])
        typical = float(np.percentile(np.abs(rate), 90)) + 1e-12
        add(rate, f"d{name}/dt")
        add(rate * p, f"d{name}/dt * P")
        add(np.tanh(rate / (0.2 * typical)), f"sign(d{name}/dt)")
        add(np.tanh(rate / (0.2 * typical)) * p, f"sign(d{name}/dt) * P")
        if name == "strain":
            acc = np.zeros(ctx.n)
            for s0, s1 in zip(ctx.starts, list(ctx.starts[1:]) + [ctx.n]):
                if s1 - s0 > 2:
                    acc[s0:s1] = np.gradient(rate[s0:s1], t[s0:s1])
            add(acc, "d2strain/dt2")
        for tau in (0.05, 0.3, 3.0, 30.0):
            if name == "strain" and tau < 0.3:
                continue
            d = u - lag(t, u, tau, ctx.starts)
            add(d, f"{name} - lag({name}, {tau:g} s)")
            add(d * (p if name == "strain" else x), f"({name} - lag({name}, {tau:g} s)) * {'P' if name == 'strain' else 'strain'}")
        del scale
    add(t / max(t.max(), 1e-9), "time")
    add((t / max(t.max(), 1e-9)) ** 2, "time^2")
    load = np.abs(x) * (1 + p)
    peak = np.zeros(ctx.n)
    for s0, s1 in zip(ctx.starts, list(ctx.starts[1:]) + [ctx.n]):
        peak[s0:s1] = np.maximum.accumulate(load[s0:s1])
    add(np.exp(-(peak - load) / max(0.05 * np.ptp(load), 1e-9)), "first-loading memory")
    return np.column_stack(cols) * ctx.engaged[:, None], names


def correction(engine: Engine, fit: Fit) -> Correction:
    """The data-driven correction on top of ``fit`` (the model with its kept library terms)."""
    effects = [get(name) for name in fit.names]
    shapes = [fit.shapes[name] for name in fit.names]
    fixed, C, clo, chi, _ = engine._design(effects, shapes)
    Xf, names = engine.ctx.cached("dd_features", lambda: features(engine.ctx))
    X = Xf[engine.order]
    A0 = np.hstack([engine.Jn, C])
    lo0 = np.r_[engine.jlo * engine.Jscale, clo]
    hi0 = np.r_[engine.jhi * engine.Jscale, chi]
    A = np.hstack([A0, X])
    y = engine.y - fixed
    G, b, yy = engine._blocks(A, y)
    k0 = A0.shape[1]
    lo = np.r_[lo0, np.full(X.shape[1], -np.inf)]
    hi = np.r_[hi0, np.full(X.shape[1], np.inf)]

    def select(Gt, bt, yyt):
        active: list[int] = []
        idx = list(range(k0))
        theta = engine._solve(Gt[np.ix_(idx, idx)], bt[idx], lo[idx], hi[idx])
        rss = engine._rss(Gt[np.ix_(idx, idx)], bt[idx], yyt, theta)
        while len(active) < MAX_TERMS:
            best = None
            for j in range(X.shape[1]):
                if j in active:
                    continue
                trial = idx + [k0 + j]
                th = engine._solve(Gt[np.ix_(trial, trial)], bt[trial], lo[trial], hi[trial])
                r = engine._rss(Gt[np.ix_(trial, trial)], bt[trial], yyt, th)
                if best is None or r < best[0]:
                    best = (r, j, th)
            if best is None or best[0] > (1.0 - MIN_STEP) * rss:
                break
            rss, j, theta = best
            active.append(j)
            idx = idx + [k0 + j]
        return idx, theta, active

    Gt, bt, yyt = G.sum(0), b.sum(0), yy.sum()
    heldout_before = heldout_after = 0.0
    fold_terms = []
    base = list(range(k0))
    if len(engine.slices) > 1:
        for k in range(len(engine.slices)):
            Gk, bk = Gt - G[k], bt - b[k]
            th0 = engine._solve(Gk[np.ix_(base, base)], bk[base], lo[base], hi[base])
            heldout_before += engine._rss(G[k][np.ix_(base, base)], b[k][base], yy[k], th0)
            idx, theta, active = select(Gk, bk, yyt - yy[k])
            heldout_after += engine._rss(G[k][np.ix_(idx, idx)], b[k][idx], yy[k], theta)
            fold_terms.append([names[j] for j in active])
    idx, theta, active = select(Gt, bt, yyt)
    dd = np.zeros(engine.n)
    if active:
        dd_sorted = X[:, active] @ theta[k0:]
        dd[engine.order] = dd_sorted
    coef = [float(c) for c in theta[k0:]]  # N per unit-RMS feature
    return Correction(
        heldout_rms_before_N=math.sqrt(heldout_before / engine.n) if fold_terms else fit.heldout_rms,
        heldout_rms_after_N=math.sqrt(heldout_after / engine.n) if fold_terms else fit.heldout_rms,
        terms=[names[j] for j in active], coefficients_N=coef, fold_terms=fold_terms, prediction=dd,
    )  # fmt: skip
