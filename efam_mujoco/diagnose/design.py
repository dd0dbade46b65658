"""The next experiment: which test would separate two hypotheses the data cannot tell apart.

For an ambiguous result the two contenders are each a fitted model (the re-fitted muscle with
its parameter corrections and one library term, or none). Both are simulated on candidate
protocols built from the ranges the recording itself covered (its strain range, its top
pressure, its stroke speed), each a test a lab can run on the same rig:

* ``repeat_top``: the top pressure again, two slow strokes over the full strain range (does the
  first loading differ from the next: softening, drift);
* ``descending``: three pressures in descending order, one stroke each (order and history);
* ``long_hold``: a stroke at the top pressure held 60 s at the far end, then 30 s back
  (relaxation vs friction vs drift);
* ``fast``: strokes four times faster than the fastest one recorded (rate dependence);
* ``ramp_at_length``: an isometric pressure ramp up and down at 60 % of the strain range (the
  pressure dependence at another length: end effects vs braid compliance vs lag);
* ``staircase_rest``: a pressure staircase at the shortest length, 8 steps up and down, 3 s
  holds (pressure lag, pressure-direction hysteresis);
* ``pressure_hold``: an isometric ramp to the top pressure held 60 s, vented, held 30 s (slow
  pressure hysteresis, relaxation);
* ``fast_ramps``: three isometric ramps 3 s each way (pressure-rate dependence).

A test that never moved the length (isometric) gets the pressure-only candidates alone: strokes
would ask both models where no data constrained them.
* ``idle``: five minutes at a middle pressure between two strokes (drift).

The score of a candidate is what of the difference between the two models' predicted forces the
diagnosis could not take up another way once the new test is added: the difference less its
least-squares projection on a constant (a load-cell zero) and, when ``absorb`` is given, on the
model's own parameter corrections linearised over the candidate (``model.linearise``: a
difference a re-fit of the braid angle or dead band reproduces separates nothing). Its expected
evidence is the chi-square it adds, ``n (rms_left / noise)^2`` over the candidate's ``n`` samples
at the rate it will be recorded, and the recommended candidate has the largest. The
recommendation states the predicted difference in newtons (raw, and what is left after the
projection), its peak, and the noise floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects import Context, EffectModel

SAMPLE_HZ = 50.0


@dataclass
class Experiment:
    """A test as set points: time (s), length (m), pressure (Pa) breakpoints, linear between."""

    name: str
    words: str
    t: np.ndarray
    L: np.ndarray
    P: np.ndarray

    def sampled(self, hz: float = SAMPLE_HZ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The protocol resampled at ``hz``: time (s), length (m) and pressure (Pa)."""
        tt = np.arange(0.0, float(self.t[-1]), 1.0 / hz)
        return tt, np.interp(tt, self.t, self.L), np.interp(tt, self.t, self.P)


class _Prog:
    def __init__(self, L0):
        self.t, self.L, self.P = [0.0], [L0], [0.0]

    def go(self, dt, L=None, P=None):
        self.t.append(self.t[-1] + max(dt, 1e-3))
        self.L.append(self.L[-1] if L is None else L)
        self.P.append(self.P[-1] if P is None else P)

    def done(self, name, words) -> Experiment:
        return Experiment(name, words, np.array(self.t), np.array(self.L), np.array(self.P))


def candidates(ctx: Context, speed_m_per_s: float) -> list[Experiment]:
    """Candidate next experiments inside the ranges the recording covered."""
    rest = ctx.muscle.rest_length_m
    L_lo, L_hi = float(np.percentile(ctx.L, 1)), float(np.percentile(ctx.L, 99))
    P_top = max(float(np.percentile(ctx.P, 99)), 50e3)
    v = max(speed_m_per_s, 1e-3)
    out = []
    # pressure-only tests at the shortest recorded length: always inside what the data covered
    p = _Prog(L_lo)
    p.go(2)
    p.go(20, P=P_top)
    p.go(60)
    p.go(20, P=0.0)
    p.go(30)
    out.append(
        p.done(
            "pressure_hold",
            f"isometric ramp to {P_top / 1e3:.0f} kPa, held 60 s, vented, 30 s at {L_lo * 1e3:.0f} mm",
        )
    )
    p = _Prog(L_lo)
    p.go(2)
    for _ in range(3):
        p.go(3, P=P_top)
        p.go(1)
        p.go(3, P=0.0)
        p.go(1)
    out.append(
        p.done(
            "fast_ramps",
            f"three fast isometric ramps 0-{P_top / 1e3:.0f}-0 kPa (3 s each way) at {L_lo * 1e3:.0f} mm",
        )
    )
    p = _Prog(L_lo)
    p.go(2)
    for k in list(range(1, 9)) + list(range(7, -1, -1)):
        p.go(0.001, P=P_top * k / 8)
        p.go(3)
    out.append(
        p.done(
            "staircase_rest",
            f"pressure staircase 8 steps to {P_top / 1e3:.0f} kPa and down, 3 s holds, at {L_lo * 1e3:.0f} mm",
        )
    )
    if L_hi - L_lo < 0.05 * rest:
        return out  # an isometric test: strokes would ask the models where no data constrained them
    stroke = (L_hi - L_lo) / v
    p = _Prog(L_lo)
    p.go(2)
    p.go(0.001, P=P_top)
    p.go(5)
    for _ in range(2):
        p.go(stroke, L=L_hi)
        p.go(3)
        p.go(stroke, L=L_lo)
        p.go(3)
    out.append(
        p.done(
            "repeat_top", f"at {P_top / 1e3:.0f} kPa, two slow strokes {L_lo * 1e3:.0f}-{L_hi * 1e3:.0f} mm"
        )
    )
    p = _Prog(L_lo)
    p.go(2)
    for f in (1.0, 2 / 3, 1 / 3):
        p.go(0.001, P=f * P_top)
        p.go(5)
        p.go(stroke, L=L_hi)
        p.go(3)
        p.go(stroke, L=L_lo)
        p.go(3)
    out.append(
        p.done(
            "descending",
            f"pressures {P_top / 1e3:.0f}, {2 * P_top / 3e3:.0f}, {P_top / 3e3:.0f} kPa in this order, one stroke each",
        )
    )
    p = _Prog(L_lo)
    p.go(2)
    p.go(0.001, P=P_top)
    p.go(5)
    p.go(stroke / 3, L=L_hi)
    p.go(60)
    p.go(stroke / 3, L=L_lo)
    p.go(30)
    out.append(
        p.done(
            "long_hold",
            f"at {P_top / 1e3:.0f} kPa, a stroke held 60 s at {L_hi * 1e3:.0f} mm, then 30 s back",
        )
    )
    p = _Prog(L_lo)
    p.go(2)
    for f in (0.5, 1.0):
        p.go(0.001, P=f * P_top)
        p.go(5)
        for _ in range(2):
            p.go(stroke / 4, L=L_hi)
            p.go(1)
            p.go(stroke / 4, L=L_lo)
            p.go(1)
    out.append(
        p.done(
            "fast",
            f"strokes 4x faster ({4 * v * 1e3:.0f} mm/s) at {P_top / 2e3:.0f} and {P_top / 1e3:.0f} kPa",
        )
    )
    L_mid = L_lo + 0.6 * (L_hi - L_lo)
    p = _Prog(L_lo)
    p.go(2)
    p.go(abs(L_mid - L_lo) / v, L=L_mid)
    p.go(3)
    p.go(20, P=P_top)
    p.go(2)
    p.go(20, P=0.0)
    p.go(3)
    out.append(
        p.done(
            "ramp_at_length", f"isometric ramp 0-{P_top / 1e3:.0f}-0 kPa over 40 s at {L_mid * 1e3:.0f} mm"
        )
    )
    p = _Prog(L_lo)
    p.go(2)
    p.go(0.001, P=P_top / 2)
    p.go(5)
    p.go(stroke, L=L_hi)
    p.go(stroke, L=L_lo)
    p.go(300)
    p.go(stroke, L=L_hi)
    p.go(stroke, L=L_lo)
    p.go(3)
    out.append(p.done("idle", f"five minutes at {P_top / 2e3:.0f} kPa between two strokes"))
    return out


def _difference(a: EffectModel, b: EffectModel, experiment: Experiment):
    """The two models' predicted force difference over ``experiment`` (N), with its L and P."""
    t, L, P = experiment.sampled()
    return a.push(t, L, P) - b.push(t, L, P), L, P


def _spread(d: np.ndarray) -> tuple[float, float]:
    d = d - d.mean()
    return float(np.sqrt(np.mean(d * d))), float(np.max(np.abs(d)))


def _left_after_projection(d: np.ndarray, L: np.ndarray, P: np.ndarray, absorb=None) -> float:
    cols = [np.ones_like(d)]
    if absorb is not None:
        J = np.asarray(absorb(P, L), float)
        if J.ndim == 2 and J.shape[1]:
            cols.append(J)
    A = np.column_stack(cols)
    scale = np.sqrt(np.mean(A * A, axis=0)) + 1e-300
    coef, *_ = np.linalg.lstsq(A / scale, d, rcond=None)
    left = d - (A / scale) @ coef
    return float(np.sqrt(np.mean(left * left)))


def separation(a: EffectModel, b: EffectModel, experiment: Experiment) -> tuple[float, float]:
    """(RMS of the predicted force difference less its mean, its peak), N."""
    return _spread(_difference(a, b, experiment)[0])


def unabsorbed(a: EffectModel, b: EffectModel, experiment: Experiment, absorb=None) -> float:
    """RMS (N) of the two models' predicted force difference over ``experiment`` left after its
    least-squares projection on a constant and on ``absorb(P, L)`` (columns: force changes the
    model's own parameter corrections can make there), i.e. what no re-fit could take up."""
    return _left_after_projection(*_difference(a, b, experiment), absorb)


def recommend(models: dict[str, EffectModel], ctx: Context, speed: float, noise_N: float,
              absorb=None, sample_hz: float = SAMPLE_HZ) -> dict:  # fmt: skip
    """The candidate experiment that best separates the two models in ``models``: the largest
    expected chi-square of the difference no re-fit could take up (``unabsorbed``; ``absorb(P,
    L)`` gives the model's parameter-correction columns over a candidate, None: a constant only),
    with the candidate recorded at ``sample_hz``."""
    (na, a), (nb, b) = list(models.items())[:2]
    scored = []
    for e in candidates(ctx, speed):
        try:
            d, L, P = _difference(a, b, e)  # the two models simulated once per candidate
            rms, peak = _spread(d)
            left = _left_after_projection(d, L, P, absorb)
        except ValueError:
            continue
        n = float(e.t[-1]) * sample_hz
        chi2 = n * (left / max(noise_N, 1e-9)) ** 2
        scored.append({"name": e.name, "protocol": e.words, "predicted_difference_rms_N": rms,
                       "predicted_difference_peak_N": peak, "ratio_to_noise": rms / max(noise_N, 1e-9),
                       "unabsorbed_rms_N": left, "expected_chi2": chi2,
                       "duration_s": float(e.t[-1])})  # fmt: skip
    scored.sort(key=lambda s: -s["expected_chi2"])
    best = scored[0] if scored else None
    words = ""
    if best and best["ratio_to_noise"] < 1.0:
        words = (
            f"No candidate experiment separates {na} and {nb}: the two fitted models predict forces differing "
            f"by at most {best['predicted_difference_rms_N']:.2f} N RMS ({best['name']}) against a noise floor of "
            f"{noise_N:.2f} N."
        )
    elif best:
        words = (
            f"Next experiment to separate {na} and {nb}: {best['name']} ({best['protocol']}); the two fitted "
            f"models predict forces differing by {best['predicted_difference_rms_N']:.2f} N RMS (peak "
            f"{best['predicted_difference_peak_N']:.2f} N; {best['unabsorbed_rms_N']:.2f} N RMS that no re-fit "
            f"of the model's parameters could take up) against a noise floor of {noise_N:.2f} N."
        )
    return {"contenders": [na, nb], "recommended": best, "candidates": scored, "words": words}


def experiment(name: str, ctx: Context, speed: float) -> Experiment:
    """The candidate experiment called ``name`` for these data."""
    for e in candidates(ctx, speed):
        if e.name == name:
            return e
    raise ValueError(f"unknown experiment '{name}'")


def stroke_speed(ctx: Context, labels) -> float:
    """Median speed (m/s) of the recorded strokes (5 mm/s when the length never moved)."""
    m = labels.moving & (labels.driver == 0)
    if m.sum() < 5:
        return 5e-3
    return float(np.median(np.abs(labels.rate[m]))) * ctx.muscle.rest_length_m
