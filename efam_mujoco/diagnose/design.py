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

One more is built for the pair itself, ``holds_where_apart`` (``focused``): an optimal design
for telling two models apart. Both are simulated on a survey of static set points inside the
recorded ranges, and the T-optimal weights (``t_optimal_weights``; Atkinson & Fedorov 1975)
pick the points where the difference that no re-fit of the weaker way round takes up is
largest; the test holds there in proportion to the weights. Its set points travel with the
recommendation (no name alone rebuilds it).

What of the difference between the two models' predicted forces the diagnosis could not take
up another way once the new test is added is the difference less its least-squares projection on
a constant (a load-cell zero), on the model's own parameter corrections linearised over the
candidate (``absorb``, ``model.linearise``: a difference a re-fit of the braid angle or dead band
reproduces separates nothing) and on the rival hypothesis's own amplitudes there (``rivals``: if
the data come from one hypothesis, the diagnosis re-fits the other on the joined data, and a
difference the rival's re-fit reproduces separates nothing either). Each way round counts
(``directions``) and the weaker decides, except where the rival contains the truth (``none``
inside any effect, a named model inside itself plus the data-driven correction): there the
rival's extra amplitudes fit about zero and only the other way round decides.

The score of a candidate is the expected outcome of the decision it feeds, not the raw
chi-square: the diagnosis of the old and new recordings together draws Bayesian-bootstrap weights
over blocks (``confidence``), so the unabsorbed squared difference is summed in the blocks the
new recording will be cut into (``blocks_of``: its half-cycles, in pieces while the joined data
have fewer than ``confidence.MIN_BLOCKS``) and ``decision_z`` gives the z of the truth's win
(one block, however large its difference, gives z = 1: a bootstrap over blocks cannot trust it;
the same difference over K blocks gives sqrt(K)), its spread widened by the noise's cross term.
The decision is the bootstrap's as it is made: an effect must beat ``none`` by the relevance
margin (``confidence.relevance_penalty``: 3 % of held-out RMS, about 6 % of the noise's mean
square in every new sample), and the truth's advantage in the blocks already recorded counts as
it stands (a weak effect the re-fit half absorbed starts behind, and the new test must overturn
that). A braid stretch of a third of the noise against ``none`` was recommended a test of
expected z 3.7 that left the joined data still split 51:49. Candidates
reaching ``Z_DECIDE`` all decide; among them the largest unabsorbed difference per sample
against the noise is recommended (robust to what the two fitted models leave out, and no test is
preferred for its length alone). When none reaches it, the best one followed by whichever of the
next three adds most (``"a then b"``; ``experiment`` builds it) is recommended if that raises
the expected z by 10 %; and a test still short of ``Z_DECIDE`` is repeated (``"a x3"``: the
whole run three times over, at most ``MAX_REPEATS`` times and ``MAX_TEST_S`` in all) as few
times as reach it, each repeat kept only while it raises the expected z by 10 % (it stops
paying once the data already recorded dominate). The recommendation states the predicted
difference in newtons (raw, and what is left after the projection), its peak, the noise floor,
the expected z and the test's duration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .confidence import MIN_BLOCKS, OUTSIDE, cut_runs, relevance_penalty
from .effects import Context, EffectModel
from .segment import label

SAMPLE_HZ = 50.0
#: expected decision z one test should reach; below it the best two are tried in sequence. Not
#: 3 (Phi(3) = 0.9987 on paper): the two fitted models leave part of the truth out, so the z a
#: test reaches falls short of the one expected. Of 36 tests tried on the 116000-117000 runs,
#: three expected at z 3.2-3.8 ended at p 0.42-0.78; a margin of one z pays for it
Z_DECIDE = 4.0
#: joins two candidate names into one experiment run one after the other
THEN = " then "
#: names a test run several times over (``"descending x3"``)
TIMES = " x"
#: the most times a test is repeated to reach ``Z_DECIDE``, and the longest the whole may last (s)
MAX_REPEATS = 4
MAX_TEST_S = 900.0
#: the optimal-design candidate: a grid of static set points inside the recorded ranges (lengths x
#: pressures), each held ``GRID_HOLD_S`` in a survey the two models are simulated on once; the
#: chosen points are then held ``FOCUS_S`` in all, in proportion to their design weights
GRID_LENGTHS = 5
GRID_PRESSURES = 6
GRID_HOLD_S = 4.0
FOCUS_S = 90.0
#: the name of the optimal-design candidate (its set points travel with the recommendation)
FOCUSED = "holds_where_apart"
#: whether the optimal-design candidate is offered (the benchmark turns it off to measure, side
#: by side, what it adds)
OFFER_OPTIMAL = True


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
    """A protocol written as moves: each ``go`` reaches its length and pressure set points
    linearly over ``dt`` seconds (at least 1 ms), starting vented at length ``L0``."""

    def __init__(self, L0):
        self.t, self.L, self.P = [0.0], [L0], [0.0]

    def go(self, dt, L=None, P=None):
        """Move to ``L`` (m) and ``P`` (Pa), each unchanged when None, over ``dt`` s."""
        self.t.append(self.t[-1] + max(dt, 1e-3))
        self.L.append(self.L[-1] if L is None else L)
        self.P.append(self.P[-1] if P is None else P)

    def pressure_cycle(self, P_top, up_s, hold_s, down_s, after_s):
        """Isometric: ramp to ``P_top`` over ``up_s``, hold, vent over ``down_s``, wait ``after_s``."""
        self.go(up_s, P=P_top)
        self.go(hold_s)
        self.go(down_s, P=0.0)
        self.go(after_s)

    def strokes(self, P, L_far, L_near, stroke_s, dwell_s, times=1, settle_s=5.0):
        """Step to pressure ``P`` and settle, then ``times`` strokes to ``L_far`` and back to
        ``L_near`` (``stroke_s`` each way), dwelling ``dwell_s`` at each end (None: no dwell)."""
        self.go(0.001, P=P)
        self.go(settle_s)
        for _ in range(times):
            for L in (L_far, L_near):
                self.go(stroke_s, L=L)
                if dwell_s is not None:
                    self.go(dwell_s)

    def done(self, name, words) -> Experiment:
        """The protocol as an ``Experiment`` called ``name``, described by ``words``."""
        return Experiment(name, words, np.array(self.t), np.array(self.L), np.array(self.P))


def candidates(ctx: Context, speed_m_per_s: float) -> list[Experiment]:
    """Candidate next experiments inside the ranges the recording covered."""
    rest = ctx.muscle.rest_length_m
    L_lo, L_hi = float(np.percentile(ctx.L, 1)), float(np.percentile(ctx.L, 99))
    P_top = max(float(np.percentile(ctx.P, 99)), 50e3)
    v = max(speed_m_per_s, 1e-3)
    kPa, lo_mm, hi_mm = f"{P_top / 1e3:.0f}", f"{L_lo * 1e3:.0f}", f"{L_hi * 1e3:.0f}"
    out = []

    def new(L0=L_lo) -> _Prog:
        p = _Prog(L0)
        p.go(2)  # every test starts with 2 s vented at the shortest recorded length
        return p

    # pressure-only tests at the shortest recorded length: always inside what the data covered
    p = new()
    p.pressure_cycle(P_top, 20, 60, 20, 30)
    out.append(p.done("pressure_hold", f"isometric ramp to {kPa} kPa, held 60 s, vented, 30 s at {lo_mm} mm"))
    p = new()
    for _ in range(3):
        p.pressure_cycle(P_top, 3, 1, 3, 1)
    out.append(p.done("fast_ramps", f"three fast isometric ramps 0-{kPa}-0 kPa (3 s each way) at {lo_mm} mm"))
    p = new()
    for k in list(range(1, 9)) + list(range(7, -1, -1)):
        p.go(0.001, P=P_top * k / 8)
        p.go(3)
    out.append(
        p.done(
            "staircase_rest", f"pressure staircase 8 steps to {kPa} kPa and down, 3 s holds, at {lo_mm} mm"
        )
    )
    if L_hi - L_lo < 0.05 * rest:
        return out  # an isometric test: strokes would ask the models where no data constrained them
    stroke = (L_hi - L_lo) / v
    p = new()
    p.strokes(P_top, L_hi, L_lo, stroke, 3, times=2)
    out.append(p.done("repeat_top", f"at {kPa} kPa, two slow strokes {lo_mm}-{hi_mm} mm"))
    p = new()
    for f in (1.0, 2 / 3, 1 / 3):
        p.strokes(f * P_top, L_hi, L_lo, stroke, 3)
    levels = f"{kPa}, {2 * P_top / 3e3:.0f}, {P_top / 3e3:.0f}"
    out.append(p.done("descending", f"pressures {levels} kPa in this order, one stroke each"))
    p = new()
    p.go(0.001, P=P_top)
    p.go(5)
    p.go(stroke / 3, L=L_hi)
    p.go(60)
    p.go(stroke / 3, L=L_lo)
    p.go(30)
    out.append(p.done("long_hold", f"at {kPa} kPa, a stroke held 60 s at {hi_mm} mm, then 30 s back"))
    p = new()
    for f in (0.5, 1.0):
        p.strokes(f * P_top, L_hi, L_lo, stroke / 4, 1, times=2)
    out.append(
        p.done("fast", f"strokes 4x faster ({4 * v * 1e3:.0f} mm/s) at {P_top / 2e3:.0f} and {kPa} kPa")
    )
    L_mid = L_lo + 0.6 * (L_hi - L_lo)
    p = new()
    p.go(abs(L_mid - L_lo) / v, L=L_mid)
    p.go(3)
    p.pressure_cycle(P_top, 20, 2, 20, 3)
    out.append(p.done("ramp_at_length", f"isometric ramp 0-{kPa}-0 kPa over 40 s at {L_mid * 1e3:.0f} mm"))
    p = new()
    p.strokes(P_top / 2, L_hi, L_lo, stroke, None)
    p.go(300)
    p.go(stroke, L=L_hi)
    p.go(stroke, L=L_lo)
    p.go(3)
    out.append(p.done("idle", f"five minutes at {P_top / 2e3:.0f} kPa between two strokes"))
    return out


def survey(ctx: Context, speed_m_per_s: float) -> tuple[Experiment, np.ndarray, np.ndarray]:
    """A tour of static set points inside the recorded ranges: at each of ``GRID_LENGTHS`` lengths
    (one when the test never moved the length), a pressure staircase of ``GRID_PRESSURES`` steps
    (``GRID_LENGTHS`` x ``GRID_PRESSURES`` at the one length of an isometric test) to the top
    recorded pressure, each held ``GRID_HOLD_S``, then vented. Returns the tour, the
    (length m, pressure Pa) of every point, and the point index of every sample at
    ``SAMPLE_HZ`` in the settled second half of its hold (-1 elsewhere)."""
    L_lo, L_hi = float(np.percentile(ctx.L, 1)), float(np.percentile(ctx.L, 99))
    P_top = max(float(np.percentile(ctx.P, 99)), 50e3)
    isometric = L_hi - L_lo < 0.05 * ctx.muscle.rest_length_m
    lengths = [L_lo] if isometric else list(np.linspace(L_lo, L_hi, GRID_LENGTHS))
    # at one length the pressure alone spans the survey: as many points as the grid has
    levels = GRID_LENGTHS * GRID_PRESSURES if isometric else GRID_PRESSURES
    v = max(speed_m_per_s, 1e-3)
    p = _Prog(L_lo)
    p.go(2)
    points, windows = [], []
    for L in lengths:
        p.go(abs(L - p.L[-1]) / v, L=L)
        for k in range(1, levels + 1):
            p.go(0.001, P=P_top * k / levels)
            p.go(GRID_HOLD_S)
            points.append((L, P_top * k / levels))
            windows.append((p.t[-1] - GRID_HOLD_S / 2, p.t[-1]))
        p.go(0.001, P=0.0)
        p.go(2)
    tour = p.done("survey", "static set points over the recorded lengths and pressures")
    t = tour.sampled()[0]
    where = np.full(len(t), -1)
    for i, (t0, t1) in enumerate(windows):
        where[(t >= t0) & (t < t1)] = i
    return tour, np.array(points), where


def t_optimal_weights(d: np.ndarray, ways: list[np.ndarray], iterations: int = 300) -> np.ndarray:
    """Design weights over candidate points that maximise what the weaker way round cannot take
    up: the T-optimal design for telling two models apart (Atkinson & Fedorov 1975), found by
    the vertex-direction algorithm. ``d``: the models' force difference at each point (N);
    ``ways``: for each way round, the columns a re-fit could move at each point (points x k).
    Every step weighs least squares of ``d`` on the weaker way's columns with the current weights
    and moves weight 1/(step + 2) towards the point its fit misses most."""
    d = np.asarray(d, float)
    if not np.all(np.isfinite(d)) or not all(np.all(np.isfinite(X)) for X in ways):
        raise ValueError("t_optimal_weights: a non-finite difference or column")
    n = len(d)
    w = np.full(n, 1.0 / n)
    scaled = [_informative(X) for X in ways]
    for step in range(iterations):
        worst, miss = math.inf, None
        for X in scaled:
            r = _weighted_residual(d, X, w)
            value = float(np.sum(w * r * r))
            if value < worst:
                worst, miss = value, r * r
        alpha = 1.0 / (step + 2)
        w = (1.0 - alpha) * w
        w[int(np.argmax(miss))] += alpha
    return w


def t_criterion(d: np.ndarray, ways: list[np.ndarray], w: np.ndarray) -> float:
    """The T-criterion of weights ``w``: the weighted mean square of ``d`` that the weaker way
    round's columns leave (what ``t_optimal_weights`` maximises)."""
    return min(float(np.sum(w * _weighted_residual(d, _informative(X), w) ** 2)) for X in ways)


def _informative(X: np.ndarray) -> np.ndarray:
    """``X`` (points x k) without the columns at rounding level (a correction that moves nothing
    at a static point; scaled to unit size it would let noise steer the design), each remaining
    column scaled to unit RMS."""
    X = np.asarray(X, float)
    size = np.sqrt(np.mean(X * X, axis=0)) if X.size else np.zeros(X.shape[1])
    keep = size > 1e-9 * max(float(size.max(initial=0.0)), 1e-300)
    return X[:, keep] / size[keep]


def _weighted_residual(d: np.ndarray, X: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``d`` less its weighted least-squares fit on the columns of ``X`` (weights ``w``)."""
    if not X.shape[1]:
        return d.copy()
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(X * sw[:, None], d * sw, rcond=1e-10)
    return d - X @ coef


def focused(a: EffectModel, b: EffectModel, ctx: Context, speed_m_per_s: float, columns) -> Experiment | None:
    """The optimal-design candidate: holds at the static set points where the two models differ
    in a way no re-fit takes up (``t_optimal_weights`` over the ``survey`` points; ``columns(t,
    L, P)`` gives, for each way round, the columns a re-fit could move), each held in proportion
    to its weight, ``FOCUS_S`` in all, visited by length then pressure, vented before each change
    of length as in the survey. None when a re-fit takes up the difference at every point."""
    tour, points, where = survey(ctx, speed_m_per_s)
    d, t, L, P = _difference(a, b, tour)
    keep = where >= 0
    n_pts = len(points)
    count = np.bincount(where[keep], minlength=n_pts).astype(float)
    if not np.any(np.abs(d[keep]) > 0) or np.any(count == 0):
        return None

    def settled(x):  # mean of each column over each point's settled samples (points x columns)
        x = x.reshape(len(x), -1)[keep]
        sums = [np.bincount(where[keep], weights=c, minlength=n_pts) for c in x.T]
        return (np.stack(sums, axis=1) if sums else np.zeros((n_pts, 0))) / count[:, None]

    ways = [np.column_stack([np.ones(n_pts), settled(np.asarray(c, float))]) for c in columns(t, L, P)]
    gap = settled(d)[:, 0]
    w = t_optimal_weights(gap, ways)
    if t_criterion(gap, ways, w) <= 1e-6 * float(np.mean(gap * gap)):
        return None  # a re-fit takes up the difference at every set point: nothing to hold for
    chosen = [i for i in np.argsort(-w) if w[i] >= 0.02][:8]
    if len(chosen) < 2:
        return None
    chosen.sort(key=lambda i: (points[i][0], points[i][1]))
    share = w[chosen] / w[chosen].sum()
    v = max(speed_m_per_s, 1e-3)
    p = _Prog(float(np.percentile(ctx.L, 1)))
    p.go(2)
    said = []
    for i, s in zip(chosen, share):
        Li, Pi = (float(x) for x in points[i])
        if Li != p.L[-1]:
            # as in the survey: vented, then the new length, then up to the set point (a
            # pressure-direction hysteresis sees each point approached as it was designed on)
            p.go(0.001, P=0.0)
            p.go(2)
            p.go(abs(Li - p.L[-1]) / v, L=Li)
        hold = max(2.0, FOCUS_S * s)
        p.go(0.001, P=Pi)
        p.go(hold)
        said.append(f"{Li * 1e3:.0f} mm/{Pi / 1e3:.0f} kPa {hold:.0f} s")
    p.go(0.001, P=0.0)
    p.go(2)
    return p.done(
        FOCUSED,
        "holds at the set points where the difference no re-fit takes up is largest (an optimal design; "
        "the set points are in the JSON report): " + ", ".join(said),
    )


def _difference(a: EffectModel, b: EffectModel, experiment: Experiment):
    """The two models' predicted force difference over ``experiment`` (N), with its t, L and P."""
    t, L, P = experiment.sampled()
    return a.push(t, L, P) - b.push(t, L, P), t, L, P


def _spread(d: np.ndarray) -> tuple[float, float]:
    d = d - d.mean()
    return float(np.sqrt(np.mean(d * d))), float(np.max(np.abs(d)))


def _left_series(d: np.ndarray, *columns) -> np.ndarray:
    """``d`` less its least-squares projection on a constant and on the given column blocks
    (n x k arrays; None or empty blocks are skipped)."""
    cols = [np.ones_like(d)]
    for J in columns:
        if J is not None:
            J = np.asarray(J, float)
            if J.ndim == 2 and J.shape[1]:
                cols.append(J)
    A = np.column_stack(cols)
    scale = np.sqrt(np.mean(A * A, axis=0)) + 1e-300
    coef, *_ = np.linalg.lstsq(A / scale, d, rcond=None)
    return d - (A / scale) @ coef


def separation(a: EffectModel, b: EffectModel, experiment: Experiment) -> tuple[float, float]:
    """(RMS of the predicted force difference less its mean, its peak), N."""
    return _spread(_difference(a, b, experiment)[0])


def unabsorbed(a: EffectModel, b: EffectModel, experiment: Experiment, absorb=None) -> float:
    """RMS (N) of the two models' predicted force difference over ``experiment`` left after its
    least-squares projection on a constant and on ``absorb(t, L, P)`` (columns: force changes a
    re-fit could make there: the model's own parameter corrections, the contenders' amplitudes),
    i.e. what no re-fit could take up."""
    d, t, L, P = _difference(a, b, experiment)
    left = _left_series(d, None if absorb is None else absorb(t, L, P))
    return float(np.sqrt(np.mean(left * left)))


def blocks_of(
    experiment: Experiment, muscle, hz: float = SAMPLE_HZ, half_cycles_before: int = 0
) -> np.ndarray:
    """Block index per sample of ``experiment`` sampled at ``hz``, as ``confidence.blocks`` will cut
    it once the new recording joins data that already had ``half_cycles_before`` half-cycles: its
    own half-cycles (``segment.label``), each cut into contiguous pieces until the joined data
    have ``confidence.MIN_BLOCKS``."""
    t, L, P = experiment.sampled(hz)
    ctx = Context(t, L, P, [0], muscle)
    labels = label(ctx.t, ctx.x, ctx.P, ctx.starts)
    half = labels.half_cycle if labels.half_cycle is not None else np.zeros(ctx.n, dtype=int)
    n_half = int(half.max()) + 1 if ctx.n else 0
    pieces = max(1, int(math.ceil(MIN_BLOCKS / max(n_half + half_cycles_before, 1))))
    return cut_runs(half, pieces, skip_empty=True)


def decision_z(block_gap: np.ndarray, noise_N: float, before=None, cost=None) -> float:
    """Expected z of the diagnosis's decision once a new recording is added: the Bayesian
    bootstrap over blocks (``confidence.bootstrap``) weighs each block's held-out squared error
    with independent unit-mean weights, so the truth beats the other hypothesis in a fraction
    ~ Phi(z) of its draws, with z = (sum_k a_k + sum_j D_j) / sqrt(sum_k (a_k^2 + 4 noise^2 S_k) +
    sum_j D_j^2) over the new blocks k and the old ones j. ``block_gap`` S_k, the squared force
    difference no re-fit takes up summed over each new block (N^2), adds S_k to the wrong
    hypothesis's error (the noise's cross term 4 noise^2 S_k to its spread), less ``cost`` c_k
    (the relevance margin an effect must beat ``none`` by, priced on the block's noise:
    a_k = S_k - c_k); ``before`` D_j, the truth's
    held-out advantage in each block of the data already recorded (the rival's squared error
    less the truth's, margins applied), counts as it stands: the joined data must overturn what
    the old data say. A difference spread over many blocks counts more than the same chi-square
    in one: one block decides nothing under the bootstrap."""
    S = np.asarray(block_gap, float)
    a = S - (0.0 if cost is None else np.asarray(cost, float))
    D = np.zeros(0) if before is None else np.asarray(before, float)
    spread = float(np.sum(a * a) + 4.0 * noise_N**2 * np.sum(S) + np.sum(D * D))
    return float((np.sum(a) + np.sum(D)) / math.sqrt(spread)) if spread > 0 else 0.0


def directions(na: str, nb: str) -> list[tuple[str, str]]:
    """(truth, rival) pairs whose re-fit decides between two hypotheses: each way round, except
    where the rival contains the truth (``none`` inside any effect, a named model inside the same
    model plus the data-driven correction): there the rival's extra amplitudes simply fit ~0 on the
    truth's data, and what decides is the other way round."""
    out = []
    for truth, rival in ((na, nb), (nb, na)):
        if truth == "none" or rival == OUTSIDE:
            continue
        out.append((truth, rival))
    return out or [(na, nb)]


def recommend(models: dict[str, EffectModel], ctx: Context, speed: float, noise_N: float,
              absorb=None, sample_hz: float = SAMPLE_HZ, before=None,
              half_cycles_before: int = 0, rivals: dict | None = None) -> dict:  # fmt: skip
    """The candidate experiment (or, when no single one is expected to decide, the best two run
    one after the other, repeated as often as it takes) that best separates the two models in
    ``models``. A candidate is scored by the expected z of the decision it feeds
    (``decision_z``): the difference of the two models' forces that no re-fit could take up
    (``unabsorbed``), summed in the blocks the diagnosis will cut the new recording into
    (``blocks_of``), recorded at ``sample_hz``. ``absorb(t, L, P)`` gives the columns the
    model's own parameter corrections move over a candidate (None: a constant only); ``rivals``
    maps a hypothesis to the columns its own amplitudes move there (its shapes and time constants
    as fitted): when the data come from one hypothesis, the other re-fits on the joined data, and
    only what neither re-fit takes up decides. Each way round (``directions``) is scored and the
    weaker one counts. ``before``: each hypothesis's held-out squared error per block of the data
    already recorded (the truth's advantage there counts in the decision, with the relevance
    margin an effect must beat ``none`` by: ``confidence.relevance_penalty``, priced on the new
    blocks too); ``half_cycles_before``: their half-cycle count.

    A test still short of ``Z_DECIDE`` is repeated (``repeated``: 2 to ``MAX_REPEATS`` times,
    at most ``MAX_TEST_S`` in all) until its expected z reaches it: a repeat adds blocks that
    the bootstrap weighs independently, so z grows about as the square root of the repeats
    while the spread of the data already recorded stays what it was."""
    (na, a), (nb, b) = list(models.items())[:2]
    rivals = rivals or {}
    ways = directions(na, nb)
    own_columns = [rivals.get(rival) for _, rival in ways]
    # each way round: how much more the truth's error weighs than the rival's in the bootstrap
    # (an effect against none: the relevance margin), and the truth's advantage in the old blocks
    weights = [relevance_penalty(truth) / relevance_penalty(rival) for truth, rival in ways]
    old_advantage = [
        None if before is None else np.asarray(before[rival]) - w * np.asarray(before[truth])
        for (truth, rival), w in zip(ways, weights)
    ]

    def way_columns(t, L, P):  # what a re-fit could move over a test, each way round
        model_cols = None if absorb is None else absorb(t, L, P)  # shared by both ways round
        return [np.column_stack([c for c in (model_cols, None if own is None else own(t, L, P)) if c is not None]
                                or [np.zeros((len(t), 0))]) for own in own_columns]  # fmt: skip

    def score(e: Experiment) -> dict:
        """The expected outcome of running ``e`` (the weaker way round decides)."""
        d, t, L, P = _difference(a, b, e)  # the two models simulated once per candidate
        rms, peak = _spread(d)
        block = blocks_of(e, ctx.muscle, SAMPLE_HZ, half_cycles_before)
        lefts = [_left_series(d, cols) for cols in way_columns(t, L, P)]
        # block sums at the recorded rate (simulated at SAMPLE_HZ), each way round
        way_gaps = [np.bincount(block, weights=ls**2) * (sample_hz / SAMPLE_HZ) for ls in lefts]
        samples = np.bincount(block) * (sample_hz / SAMPLE_HZ)
        zs = [
            decision_z(g, noise_N, old, (w - 1.0) * samples * noise_N**2)
            for g, old, w in zip(way_gaps, old_advantage, weights)
        ]
        weak = int(np.argmin(zs))
        left = float(np.sqrt(np.mean(lefts[weak] ** 2)))
        return {"name": e.name, "protocol": e.words, "predicted_difference_rms_N": rms,
                "predicted_difference_peak_N": peak, "ratio_to_noise": rms / max(noise_N, 1e-9),
                "unabsorbed_rms_N": left, "expected_chi2": float(e.t[-1]) * sample_hz * (left / max(noise_N, 1e-9)) ** 2,
                "blocks": int(len(way_gaps[weak])), "expected_z": zs[weak], "duration_s": float(e.t[-1]),
                "repeats": 1}  # fmt: skip

    tests, scored = {}, []
    try:
        optimal = focused(a, b, ctx, speed, way_columns) if OFFER_OPTIMAL else None
    except ValueError:
        optimal = None
    for e in candidates(ctx, speed) + ([optimal] if optimal is not None else []):
        try:
            scored.append(score(e))
        except ValueError:
            continue
        tests[e.name] = e
    # past Z_DECIDE the bootstrap decides whatever the test: among those that
    # decide, the largest difference per sample against the noise (robust to what the two fitted
    # models leave out, and a long test is not preferred for its length alone)
    scored.sort(key=lambda s: (-min(s["expected_z"], Z_DECIDE), -s["unabsorbed_rms_N"]))
    best = scored[0] if scored else None
    chosen = tests[best["name"]] if best else None
    # one test not expected to decide: the best followed by whichever of the next three adds most
    if best and best["expected_z"] < Z_DECIDE and len(scored) >= 2:
        pairs = [joined(chosen, tests[s["name"]]) for s in scored[1:4]]
        pair_scores = [score(e) for e in pairs]
        k = int(np.argmax([s["expected_z"] for s in pair_scores]))
        if _raises(pair_scores[k]["expected_z"], best["expected_z"]):
            best, chosen = pair_scores[k], pairs[k]
    # still short: the same test again, as few times as reach Z_DECIDE (not when even
    # MAX_REPEATS runs, z growing as sqrt(repeats), could not reach z 1: a long test deciding nothing)
    if best and 1.0 / math.sqrt(MAX_REPEATS) <= best["expected_z"] < Z_DECIDE:
        for times in range(2, MAX_REPEATS + 1):
            if times * float(chosen.t[-1]) > MAX_TEST_S:
                break
            again = score(repeated(chosen, times))
            if not _raises(again["expected_z"], best["expected_z"]):
                break  # the data already recorded dominate (their spread, their margin): repeats do not pay
            best = {**again, "repeats": times}
            if again["expected_z"] >= Z_DECIDE:
                break
    if best:
        # the set points travel with the recommendation: the optimal-design holds are built from
        # the two fitted models, and no name alone rebuilds them (``experiment`` takes these)
        final = repeated(chosen, best["repeats"]) if best["repeats"] > 1 else chosen
        best = dict(best)  # not the candidate's own entry: the set points are written once
        best["set_points"] = {"time_s": final.t.tolist(), "length_m": final.L.tolist(),
                              "pressure_Pa": final.P.tolist()}  # fmt: skip
    words = ""
    if best and best["ratio_to_noise"] < 1.0 and best["repeats"] == 1:
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
            f"of the model's parameters or of the rival's amplitudes could take up) against a noise floor of "
            f"{noise_N:.2f} N; expected decision z {best['expected_z']:.1f} over {best['blocks']} blocks "
            f"({best['duration_s']:.0f} s)."
        )
        if best["expected_z"] < 1.0:
            # a bootstrap win fraction under Phi(1) = 0.84: the test is the best on offer, not a decision
            words += (
                " Not expected to decide (expected z under 1): on every candidate, what separates these two "
                "fitted models is mostly what a re-fit takes up or lies within the noise."
            )
    return {"contenders": [na, nb], "recommended": best, "candidates": scored, "words": words}


def _raises(z_new: float, z_old: float) -> bool:
    """A longer test is worth it: it raises the expected z by 10 % and above 0."""
    return z_new > 0.0 and z_new > z_old + 0.1 * abs(z_old)


def joined(first: Experiment, second: Experiment, name: str | None = None) -> Experiment:
    """``first`` then ``second`` (its set points shifted in time after the first's)."""
    t = np.r_[first.t, first.t[-1] + 1e-3 + second.t]
    return Experiment(name or f"{first.name}{THEN}{second.name}", f"{first.words}; then {second.words}", t,
                      np.r_[first.L, second.L], np.r_[first.P, second.P])  # fmt: skip


def repeated(test: Experiment, times: int) -> Experiment:
    """``test`` run ``times`` times one after the other, named ``"<name> x<times>"``."""
    out = test
    for _ in range(times - 1):
        out = joined(out, test)
    return Experiment(f"{test.name}{TIMES}{times}", f"{test.words}; the whole run {times} times over", out.t,
                      out.L, out.P)  # fmt: skip


def experiment(name: str, ctx: Context, speed: float, set_points: dict | None = None) -> Experiment:
    """The candidate experiment called ``name`` for these data; ``"a then b"``: the two run one
    after the other; ``"<test> x3"``: the test run three times over. ``set_points``: the
    recommendation's own (``time_s``, ``length_m``, ``pressure_Pa``), which any name may carry and
    a test holding ``FOCUSED`` (built from the two fitted models) needs."""
    if set_points is not None:
        return Experiment(name, name, *_checked_set_points(name, set_points))
    if FOCUSED in name:
        raise ValueError(
            f"'{name}' is built from the two fitted models: give the recommendation's set_points"
        )
    head, times, count = name.rpartition(TIMES)
    if times and count.isdigit():
        return repeated(experiment(head, ctx, speed), int(count))
    if THEN in name:
        first, second = (experiment(part, ctx, speed) for part in name.split(THEN, 1))
        return joined(first, second, name)
    for e in candidates(ctx, speed):
        if e.name == name:
            return e
    raise ValueError(f"unknown experiment '{name}'")


def _checked_set_points(name: str, set_points: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (time s, length m, pressure Pa) arrays of a recommendation's ``set_points``, refused
    with the key and the problem when they cannot be a test."""
    out = []
    for key in ("time_s", "length_m", "pressure_Pa"):
        if key not in set_points:
            raise ValueError(f"set points of '{name}': no '{key}'")
        try:
            a = np.asarray(set_points[key], dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"set points of '{name}': '{key}' is not a list of numbers") from None
        if a.ndim != 1 or len(a) < 2 or not np.all(np.isfinite(a)):
            raise ValueError(f"set points of '{name}': '{key}' must be at least 2 finite numbers")
        out.append(a)
    t, L, P = out
    if not len(t) == len(L) == len(P):
        raise ValueError(f"set points of '{name}': time_s, length_m and pressure_Pa differ in length")
    if np.any(np.diff(t) < 0):
        raise ValueError(f"set points of '{name}': time_s goes backwards")
    if np.any(L <= 0) or np.any(P < 0):
        raise ValueError(f"set points of '{name}': a length at or under 0 m or a pressure under 0 Pa")
    return t, L, P


def stroke_speed(ctx: Context, labels) -> float:
    """Median speed (m/s) of the recorded strokes (5 mm/s when the length never moved)."""
    m = labels.moving & (labels.driver == 0)
    if m.sum() < 5:
        return 5e-3
    return float(np.median(np.abs(labels.rate[m]))) * ctx.muscle.rest_length_m
