"""What the experimenter did at each sample: cycles, pressure levels, direction, rate, holds.

Recordings are concatenated (``starts`` marks each one). Each recording has a *driver*: the strain
when its length moves (isobaric strokes), else the pressure (isometric pressure ramps, where the
rate of the test is the pressure rate). On the driver, smoothed over about half a second:

* a *cycle* is one excursion away from the driver's low state and back (a stroke out and back;
  a pressure ramp up and down). It runs from the completed return of the previous excursion to
  the completed return of its own, so the pressure change and settling before a stroke belong to
  that stroke's cycle;
* its *level* is the pressure it was run at (clustered over cycles), ``cycle_in_level`` counts
  cycles at one level in time order (0 = the first);
* ``direction`` is +1 while the driver rises (loading, pressurising), -1 while it falls, 0 when
  it stands; ``hold`` marks samples where neither length nor pressure moves (dwell);
* ``rate_class`` 0/1 = slow/fast when the moving cycles run at clearly different rates.

Held-out folds keep whole cycles together: fold = (level + cycle_in_level) mod K, so every fold
holds out cycles of several levels and several positions (first, later) in the test order. When
each of several recordings holds a single cycle (one pressure sweep per held length), whole
half-cycles are held out instead: the rising branch of every other recording and the falling branch
of the others form one fold, the rest the other, so every length and both directions are trained
on. A single recording with a single cycle falls back to alternating tenths of the test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects import segments

SMOOTH_S = 0.5
MAX_FOLDS = 5


@dataclass
class Labels:
    driver: np.ndarray  # per sample: 0 strain, 1 pressure
    rate: np.ndarray  # driver rate: strain/s or Pa/s (smoothed)
    direction: np.ndarray
    moving: np.ndarray
    hold: np.ndarray
    hold_id: np.ndarray  # -1 outside holds
    cycle: np.ndarray
    level: np.ndarray
    levels_Pa: np.ndarray
    cycle_in_level: np.ndarray
    rate_class: np.ndarray  # -1 still, 0 slow, 1 fast (0 when only one rate)
    fold: np.ndarray
    n_folds: int

    @property
    def isometric(self) -> bool:
        return bool(np.all(self.driver == 1))


def smooth(u: np.ndarray, window: int) -> np.ndarray:
    if window <= 1:
        return u.copy()
    kernel = np.ones(window) / window
    padded = np.r_[np.full(window // 2, u[0]), u, np.full(window - 1 - window // 2, u[-1])]
    return np.convolve(padded, kernel, mode="valid")


def _window(t: np.ndarray) -> int:
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    return max(3, int(round(SMOOTH_S / max(dt, 1e-9))))


def _rate(t, u, window):
    s = smooth(u, window)
    return np.gradient(s, t) if len(t) > 2 else np.zeros(len(t)), s


def label(t, x, P, starts) -> Labels:
    n = len(t)
    out = {k: np.zeros(n, dtype=int) for k in ("driver", "direction", "cycle", "rate_class")}
    rate = np.zeros(n)
    moving = np.zeros(n, dtype=bool)
    hold = np.zeros(n, dtype=bool)
    cycle_count = 0
    excursions = []  # (cycle index, sample slice of the excursion, recording)
    branch = np.zeros(n, dtype=int)
    recording = np.zeros(n, dtype=int)
    per_recording_cycles: list[int] = []
    for b, e in segments(np.asarray(starts), n):
        tt = t[b:e]
        w = _window(tt)
        rx, sx = _rate(tt, x[b:e], w)
        rp, sp = _rate(tt, P[b:e], w)
        use_pressure = np.ptp(sx) < 0.01
        out["driver"][b:e] = int(use_pressure)
        r, s = (rp, sp) if use_pressure else (rx, sx)
        rate[b:e] = r
        thr = 0.05 * np.percentile(np.abs(r), 90) + 1e-15
        mv = np.abs(r) > thr
        moving[b:e] = mv
        out["direction"][b:e] = np.where(mv, np.sign(r), 0).astype(int)
        still_p = np.abs(rp) <= max(0.05 * np.percentile(np.abs(rp), 90), 5e3)  # 5 kPa/s: noise
        hold[b:e] = _min_runs(~mv & (still_p if not use_pressure else True), tt, 1.0)
        # cycles: excursions of the driver above the middle of its range
        lo, hi = np.percentile(s, 2), np.percentile(s, 98)
        q = (s - lo) / max(hi - lo, 1e-15)
        up = q > 0.5
        found = []  # (start, end) of each excursion and where its return completes
        i = 0
        while i < len(q):
            if not up[i]:
                i += 1
                continue
            j = i
            while j < len(q) and up[j]:
                j += 1
            k = j
            while k < len(q) and q[k] > 0.05:  # the return completes near the low state
                k += 1
            found.append((i, j, k))
            i = max(k, j)
        cyc = np.zeros(e - b, dtype=int)
        for m, (_, _, k) in enumerate(found[:-1]):
            cyc[k:] = m + 1
        for m, (i, j, _) in enumerate(found):
            excursions.append((cycle_count + m, slice(b + i, b + j)))
        out["cycle"][b:e] = cycle_count + cyc
        cycle_count += max(len(found), 1)
        # branch within each cycle: rising up to the driver's peak, falling after it
        for c in np.unique(cyc):
            idx = np.flatnonzero(cyc == c)
            peak = idx[int(np.argmax(s[idx]))]
            branch[b + idx] = np.where(idx <= peak, 0, 1)
        recording[b:e] = len(per_recording_cycles)
        per_recording_cycles.append(max(len(found), 1))
    cycle = out["cycle"]
    n_cycles = cycle_count
    # level of each cycle: median pressure over its excursion (or over the cycle)
    cycle_P = np.array([np.median(P[cycle == c]) if np.any(cycle == c) else 0.0 for c in range(n_cycles)])
    for c, sl in excursions:
        if c < n_cycles:
            cycle_P[c] = np.median(P[sl])
    tol = max(3e3, 0.03 * float(np.max(np.abs(P), initial=0.0)))
    levels, cycle_level = _cluster(cycle_P, tol)
    level = cycle_level[cycle]
    cycle_in_level = np.zeros(n, dtype=int)
    counts: dict[int, int] = {}
    order_in_level = np.zeros(n_cycles, dtype=int)
    for c in range(n_cycles):
        lv = int(cycle_level[c])
        order_in_level[c] = counts.get(lv, 0)
        counts[lv] = order_in_level[c] + 1
    cycle_in_level = order_in_level[cycle]
    # rate classes from the excursions' median moving rates
    exc_rate = {}
    for c, sl in excursions:
        r = np.abs(rate[sl][moving[sl]])
        if len(r):
            exc_rate[c] = float(np.median(r))
    rate_class = np.where(moving, 0, -1)
    if len(exc_rate) >= 2:
        values = np.array(list(exc_rate.values()))
        if values.max() > 1.5 * values.min():
            split = np.sqrt(values.max() * values.min())
            for c, v in exc_rate.items():
                rate_class[(cycle == c) & moving] = int(v > split)
    hold_id = np.full(n, -1)
    edges = np.flatnonzero(np.diff(np.r_[0, hold.astype(int), 0]))
    for k, (s0, s1) in enumerate(zip(edges[::2], edges[1::2])):
        hold_id[s0:s1] = k
    if len(per_recording_cycles) >= 2 and max(per_recording_cycles) == 1:
        # one cycle per recording (e.g. one pressure sweep per held length): hold out half-cycles,
        # the rising branch of every other recording and the falling branch of the rest, so that
        # every recording and both branches stay in training
        fold, n_folds = (recording + branch) % 2, 2
    else:
        fold, n_folds = _folds(cycle, level, cycle_in_level, n_cycles, t)
    return Labels(
        driver=out["driver"], rate=rate, direction=out["direction"], moving=moving, hold=hold,
        hold_id=hold_id, cycle=cycle, level=level, levels_Pa=levels, cycle_in_level=cycle_in_level,
        rate_class=rate_class, fold=fold, n_folds=n_folds,
    )  # fmt: skip


def _min_runs(mask: np.ndarray, t: np.ndarray, seconds: float) -> np.ndarray:
    """``mask`` with runs shorter than ``seconds`` removed."""
    out = mask.copy()
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    for s0, s1 in zip(edges[::2], edges[1::2]):
        if t[s1 - 1] - t[s0] < seconds:
            out[s0:s1] = False
    return out


def _cluster(values: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(values)
    labels = np.zeros(len(values), dtype=int)
    centres: list[list[float]] = []
    for i in order:
        if centres and values[i] - centres[-1][-1] <= tol:
            centres[-1].append(values[i])
        else:
            centres.append([values[i]])
        labels[i] = len(centres) - 1
    return np.array([float(np.median(c)) for c in centres]), labels


def _folds(cycle, level, cycle_in_level, n_cycles, t) -> tuple[np.ndarray, int]:
    if n_cycles >= 2:
        k = min(MAX_FOLDS, n_cycles)
        return (level + cycle_in_level) % k, k
    # one cycle only: alternate ten blocks of time between two folds
    block = np.minimum((np.arange(len(t)) * 10) // max(len(t), 1), 9)
    return block % 2, 2
