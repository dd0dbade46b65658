"""Least squares over a few physical parameters, each residual a MuJoCo replay.

Plain Levenberg-Marquardt in the unit box of the parameters' bounds (log scale where the
parameter says so): start values and a coarse grid are rolled out as one batch, then each
iteration rolls out the finite-difference Jacobian and two damped steps as one batch. An
effect is fitted jointly with the re-fit's parameters (``shared``), whose Jacobian columns are
reused from the re-fit instead of being rolled out again. Fits see the training rows only; the
held-out rows are only ever evaluated.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .effects import Param
from .replay import Knobs, Replayer

STEP_U = 0.01  # finite-difference step in the unit box


@dataclass
class FitResult:
    """One fitted hypothesis. ``tip`` is its replay at every sample (training and held out)."""

    values: dict
    knobs: Knobs
    tip: np.ndarray
    sse_train: float
    n_params: int
    jacobian: np.ndarray | None = None  # d residual / d unit parameter at the last linearisation
    params: tuple = ()


def residual(tip: np.ndarray, measured: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Tip error (m) on the given rows, flattened."""
    return (tip[rows] - measured[rows]).ravel()


def fit(
    replayer: Replayer,
    params: tuple[Param, ...],
    make: Callable[[dict], Knobs],
    measured: np.ndarray,
    train: np.ndarray,
    iterations: int = 2,
    start: dict | None = None,
    shared: FitResult | None = None,
    grid: bool = True,
    resume: FitResult | None = None,
) -> FitResult:
    """Fit ``params`` (knobs made by ``make(values)``) to ``measured`` tip rows ``train``; with
    ``shared``, its parameters are fitted too (from its values, with its Jacobian columns).
    ``grid=False``: from ``start`` alone (its start grid already searched elsewhere);
    ``resume``: more iterations of an earlier fit of the same parameters (nothing re-rolled)."""
    own = len(params)
    every = tuple(params) + (shared.params if shared else ())
    start = {**(shared.values if shared else {}), **(start or {})}
    u0 = np.array([p.to_unit(start.get(p.key, p.start if p.start is not None else p.lo)) for p in every])

    def values(u):
        return {p.key: p.from_unit(x) for p, x in zip(every, u)}

    if resume is not None:
        u = np.array([p.to_unit(resume.values[p.key]) for p in every])
        tip, cost = resume.tip, resume.sse_train
    else:
        starts = [u0]
        for i, p in enumerate(params if grid else ()):
            for g in p.grid:
                u = u0.copy()
                u[i] = p.to_unit(g)
                if not any(
                    np.allclose(u, s, rtol=0, atol=1e-12) for s in starts
                ):  # a grid value at the start
                    starts.append(u)
        tips = replayer.tips([make(values(u)) for u in starts])
        sse = np.array([np.sum(residual(t, measured, train) ** 2) for t in tips])
        best = int(np.argmin(sse))
        u, tip, cost = starts[best], tips[best], sse[best]
    lam = 1e-2
    J = None
    for _ in range(iterations):
        r0 = residual(tip, measured, train)
        fresh = range(own) if shared is not None and shared.jacobian is not None else range(len(every))
        probes = []
        for i in fresh:
            du = np.zeros_like(u)
            du[i] = STEP_U if u[i] + STEP_U <= 1 else -STEP_U
            probes.append(u + du)
        ptips = replayer.tips([make(values(x)) for x in probes]) if probes else []
        cols = [(residual(t, measured, train) - r0) / (x - u).sum() for t, x in zip(ptips, probes)]
        J = np.column_stack(
            cols
            + (
                [shared.jacobian[:, j] for j in range(len(every) - own)]
                if len(cols) == own and shared
                else []
            )
        )
        A = J.T @ J
        g = J.T @ r0
        trials = []
        for lam_try in (lam, lam * 30):
            step = -np.linalg.solve(A + lam_try * np.diag(np.diag(A) + 1e-12) + 1e-15 * np.eye(len(u)), g)
            trials.append(np.clip(u + step, 0, 1))
        ttips = replayer.tips([make(values(x)) for x in trials])
        tsse = [np.sum(residual(t, measured, train) ** 2) for t in ttips]
        k = int(np.argmin(tsse))
        if tsse[k] < cost:
            u, tip, cost = trials[k], ttips[k], tsse[k]
            lam = lam / 3 if k == 0 else lam * 3
        else:
            lam *= 30
    v = values(u)
    return FitResult(v, make(v), tip, float(cost), own, J, tuple(every))
