"""Where the residual stands above the noise floor, and by what it is organised.

The residual is measured minus simulated force after the model's own parameters were re-fitted
(the baseline). The noise floor is its white-noise level (``effects.high_frequency_noise``: the
MAD of second differences, which a slowly varying mismatch hardly touches).

For each factor the samples are put in bins and the *strength* of the factor is the RMS of the
bin means about their weighted mean: the part of the residual the factor alone organises. A
factor stands above the noise floor when its strength exceeds ``SIGNIFICANT`` x the noise floor
(and the bins hold enough samples for their means to be far from noise: a bin mean of n
correlated samples is trusted to noise / sqrt(n / 20)).

Factors: pressure (test level), strain, direction of motion (loading / unloading; for
isometric pressure ramps: pressurising / venting), rate (slow / fast), dwell (how the residual
changes during holds, after lengthening and after shortening), cycle number at one level (first
cycle vs later ones), and time (the test's progress). Hysteresis is also measured directly: the
mean residual difference between loading and unloading at the same level and strain.
"""

from __future__ import annotations

import numpy as np

from .effects import Context
from .segment import Labels

SIGNIFICANT = 0.25
CHUNK = 20  # samples that count as one independent measurement of a bin mean


def _bins(residual, groups: np.ndarray, names: dict, noise: float) -> dict:
    out = []
    for g in sorted(names):
        m = groups == g
        if not np.any(m):
            continue
        r = residual[m]
        out.append(
            {
                "bin": names[g],
                "n": int(m.sum()),
                "mean_N": float(r.mean()),
                "rms_N": float(np.sqrt(np.mean(r * r))),
            }
        )
    if not out:
        return {"bins": [], "strength_N": 0.0, "above_noise": False}
    n = np.array([b["n"] for b in out], dtype=float)
    mu = np.array([b["mean_N"] for b in out])
    centre = float(np.sum(n * mu) / n.sum())
    strength = float(np.sqrt(np.sum(n * (mu - centre) ** 2) / n.sum())) if len(out) > 1 else abs(centre)
    trusted = noise / np.sqrt(max(n.min() / CHUNK, 1.0))
    above = bool(len(out) > 1 and strength > SIGNIFICANT * noise and strength > 3 * trusted)
    return {"bins": out, "strength_N": strength, "above_noise": above}


def locate(ctx: Context, labels: Labels, residual: np.ndarray, noise: float) -> dict:
    """The located mismatch: per factor bins, strengths, and sentences (strongest first)."""
    iso = labels.isometric
    factors: dict[str, dict] = {}
    levels = {i: f"{p / 1e3:.0f} kPa" for i, p in enumerate(labels.levels_Pa)}
    if iso:
        edges = np.linspace(ctx.P.min(), ctx.P.max(), 9)
        pbin = np.clip(np.searchsorted(edges, ctx.P) - 1, 0, 7)
        factors["pressure"] = _bins(
            residual, pbin, {i: f"{edges[i] / 1e3:.0f}-{edges[i + 1] / 1e3:.0f} kPa" for i in range(8)}, noise
        )
    else:
        factors["pressure"] = _bins(residual, labels.level, levels, noise)
        moving = labels.moving
        q = np.quantile(ctx.x[moving], np.linspace(0, 1, 9)) if moving.any() else np.linspace(0, 1, 9)
        sbin = np.where(moving, np.clip(np.searchsorted(q, ctx.x) - 1, 0, 7), -1)
        factors["strain"] = _bins(residual, sbin, {i: f"{q[i]:.2f}-{q[i + 1]:.2f}" for i in range(8)}, noise)
    up, down = ("pressurising", "venting") if iso else ("lengthening", "shortening")
    factors["direction"] = _bins(residual, labels.direction, {1: up, -1: down, 0: "still"}, noise)
    if np.any(labels.rate_class == 1):
        factors["rate"] = _bins(residual, labels.rate_class, {0: "slow", 1: "fast"}, noise)
    factors["cycle"] = _bins(
        residual, np.minimum(labels.cycle_in_level, 3), {0: "1st", 1: "2nd", 2: "3rd", 3: "later"}, noise
    )
    tbin = np.minimum((np.arange(ctx.n) * 8) // max(ctx.n, 1), 7)
    factors["time"] = _bins(residual, tbin, {i: f"{i + 1}/8 of the test" for i in range(8)}, noise)
    factors["dwell"] = _dwell(ctx, labels, residual, noise)
    hysteresis = _hysteresis(ctx, labels, residual, iso)
    words = _words(factors, hysteresis, residual, noise, iso)
    return {
        "noise_N": noise,
        "residual_rms_N": float(np.sqrt(np.mean(residual**2))),
        "factors": factors,
        "hysteresis_N": hysteresis,
        "above_noise": [k for k, f in factors.items() if f["above_noise"]],
        "summary": words,
    }


def _dwell(ctx, labels, residual, noise) -> dict:
    """Residual change over each hold (last quarter minus first quarter), by the direction of
    the motion before it."""
    changes = {1: [], -1: []}
    for h in range(labels.hold_id.max() + 1):
        idx = np.flatnonzero(labels.hold_id == h)
        if len(idx) < 8 or idx[0] == 0:
            continue
        before = labels.direction[max(0, idx[0] - 40) : idx[0]]
        before = before[before != 0]
        if not len(before):
            continue
        q = max(len(idx) // 4, 2)
        change = float(residual[idx[-q:]].mean() - residual[idx[:q]].mean())
        changes[int(np.sign(before[-1]))].append(change)
    bins = []
    for d, name in ((1, "after rising"), (-1, "after falling")):
        if changes[d]:
            bins.append({"bin": name, "n": len(changes[d]), "mean_N": float(np.mean(changes[d])),
                         "rms_N": float(np.sqrt(np.mean(np.square(changes[d]))))})  # fmt: skip
    strength = float(np.sqrt(np.mean([b["rms_N"] ** 2 for b in bins]))) if bins else 0.0
    n_holds = sum(b["n"] for b in bins)
    above = bool(bins and strength > SIGNIFICANT * noise and strength > 3 * noise / np.sqrt(max(n_holds, 1)))
    return {"bins": bins, "strength_N": strength, "above_noise": above}


def _hysteresis(ctx, labels, residual, iso) -> float:
    """Mean residual(rising) - residual(falling) over cells of equal level and position."""
    position = ctx.P if iso else ctx.x
    lo, hi = np.percentile(position, [1, 99])
    cell = np.clip(((position - lo) / max(hi - lo, 1e-12) * 10).astype(int), 0, 9)
    key = labels.level * 10 + cell if not iso else cell
    diffs, weights = [], []
    for k in np.unique(key):
        m = key == k
        a = residual[m & (labels.direction == 1)]
        b = residual[m & (labels.direction == -1)]
        if len(a) >= 5 and len(b) >= 5:
            diffs.append(a.mean() - b.mean())
            weights.append(min(len(a), len(b)))
    return float(np.average(diffs, weights=weights)) if diffs else 0.0


def _words(factors, hysteresis, residual, noise, iso) -> list[str]:
    rms = float(np.sqrt(np.mean(residual**2)))
    lines = [
        f"Residual after re-fitting the model's own parameters: RMS {rms:.2f} N against a noise floor of {noise:.2f} N."
    ]
    if rms < 1.1 * noise:
        lines.append(
            "It does not stand above the noise floor anywhere: nothing is missing that these data can show."
        )
        return lines
    ranked = sorted(
        ((k, f) for k, f in factors.items() if f["above_noise"]), key=lambda kv: -kv[1]["strength_N"]
    )
    if not ranked:
        lines.append(
            "No single factor organises it; the excess is spread evenly (noise or many small causes)."
        )
    for name, f in ranked:
        bins = f["bins"]
        lo = min(bins, key=lambda b: b["mean_N"])
        hi = max(bins, key=lambda b: b["mean_N"])
        what = {
            "pressure": "pressure", "strain": "strain", "direction": "direction of motion", "rate": "rate",
            "cycle": "cycle number at one pressure", "time": "time", "dwell": "holds (dwell)",
        }[name]  # fmt: skip
        if name == "dwell":
            parts = ", ".join(f"{b['mean_N']:+.2f} N during holds {b['bin']}" for b in bins)
            lines.append(f"It changes during holds (relaxation): {parts}.")
            continue
        lines.append(
            f"It depends on {what} ({f['strength_N']:.2f} N): from {lo['mean_N']:+.2f} N ({lo['bin']}) "
            f"to {hi['mean_N']:+.2f} N ({hi['bin']})."
        )
    if abs(hysteresis) > SIGNIFICANT * noise:
        a, b = ("pressurising", "venting") if iso else ("lengthening", "shortening")
        lines.append(
            f"Hysteresis: at equal {'pressure' if iso else 'pressure and strain'} the push force is "
            f"{abs(hysteresis):.2f} N {'higher' if hysteresis > 0 else 'lower'} while {a} than while {b}."
        )
    return lines
