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
least ``MIN_EXCESS_CUT`` of the held-out excess over the noise floor. A further effect is added
while it lowers the held-out RMS left by the kept ones by ``SECOND_GAIN`` (and BIC agrees), up to
``max_effects``. The thresholds were set on synthetic recordings with seeds 5000-5067, not on the
benchmark's.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import lsq_linear, minimize_scalar

from .effects import Context, Effect, get, high_frequency_noise
from .model import MIN_DELTA_BIC, Linearised  # one BIC margin, shared with ``model.refit``
from .segment import Labels

MIN_GAIN = 0.03  # held-out RMS must fall by 3 %
MIN_EXCESS_CUT = 0.3  # and lose 30 % of its excess over the noise floor
MIN_EXCESS_RATIO = 1.08  # the baseline held-out RMS must stand this far above the noise floor
SECOND_GAIN = 0.03  # a further effect must lower the held-out RMS left by the others by 3 %


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
    before_heldout_rms: float | None = None  # held-out RMS of the model it was added to
    heldout_residual: np.ndarray | None = field(default=None, repr=False)  # per sample, held out

    @property
    def heldout_rms(self) -> float:
        """RMS (N) of the held-out residual over all folds."""
        return math.sqrt(self.heldout_rss / max(self.heldout_n, 1))

    def chi2(self, noise: float) -> float:
        """Chi-square of the fitted residual for a noise level ``noise`` (N)."""
        return self.rss / noise**2

    def bic(self, noise: float, n: int) -> float:
        """Bayesian information criterion of the fit for ``n`` samples."""
        return self.chi2(noise) + self.k * math.log(n)


def _nearest_positive_definite(Gs: np.ndarray):
    """A unit-diagonal normal matrix that rounding left indefinite, made positive definite, with
    its Cholesky factor: a ridge first, and where that is not enough its eigenvalues floored (a
    training fold's matrix is the total less the held-out fold's, and a column whose size sits
    nearly all in one fold, e.g. a drift's accelerating course on a test hours long, loses its
    digits in that difference). Returns (matrix, ``cho_factor`` of it)."""
    ridged = Gs + 1e-6 * np.eye(len(Gs))
    try:
        return ridged, cho_factor(ridged)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (Gs + Gs.T))
        w = np.maximum(w, 1e-6 * max(float(w.max()), 1.0))
        floored = (V * w) @ V.T
        return floored, cho_factor(floored)


#: the lowest noise floor (N): see ``noise_floor``
MIN_NOISE_N = 1e-6


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
        """Bounded least squares on the normal equations (bounds contain 0)."""
        diag = np.diag(G)
        # columns without data, or pinned at 0 by their bounds, stay 0
        live = (diag > 1e-12 * max(float(diag.max(initial=0.0)), 1e-300)) & (hi - lo > 0)
        theta = np.zeros(len(b))
        if not live.any():
            return theta
        G, b, lo, hi = G[np.ix_(live, live)], b[live], lo[live], hi[live]
        d = np.sqrt(np.diag(G))
        Gs = G / np.outer(d, d) + 1e-10 * np.eye(len(d))
        bs = b / d
        if not (np.all(np.isfinite(Gs)) and np.all(np.isfinite(bs))):
            raise ArithmeticError(
                "the fit's normal equations overflowed (a candidate term grew beyond double precision over "
                "this test): check the time column's unit and the test's duration"
            )
        try:
            c = cho_factor(Gs)
        except np.linalg.LinAlgError:
            Gs, c = _nearest_positive_definite(Gs)
        free = cho_solve(c, bs) / d
        if np.all(free >= lo - 1e-12) and np.all(free <= hi + 1e-12):
            theta[live] = free
            return theta
        R = np.linalg.cholesky(Gs).T
        z = np.linalg.solve(R.T, bs)
        theta[live] = lsq_linear(R, z, bounds=(lo * d, hi * d), method="bvls").x / d
        return theta

    @staticmethod
    def _rss(G, b, yy, theta):
        # a sum of squares expanded on the normal equations can round below zero when the fit
        # is near exact (a constant recording): it is zero then
        return max(float(yy - 2 * theta @ b + theta @ G @ theta), 0.0)

    def _design(self, effects: list[Effect], shapes: list[dict]):
        """Stacked effect columns (scaled), fixed force, bounds, and column bookkeeping."""
        fixed = np.zeros(self.n)
        cols, lo, hi, owner = [], [], [], []
        for effect, shape in zip(effects, shapes):
            f, C = effect.design(self.ctx, effect.settle(self.ctx, shape))
            fixed = fixed + f
            basis = None if effect.per_recording else effect.fit_basis(self.ctx)
            if effect.per_recording:  # one amplitude per recording, keyed "<key>#<recording>"
                params = [(effect.linear[0].lo, effect.linear[0].hi, f"{effect.linear[0].key}#{r}")
                          for r in range(C.shape[1])]  # fmt: skip
            elif basis is not None:  # solved for k (values = T @ k), keyed "~<j>"
                T, klo, khi = basis
                C = C @ T
                params = [(klo[j], khi[j], f"~{j}") for j in range(T.shape[1])]
            else:
                params = [(p.lo, p.hi, p.key) for p in effect.linear]
            for j, (p_lo, p_hi, key) in enumerate(params):
                col = C[:, j][self.order]
                scale = math.sqrt(float(np.mean(col**2)))
                if scale < 1e-9:
                    continue  # not identifiable from these recordings (e.g. no motion)
                cols.append(col / scale)
                lo.append(p_lo * scale)
                hi.append(p_hi * scale)
                owner.append((effect.name, key, scale))
        C = np.column_stack(cols) if cols else np.zeros((self.n, 0))
        return fixed[self.order], C, np.array(lo), np.array(hi), owner

    def _fill_unseen(self, theta, G_train, owner, k_model):
        """A per-recording amplitude (a load-cell zero) of a recording held out entirely has no
        training data: predict it with the mean of the other recordings' amplitudes."""
        groups: dict[str, list[int]] = {}
        for j, (name, key, _) in enumerate(owner):
            if "#" in key:
                groups.setdefault(name, []).append(j)
        for cols in groups.values():
            idx = [k_model + j for j in cols]
            seen = [i for i in idx if G_train[i, i] > 0]
            unseen = [i for i in idx if G_train[i, i] <= 0]
            if seen and unseen:
                mean = np.mean([theta[i] / owner[i - k_model][2] for i in seen])
                for i in unseen:
                    theta[i] = mean * owner[i - k_model][2]
        return theta

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
                th = self._fill_unseen(th, Gt - G[k], owner, self.Jn.shape[1])
                s = self.slices[k]
                folds.append(
                    (self._rss(Gt - G[k], bt - b[k], yyt - yy[k], th), self._rss(G[k], b[k], yy[k], th),
                     (y[s] - A[s] @ th).astype(np.float32))
                )  # fmt: skip
        return theta, full, folds, (fixed, A, owner)

    # --------------------------------------------------------------------- candidates
    def baseline(self) -> Fit:
        """The fit with no effect: the re-fitted model alone."""
        return self.candidate([], [])

    def candidate(
        self,
        effects: list[Effect],
        fixed_shapes: list[dict | None],
        folds: bool = True,
        with_model: bool = True,
    ) -> Fit:
        """Fit effects; the shapes given as None are searched (grid per fold, refined on all).
        ``folds=False`` skips the held-out scoring (its RMS is then NaN); ``with_model=False``
        keeps the model's parameters where they are (only the effects are fitted)."""
        if not with_model:
            saved = (self.jlo, self.jhi)
            self.jlo = np.r_[np.zeros(len(self.jlo) - 1), self.jlo[-1:]]
            self.jhi = np.r_[np.zeros(len(self.jhi) - 1), self.jhi[-1:]]
            try:
                return self.candidate(effects, fixed_shapes, folds)
            finally:
                self.jlo, self.jhi = saved
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
            theta, full, per_fold, _ = self.fit(effects, shapes, want_folds=folds)
            results.append((shapes, full, per_fold))
        heldout, count, residual = self._heldout(results)
        best = min(results, key=lambda r: r[1])[0]
        best = self._refine(effects, best, free)
        theta, full, _, (fixed, A, owner) = self.fit(effects, best, want_folds=False)
        fit = self._package(effects, best, theta, full, heldout, count, fixed, A, owner)
        if residual is not None:
            fit.heldout_residual = np.empty(self.n)
            fit.heldout_residual[self.order] = residual
        return fit

    def _heldout(self, results):
        """Pooled held-out RSS, and the held-out residual of every sample (sorted order), each fold
        predicted with the shapes its own training data chose."""
        if not results[0][2]:
            return float("nan"), 0, None
        total = 0.0
        residual = np.empty(self.n)
        for k in range(len(self.slices)):
            train_best = min(results, key=lambda r: r[2][k][0])
            total += train_best[2][k][1]
            residual[self.slices[k]] = train_best[2][k][2]
        return total, self.n, residual

    def _refine(self, effects, shapes, free):
        """Coordinate-wise bounded refinement of the free shape parameters in log space."""
        shapes = [dict(s) for s in shapes]
        for i in free:
            for p in effects[i].shapes:
                if p.discrete:
                    continue
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
            # an amplitude these data leave unidentified (a column without data) is written as its
            # default where the physics has one (the pressure lag's volume gain: 1), else 0
            unseen = {p.key: 0.0 if p.default is None else p.default for p in effect.linear}
            values[effect.name] = unseen | effect.settle(self.ctx, shape)
            identifiable[effect.name] = list(shape)
        per_recording: dict[tuple[str, str], dict[int, float]] = {}
        in_basis: dict[str, dict[int, float]] = {}
        bounds = {(e.name, p.key): (p.lo, p.hi) for e in effects for p in e.linear}

        def held(name, key, value):  # the solver's bounds, less its last-digit rounding past them
            lo, hi = bounds[name, key]
            return float(min(max(value, lo), hi))

        for (name, key, scale), a in zip(owner, theta[k_model:]):
            if key.startswith("~"):
                in_basis.setdefault(name, {})[int(key[1:])] = a / scale
                continue
            if "#" in key:
                base, r = key.split("#")
                per_recording.setdefault((name, base), {})[int(r)] = held(name, base, a / scale)
                continue
            values[name][key] = held(name, key, a / scale)
            identifiable[name].append(key)
        for effect in effects:  # values solved in a fit basis: T @ k (an unseen k is 0)
            if effect.name in in_basis:
                T = effect.fit_basis(self.ctx)[0]
                k = np.array([in_basis[effect.name].get(j, 0.0) for j in range(T.shape[1])])
                for p, a in zip(effect.linear, T @ k):
                    values[effect.name][p.key] = held(effect.name, p.key, a)
                    identifiable[effect.name].append(p.key)
        counts = np.diff(np.r_[self.ctx.starts, self.n])
        for (name, base), found in per_recording.items():
            by = [found.get(r, 0.0) for r in range(len(counts))]
            values[name][base] = float(np.average(by, weights=counts))
            if len(by) > 1:
                values[name][f"{base}_by_recording"] = by
            identifiable[name].extend([base] * len(found))
        pred_sorted = self.ctx.base[self.order] + fixed + A @ theta
        prediction = np.empty(self.n)
        prediction[self.order] = pred_sorted
        k = sum(len(v) for v in identifiable.values())
        return Fit(
            names=tuple(e.name for e in effects), shapes={e.name: s for e, s in zip(effects, shapes)},
            values=values, du=du, rss=full, k=k, heldout_rss=heldout, heldout_n=count,
            prediction=prediction, identifiable=identifiable,
        )  # fmt: skip


def pays(new: Fit, old: Fit, noise: float, n: int, second: bool = False) -> tuple[bool, dict]:
    """Whether ``new`` (one more effect) is worth its parameters over ``old``."""
    # a further effect is judged on its own held-out gain (on real data the excess left over the
    # noise floor is mostly model-structure error, which no effect is asked to remove)
    min_gain, min_cut = (SECOND_GAIN, -math.inf) if second else (MIN_GAIN, MIN_EXCESS_CUT)
    d_bic = new.bic(noise, n) - old.bic(noise, n)
    before, after = old.heldout_rms, new.heldout_rms
    excess_before = max(before**2 - noise**2, 0.0)
    excess_after = max(after**2 - noise**2, 0.0)
    gain = 1.0 - after / before if before > 0 else 0.0
    cut = 1.0 - excess_after / excess_before if excess_before > 0 else 0.0
    stands_out = before > MIN_EXCESS_RATIO * noise
    # near the noise floor an effect must remove a good share of the excess; far above it (real
    # data, where model-structure error dominates the excess) a large held-out gain suffices
    ok = bool(
        d_bic < -MIN_DELTA_BIC
        and gain >= min_gain
        and (cut >= min_cut or gain >= 2 * min_gain)
        and stands_out
    )
    return ok, {"delta_bic": d_bic, "heldout_gain": gain, "excess_cut": cut, "stands_out": stands_out}


def noise_floor(measured: float, fits: list[Fit]) -> float:
    """The noise floor: the measured one (``search``), but never above the held-out RMS of any
    hypothesis, since no model predicts unseen data better than the noise in expectation. The
    high-frequency estimate counts as noise what changes within a few samples: a model error that
    turns at a stroke's reversal or a pressure step (at 25-50 Hz a kink spans two samples), and
    the share of the pressure sensor's noise the errors-in-variables column takes out of every
    prediction. On the clean recordings of a benchmark run (108000) it stood above the model's own
    held-out RMS in 32 of 48, by up to 25 % (30 Hz strokes), and a real effect of a third of the
    noise then had no excess to remove (a braid stretch named `none` after the next experiment)."""
    heldout = [f.heldout_rms for f in fits if math.isfinite(f.heldout_rms) and f.heldout_rms > 0]
    # a noise-free recording (a simulation's output, a channel quantised to one value) still
    # gets a floor: a micronewton, below any load cell's resolution, so that chi-squares stay finite
    return max(min([measured] + heldout), MIN_NOISE_N)


def search(engine: Engine, names: tuple[str, ...], max_effects: int = 2):
    """Single effects first, then one more on top of the best if it still pays.

    The noise floor is the white-noise level of the baseline's residual (``high_frequency_noise``)
    with, in quadrature, the smooth force error the pressure sensor's noise leaves in every
    prediction (``Context.input_noise_floor``), capped at the best held-out RMS (``noise_floor``).
    Returns (noise, baseline fit, kept fits in order, every single-effect fit, decision notes)."""
    n = engine.n
    base = engine.baseline()
    residual = np.empty(n)
    residual[engine.order] = engine.y + engine.ctx.base[engine.order]
    residual -= base.prediction
    measured = math.hypot(high_frequency_noise(residual, engine.ctx.starts), engine.ctx.input_noise_floor())
    singles = {name: engine.candidate([get(name)], [None]) for name in names}
    noise = noise_floor(measured, [base] + list(singles.values()))
    ranked = sorted(singles.values(), key=lambda f: (f.heldout_rms, f.bic(noise, n)))
    notes = {f.names[0]: pays(f, base, noise, n)[1] for f in ranked}
    kept: list[Fit] = []
    if ranked:
        ok, _ = pays(ranked[0], base, noise, n)
        if ok:
            ranked[0].before_heldout_rms = base.heldout_rms
            kept.append(ranked[0])
    while kept and len(kept) < max_effects:
        effects = [get(name) for name in kept[-1].names]
        shapes = [kept[-1].shapes[name] for name in kept[-1].names]
        # scored with its shapes fixed, as every option on top of it will be
        current = engine.candidate(effects, shapes)
        options = []
        for name in names:
            if name in current.names:
                continue
            options.append(engine.candidate(effects + [get(name)], shapes + [None]))
        if not options:
            break
        best = min(options, key=lambda f: (f.heldout_rms, f.bic(noise, n)))
        ok, info = pays(best, current, noise, n, second=True)
        notes[" + ".join(best.names)] = info | {"heldout_rms_N": best.heldout_rms}
        if not ok:
            break
        best.before_heldout_rms = current.heldout_rms
        kept.append(best)
    return noise, base, kept, singles, notes
