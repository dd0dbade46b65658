"""Fit every candidate jointly with the model's parameter corrections; keep what pays.

For a candidate (one effect, or the kept effect plus one more) the force is

    F = F_base + J du + fixed(shape) + C(shape) a

with ``J du`` the linearised correction of the model's own parameters (``model.Linearised``),
``a`` the effect's linear amplitudes and ``shape`` its non-linear parameters. For a fixed shape
this is a bounded linear least-squares problem; it is solved on its normal equations, so each
fold's training fit costs a k x k solve (k <= 16) whatever the number of samples.

Validation. Whole cycles are held out (``segment`` folds). In each fold the shape is chosen on the
training cycles only (the grid point with the smallest training error) and the held-out cycles
are predicted; the held-out RMS pools all folds. The baseline (no effect, same corrections) is
scored the same way.

Information criterion. BIC on the noise-normalised residual: ``chi2 = RSS / noise^2`` and
``BIC = chi2 + k ln n`` with k the effect's identifiable parameters. With ~20 000 samples a
systematic residual of a fraction of the noise is already "significant", so an effect is kept
only when it also matters: it must lower the held-out RMS by at least ``MIN_GAIN`` and remove at
least ``MIN_EXCESS_CUT`` of the held-out excess over the noise floor; a second effect is added only
when it passes the same tests against the first.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import lsq_linear, minimize_scalar

from .effects import Context, Effect, get, high_frequency_noise
from .model import Linearised
from .segment import Labels

MIN_DELTA_BIC = 30.0
MIN_GAIN = 0.08  # held-out RMS must fall by 8 %
MIN_EXCESS_CUT = 0.3  # and lose 30 % of its excess over the noise floor
MIN_EXCESS_RATIO = 1.08  # the baseline held-out RMS must stand this far above the noise floor


@dataclass
class Fit:
    """One candidate model fitted to all data, with its held-out score."""

    names: tuple[str, ...]
    shapes: dict[str, dict[str, float]]
    values: dict[str, dict[str, float]]
    du: np.ndarray
    rss: float
    k: int
    heldout_rss: float
    heldout_n: int
    prediction: np.ndarray  # linearised prediction of the force, original sample order
    identifiable: dict[str, list[str]] = field(default_factory=dict)

    @property
    def heldout_rms(self) -> float:
        return math.sqrt(self.heldout_rss / max(self.heldout_n, 1))

    def chi2(self, noise: float) -> float:
        return self.rss / noise**2

    def bic(self, noise: float, n: int) -> float:
        return self.chi2(noise) + self.k * math.log(n)


class Engine:
    """Normal-equation blocks per fold for the base model, and candidate fits on top."""

    def __init__(self, ctx: Context, lin: Linearised, force: np.ndarray, labels: Labels):
        self.ctx = ctx
        self.lin = lin
        self.n = ctx.n
        self.order = np.argsort(labels.fold, kind="stable")
        folds = labels.fold[self.order]
        edges = np.r_[0, np.flatnonzero(np.diff(folds)) + 1, len(folds)]
        self.slices = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
        self.y = (force - ctx.base)[self.order]
        # the model's parameter corrections, then one column for the force error the model
        # inherits from the pressure sensor's noise, so that no effect is credited with it
        eiv = ctx.input_noise()[self.order]
        self.J = np.column_stack([lin.J[self.order], eiv])
        self.Jscale = np.sqrt(np.mean(self.J**2, axis=0)) + 1e-300
        self.Jn = self.J / self.Jscale
        self.jlo = np.r_[lin.lo, -2.0]
        self.jhi = np.r_[lin.hi, 2.0]

    # ----------------------------------------------------------------------- solving
    def _blocks(self, A: np.ndarray, y: np.ndarray):
        G = np.stack([A[s].T @ A[s] for s in self.slices])
        b = np.stack([A[s].T @ y[s] for s in self.slices])
        yy = np.array([y[s] @ y[s] for s in self.slices])
        return G, b, yy

    @staticmethod
    def _solve(G, b, lo, hi):
        d = np.sqrt(np.maximum(np.diag(G), 1e-300))
        Gs = G / np.outer(d, d) + 1e-10 * np.eye(len(d))
        bs = b / d
        try:
            c = cho_factor(Gs)
        except np.linalg.LinAlgError:
            Gs = Gs + 1e-6 * np.eye(len(d))
            c = cho_factor(Gs)
        free = cho_solve(c, bs) / d
        if np.all(free >= lo - 1e-12) and np.all(free <= hi + 1e-12):
            return free
        R = np.linalg.cholesky(Gs).T
        z = np.linalg.solve(R.T, bs)
        sol = lsq_linear(R, z, bounds=(lo * d, hi * d), method="bvls")
        return sol.x / d

    @staticmethod
    def _rss(G, b, yy, theta):
        return float(yy - 2 * theta @ b + theta @ G @ theta)

    def _design(self, effects: list[Effect], shapes: list[dict]):
        """Stacked effect columns (scaled), fixed force, bounds, and column bookkeeping."""
        fixed = np.zeros(self.n)
        cols, lo, hi, owner = [], [], [], []
        for effect, shape in zip(effects, shapes):
            f, C = effect.design(self.ctx, shape)
            fixed = fixed + f
            for j, p in enumerate(effect.linear):
                col = C[:, j][self.order]
                scale = math.sqrt(float(np.mean(col**2)))
                if scale < 1e-9:
                    continue  # not identifiable from these recordings (e.g. no motion)
                cols.append(col / scale)
                lo.append(p.lo * scale)
                hi.append(p.hi * scale)
                owner.append((effect.name, p.key, scale))
        C = np.column_stack(cols) if cols else np.zeros((self.n, 0))
        return fixed[self.order], C, np.array(lo), np.array(hi), owner

    def fit(self, effects: list[Effect], shapes: list[dict], want_folds: bool = True):
        """Full-data fit and per-fold (train RSS, test RSS) for one set of shapes."""
        fixed, C, clo, chi, owner = self._design(effects, shapes)
        A = np.hstack([self.Jn, C])
        lo = np.r_[self.jlo * self.Jscale, clo]
        hi = np.r_[self.jhi * self.Jscale, chi]
        y = self.y - fixed
        G, b, yy = self._blocks(A, y)
        Gt, bt, yyt = G.sum(0), b.sum(0), yy.sum()
        theta = self._solve(Gt, bt, lo, hi)
        full = self._rss(Gt, bt, yyt, theta)
        folds = []
        if want_folds and len(self.slices) > 1:
            for k in range(len(self.slices)):
                th = self._solve(Gt - G[k], bt - b[k], lo, hi)
                folds.append(
                    (self._rss(Gt - G[k], bt - b[k], yyt - yy[k], th), self._rss(G[k], b[k], yy[k], th))
                )
        return theta, full, folds, (fixed, A, owner)

    # --------------------------------------------------------------------- candidates
    def baseline(self) -> Fit:
        return self.candidate([], [])

    def candidate(self, effects: list[Effect], fixed_shapes: list[dict | None]) -> Fit:
        """Fit effects; the shapes given as None are searched (grid per fold, refined on all)."""
        free = [i for i, s in enumerate(fixed_shapes) if s is None]
        grids = []
        for i in free:
            params = effects[i].shapes
            axes = [effects[i].shape_range(self.ctx, p)[1] for p in params]
            grids.append([dict(zip([p.key for p in params], combo)) for combo in itertools.product(*axes)])
        combos = list(itertools.product(*grids)) if grids else [()]
        results = []
        for combo in combos:
            shapes = list(fixed_shapes)
            for i, s in zip(free, combo):
                shapes[i] = s
            theta, full, folds, _ = self.fit(effects, shapes)
            results.append((shapes, full, folds))
        heldout, count = self._heldout(results)
        best = min(results, key=lambda r: r[1])[0]
        best = self._refine(effects, best, free)
        theta, full, _, (fixed, A, owner) = self.fit(effects, best, want_folds=False)
        return self._package(effects, best, theta, full, heldout, count, fixed, A, owner)

    def _heldout(self, results):
        if not results[0][2]:
            return float("nan"), 0
        total = 0.0
        for k in range(len(self.slices)):
            train_best = min(results, key=lambda r: r[2][k][0])
            total += train_best[2][k][1]
        return total, self.n

    def _refine(self, effects, shapes, free):
        """Coordinate-wise bounded refinement of the free shape parameters in log space."""
        shapes = [dict(s) for s in shapes]
        for i in free:
            for p in effects[i].shapes:
                p_lo, p_grid, p_hi = effects[i].shape_range(self.ctx, p)
                grid = np.log(np.array(p_grid))
                cur = math.log(shapes[i][p.key])
                step = float(np.min(np.diff(grid))) if len(grid) > 1 else 0.5
                lo = max(math.log(p_lo), cur - step)
                hi = min(math.log(p_hi), cur + step)
                if hi - lo < 1e-9:
                    continue

                def cost(logv, i=i, key=p.key):
                    trial = [dict(s) for s in shapes]
                    trial[i][key] = math.exp(logv)
                    return self.fit(effects, trial, want_folds=False)[1]

                res = minimize_scalar(
                    cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.02, "maxiter": 12}
                )
                if res.fun < cost(cur):
                    shapes[i][p.key] = math.exp(res.x)
        return shapes

    def _package(self, effects, shapes, theta, full, heldout, count, fixed, A, owner) -> Fit:
        k_model = self.Jn.shape[1]
        du = theta[: k_model - 1] / self.Jscale[: k_model - 1]
        values: dict[str, dict[str, float]] = {}
        identifiable: dict[str, list[str]] = {}
        for effect, shape in zip(effects, shapes):
            values[effect.name] = {p.key: 0.0 for p in effect.linear} | dict(shape)
            identifiable[effect.name] = list(shape)
        for (name, key, scale), a in zip(owner, theta[k_model:]):
            values[name][key] = float(a / scale)
            identifiable[name].append(key)
        pred_sorted = self.ctx.base[self.order] + fixed + A @ theta
        prediction = np.empty(self.n)
        prediction[self.order] = pred_sorted
        k = sum(len(v) for v in identifiable.values())
        return Fit(
            names=tuple(e.name for e in effects), shapes={e.name: s for e, s in zip(effects, shapes)},
            values=values, du=du, rss=full, k=k, heldout_rss=heldout, heldout_n=count,
            prediction=prediction, identifiable=identifiable,
        )  # fmt: skip


def pays(new: Fit, old: Fit, noise: float, n: int) -> tuple[bool, dict]:
    """Whether ``new`` (one more effect) is worth its parameters over ``old``."""
    d_bic = new.bic(noise, n) - old.bic(noise, n)
    before, after = old.heldout_rms, new.heldout_rms
    excess_before = max(before**2 - noise**2, 0.0)
    excess_after = max(after**2 - noise**2, 0.0)
    gain = 1.0 - after / before if before > 0 else 0.0
    cut = 1.0 - excess_after / excess_before if excess_before > 0 else 0.0
    stands_out = before > MIN_EXCESS_RATIO * noise
    ok = bool(d_bic < -MIN_DELTA_BIC and gain >= MIN_GAIN and cut >= MIN_EXCESS_CUT and stands_out)
    return ok, {"delta_bic": d_bic, "heldout_gain": gain, "excess_cut": cut, "stands_out": stands_out}


def search(engine: Engine, names: tuple[str, ...], max_effects: int = 2):
    """Single effects first, then one more on top of the best if it still pays.

    The noise floor is the white-noise level of the baseline's residual (``high_frequency_noise``).
    Returns (noise, baseline fit, kept fits in order, every single-effect fit, decision notes)."""
    n = engine.n
    base = engine.baseline()
    residual = np.empty(n)
    residual[engine.order] = engine.y + engine.ctx.base[engine.order]
    residual -= base.prediction
    noise = high_frequency_noise(residual, engine.ctx.starts)
    singles = {name: engine.candidate([get(name)], [None]) for name in names}
    ranked = sorted(singles.values(), key=lambda f: (f.heldout_rms, f.bic(noise, n)))
    notes = {f.names[0]: pays(f, base, noise, n)[1] for f in ranked}
    kept: list[Fit] = []
    if ranked:
        ok, _ = pays(ranked[0], base, noise, n)
        if ok:
            kept.append(ranked[0])
    while kept and len(kept) < max_effects:
        current = kept[-1]
        effects = [get(name) for name in current.names]
        shapes = [current.shapes[name] for name in current.names]
        options = []
        for name in names:
            if name in current.names:
                continue
            options.append(engine.candidate(effects + [get(name)], shapes + [None]))
        if not options:
            break
        best = min(options, key=lambda f: (f.heldout_rms, f.bic(noise, n)))
        ok, info = pays(best, current, noise, n)
        notes[" + ".join(best.names)] = info
        if not ok:
            break
        kept.append(best)
    return noise, base, kept, singles, notes
