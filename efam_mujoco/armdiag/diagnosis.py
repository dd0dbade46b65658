"""The arm diagnosis: re-fit, locate, try every library effect, choose with held-out blocks.

1. **Folds.** The recording is cut into 6 contiguous time blocks; blocks 2 and 5 are held out
   (they touch no fit, no noise estimate, no choice of start values). Rows with a marker dropout
   are in neither.
2. **Re-fit** what the model already has, within calibration bounds (``effects.refit_params``).
3. **Effects.** Every library effect is fitted on top of the re-fit on the training blocks
   (start grid and one local step; the four with the smallest training error then get the rest
   of the local search);
   per-muscle effects are screened on their start grid for every muscle (on the first
   :data:`SCREEN_S` of the recording), the :data:`SCREENED_OPTIONS` best then get a local step
   on every training row and the better is kept.
4. **Choice.** Each hypothesis h (``none`` = the re-fit alone) gets a held-out score
   ``-n_eff/2 log SSE_h - k_h/2 log n_eff`` (k_h: its parameters, plus the log of the number of
   ways to place it: muscles, or muscle pairs; n_eff: held-out samples divided by the residual's
   correlation length); probabilities are ``exp(score / T)`` normalised, T calibrated on seeds
   disjoint from the benchmark's. A model that already reproduces the held-out blocks within
   1.25 x the marker noise needs no effect.
5. **Ambiguity** is a paired held-out comparison (:func:`paired_comparison`): the held-out rows
   cut into contiguous segments of at least the loss difference's correlation length, the
   runner-up's per-segment log error ratio over the best's, a one-sided Student t; ambiguous
   when the runner-up is not worse at the 95 % level. With ``none`` first and an effect second
   that is *better* at that level, the data have spoken for the effect: it is the answer
   (:func:`choose`). Confident when the probability is >= 0.8 and it is not ambiguous.
6. **Next experiment** for every ambiguous answer (``design.recommend``).

**Coarse to fine in time** (long recordings). Steps 2 and 3 (the re-fit, every start grid,
screen and local step) run on a *search window*: the shortest head of the recording made of
whole blocks whose training blocks add up to :data:`WINDOW_TRAIN_S` of training time (at 60 s:
the first block, 0-10 s). The fitted hypotheses are then replayed once each on the whole
recording, and everything from step 4 on (held-out scores, probabilities, the paired
comparison, the reported training and held-out errors, the located mismatch) uses those
whole-recording replays: the held-out blocks lie beyond the window, so the verdict sees data no
search touched. The parameters are constants of the arm, and 10 s of training rows is what
every benchmark recording (15 s, four 2.5 s training blocks) is diagnosed from; a 60 s
recording then costs about a fifth of its simulated time. A recording with no more than
:data:`WINDOW_TRAIN_S` of training time (up to 15 s long, as the benchmark's) is searched
whole, exactly as before the rule.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..recordings import comment_report
from ..units import PRESSURE, split_unit
from . import design
from .effects import LIBRARY, get, refit_knobs, refit_params
from .fit import FitResult, fit, residual
from .locate import locate, noise_floor
from .recording import (
    MIN_COMMAND_SHARE,
    TIME,
    TYPICAL_INTERVAL_S,
    ArmRecording,
    ArmRecordingError,
    ArmRecordingWarning,
    check_against_model,
    shown_path,
    unit_hint,
    units_putting,
)
from .replay import SETTLE_S, Knobs, Replayer, default_threads, with_values
from .specfile import model_limits

BLOCKS = 6
HELD_OUT_BLOCKS = (1, 4)
CONFIDENT = 0.8
NOISE_MARGIN = 1.25
ITERATIONS = 3
#: every effect gets its start grid and FIRST_ITERATIONS local steps; the FULLY_FITTED effects
#: with the smallest training error get the rest of the ITERATIONS
FIRST_ITERATIONS = 1
FULLY_FITTED = 4
#: per-muscle and per-pair options are screened on the recording's first SCREEN_S seconds (the
#: whole recording when shorter): three of the six folds, two of them training blocks, at 60 s
#: (a long recording's screens run on its search window, shorter than this)
SCREEN_S = 30.0
#: per-muscle and per-pair options: this many of the best screened get a local step (see
#: ``_fit_effect``)
SCREENED_OPTIONS = 2
#: coarse to fine in time: the search (re-fit, grids, screens, local steps) sees the shortest
#: head of the recording with this much training time (whole training blocks); the held-out
#: verdict always sees the whole recording (see the module docstring)
WINDOW_TRAIN_S = 10.0
#: the paired held-out comparison (:func:`paired_comparison`): held-out rows cut into contiguous
#: segments (at least one correlation length of the loss difference each, between these counts);
#: the runner-up is told apart from the best when its per-segment log error ratio is positive at
#: this one-sided level (Student t)
SEGMENTS_MIN, SEGMENTS_MAX = 8, 32
#: Longest replay (settling included) the diagnosis starts, in time steps of the arm model. Every
#: rollout keeps the full state and the sensors at every step for every variant of its batch
#: (about 1 kB per step for the 1x3 arm), the whole-recording replays batch a dozen variants, and
#: the search replays its window a few hundred times: 200 000 steps (200 s at the default arm's
#: 1 ms) is some 200 MB per variant and tens of minutes of CPU. The parameters are constants of the
#: arm, found from the first 10 s of training time, so a longer recording adds little: cut it. A
#: recording in ms under a 's' header (a 6 s test reads as 6000 s) is far beyond the bound and is
#: refused here, before any rollout, with the unit that fits.
MAX_REPLAY_STEPS = 200_000
#: t reported when every segment gives the same nonzero log ratio (finite, for JSON)
T_SURE = 1e6
PAIRED_LEVEL = 0.95
#: probabilities are exp(score / T) normalised: T fitted (maximum likelihood of the concealed truth)
#: on 18 calibration recordings of 30 s (9 per bench arm), seeds 76000+, disjoint from the benchmark's
#: evaluation seeds (``python bench/bench_armdiag.py``, "calibration" in bench/results/armdiag.json)
PROBABILITY_TEMPERATURE = 5.01
#: P(none is right) when the re-fitted model is already at the noise floor (same calibration set:
#: 2 of 2 at-floor recordings were clean, Laplace-smoothed (2 + 1) / (2 + 2))
P_NONE_AT_FLOOR = 0.75


@dataclass
class ArmDiagnosis:
    """What :func:`diagnose_arm` found; ``to_json`` has the muscle diagnosis's keys (tip errors
    in m instead of forces in N) plus ``muscle`` per effect, probabilities and the verdict."""

    effects: list[dict]
    rms_before_m: float
    rms_after_m: float
    heldout_rms_before_m: float
    heldout_rms_after_m: float
    heldout_rms_nominal_m: float
    noise_m: float
    located: dict
    candidates: list[dict]
    decisions: dict
    refit: dict
    probabilities: dict
    verdict: dict
    next_experiment: dict | None
    seconds: float
    n_samples: int
    sources: list[str]
    knobs_before: Knobs = field(repr=False, default=None)
    knobs_after: Knobs = field(repr=False, default=None)
    time_s: np.ndarray = field(repr=False, default=None)
    measured: np.ndarray = field(repr=False, default=None)
    tip_nominal: np.ndarray = field(repr=False, default=None)
    tip_before: np.ndarray = field(repr=False, default=None)
    tip_after: np.ndarray = field(repr=False, default=None)
    heldout: np.ndarray = field(repr=False, default=None)
    candidate_tips: dict = field(repr=False, default=None)  # hypothesis -> replayed tip (samples, 3)

    @property
    def names(self) -> list[str]:
        """Names of the effects the diagnosis kept."""
        return [e["name"] for e in self.effects]

    def to_json(self) -> dict:
        """The diagnosis as plain JSON types (the muscle diagnosis keys, tip errors in m, plus ``muscle``)."""
        keys = (
            "effects", "rms_before_m", "rms_after_m", "heldout_rms_before_m", "heldout_rms_after_m",
            "heldout_rms_nominal_m", "noise_m", "located", "candidates", "decisions", "refit",
            "probabilities", "verdict", "next_experiment", "n_samples", "seconds", "sources",
        )  # fmt: skip
        return {k: _jsonable(getattr(self, k)) for k in keys}


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def check_replay_work(rec: ArmRecording, timestep_s: float, settle_s: float = SETTLE_S) -> int:
    """The time steps of one replay of ``rec`` (settling included) with the model's step;
    :class:`.recording.ArmRecordingError` naming the time column when beyond
    :data:`MAX_REPLAY_STEPS` (with the unit its numbers fit, a unit mix-up being the usual cause)."""
    steps = int(round(settle_s / timestep_s)) + int(math.floor(rec.duration_s / timestep_s)) + 1
    if steps > MAX_REPLAY_STEPS:
        column = rec.meta.get("time_column", "time_s")
        interval = float(np.median(np.diff(rec.time_s)))
        longest = (MAX_REPLAY_STEPS - 1) * timestep_s - settle_s
        hint = unit_hint(column, interval, TYPICAL_INTERVAL_S, TIME)
        raise ArmRecordingError(
            f"{rec.meta.get('source', 'recording')}: column '{column}': the recording spans "
            f"{rec.duration_s:.4g} s ({interval:.4g} s between samples): one replay is {steps} steps of "
            f"the model's {timestep_s * 1e3:g} ms, beyond the diagnosis's limit of {MAX_REPLAY_STEPS} "
            f"(memory and time for a few hundred replays)"
            + (f"; a time unit mix-up?{hint}" if hint else "")
            + f"; otherwise cut the recording to its first {longest:.0f} s (the search uses its first 10 s "
            "of training time)"
        )
    return steps


def folds(time_s: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(training rows, held-out rows): contiguous time blocks, dropouts in neither."""
    edges = np.linspace(time_s[0], time_s[-1], BLOCKS + 1)
    block = np.clip(np.searchsorted(edges, time_s, side="right") - 1, 0, BLOCKS - 1)
    held = np.isin(block, HELD_OUT_BLOCKS)
    return valid & ~held, valid & held


def search_window_s(time_s: np.ndarray) -> float | None:
    """Length (s from the first sample) of the search window: the shortest head of the recording
    made of whole blocks whose training blocks add up to :data:`WINDOW_TRAIN_S`; None when that
    is the whole recording (it is then searched whole)."""
    block_s = (time_s[-1] - time_s[0]) / BLOCKS
    trained = 0.0
    for b in range(BLOCKS - 1):  # the last block ends the recording: no window
        trained += 0.0 if b in HELD_OUT_BLOCKS else block_s
        if trained >= WINDOW_TRAIN_S - 1e-3 * block_s:  # (sample times: a block is a hair short)
            return float((b + 1) * block_s)
    return None


def _rms(x) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _correlation_length(r: np.ndarray) -> float:
    """1 + 2 sum of the residual's autocorrelation (per coordinate, averaged), in samples."""
    out = []
    for col in r.T:
        c = col - col.mean()
        v = float(c @ c)
        if v <= 0:
            continue
        total, lag = 1.0, 1
        while lag < len(c) // 4:
            rho = float(c[:-lag] @ c[lag:]) / v
            if rho < 0.05:
                break
            total += 2 * rho
            lag += 1
        out.append(total)
    return float(np.mean(out)) if out else 1.0


#: commands read in another pressure unit must bring the nominal replay's tip error under this
#: share of its error as read (and by at least ``COMMAND_UNIT_MATERIAL_M``) to be called a unit
#: mix-up: the muscle recordings' ``pressure-unit`` rule (``recordings.UNIT_ERROR_SHARE``)
COMMAND_UNIT_SHARE = 0.3
#: ... and warned of (not refused) when so read it leaves under this share: a recording far from
#: the nominal arm (a payload, a stiffer sleeve) halves a unit's advantage, and 75 psi read as
#: 75 kPa then left 119 mm against 59 mm read in psi, without a word
COMMAND_UNIT_WARN_SHARE = 0.6
COMMAND_UNIT_MATERIAL_M = 5e-3


def _check_command_unit(replayer: Replayer, rec: ArmRecording, valid: np.ndarray) -> None:
    """Refuse commands written in another pressure unit than their header's when the nominal
    arm follows the recorded tip far better with them so read (psi under a kPa header: 75 psi
    read as 75 kPa barely bends the arm). Only units that keep the largest command inside the
    model's range and above ``MIN_COMMAND_SHARE`` of it are tried, as the muscles' gains of one
    batched replay: a test commanded at the usual pressures tries none and costs nothing."""
    columns = rec.meta.get("command_columns") or [f"p_{m}_Pa" for m in rec.muscles]
    unit = split_unit(columns[0])[1]
    top = float(np.max(replayer.max_Pa))
    highest = float(np.nanmax(rec.command_Pa)) if rec.command_Pa.size else 0.0
    if unit not in PRESSURE or not (math.isfinite(top) and highest > 0):
        return
    number = highest / PRESSURE[unit]  # the largest command as written
    options = [
        (u, PRESSURE[u] / PRESSURE[unit])
        for u in units_putting(number, MIN_COMMAND_SHARE * top, top)
        if u != unit
    ]
    if not options:
        return
    nominal = replayer.nominal
    variants = [nominal] + [with_values(nominal, gain=tuple(g * f for g in nominal.gain)) for _, f in options]
    tips = replayer.tips(variants)
    errors = [float(np.sqrt(np.mean((t[valid] - rec.tip_m[valid]) ** 2))) for t in tips]
    k = int(np.argmin(errors[1:]))
    as_read, best = errors[0], errors[1 + k]
    if as_read - best <= COMMAND_UNIT_MATERIAL_M or best >= COMMAND_UNIT_WARN_SHARE * as_read:
        return
    name = columns[0]
    words = (
        f"{shown_path(rec.meta.get('source', 'recording'))}: column '{name}': the model arm follows the recorded "
        f"tip with {best * 1e3:.3g} mm RMS if the commands were in {options[k][0]} against {as_read * 1e3:.3g} mm "
        f"as read in {unit}: is the columns' unit right? the numbers fit '{split_unit(name)[0]}_{options[k][0]}'"
    )
    if best < COMMAND_UNIT_SHARE * as_read:
        raise ArmRecordingError(words)
    warnings.warn(words + " (diagnosed as read)", ArmRecordingWarning, stacklevel=3)


def diagnose_arm(
    spec, recording: ArmRecording, threads: int | None = None, effects: tuple[str, ...] | None = None
) -> ArmDiagnosis:
    """Diagnose one arm recording against the arm model ``spec`` (an :class:`mujoco.MjSpec` from
    :func:`.specfile.load_arm_model` or :func:`efam_mujoco.arm.build_spec`)."""
    clock = time.process_time()
    rec = recording
    limits = model_limits(spec)
    if skipped := comment_report(rec):  # a commented-out sample is not replayed: said, as for a muscle
        warnings.warn(skipped, ArmRecordingWarning, stacklevel=2)
    for note in check_against_model(rec, limits["max_command_Pa"], limits["base_m"], limits["rest_reach_m"]):
        warnings.warn(note, ArmRecordingWarning, stacklevel=2)
    check_replay_work(rec, limits["timestep_s"])
    replayer = Replayer(spec, rec.time_s, rec.command_Pa, threads=threads or default_threads())
    if replayer.muscles != rec.muscles:
        raise ValueError(
            f"recording muscles {rec.muscles} differ from the model's actuators {replayer.muscles}"
        )
    measured = rec.tip_m
    valid = rec.valid
    train, held = folds(rec.time_s, valid)
    if train.sum() < 20 or held.sum() < 10:
        raise ValueError(f"{rec.meta.get('source', 'recording')}: too few tip samples to hold any out")
    noise = noise_floor(rec.time_s, np.where(train[:, None], measured, np.nan))
    _check_command_unit(replayer, rec, valid)
    M = len(rec.muscles)

    # 2. the re-fit, on the search window (the whole recording unless it is long)
    window_s = search_window_s(rec.time_s)
    search = replayer if window_s is None else replayer.head(window_s)
    n_w = len(search.time_s)
    w_measured, w_train = measured[:n_w], train[:n_w]
    nominal = replayer.nominal
    rparams = refit_params(M)
    base = fit(search, rparams, lambda v: refit_knobs(nominal, v), w_measured, w_train, iterations=3)

    # 3. the effects
    library = [e for e in LIBRARY if effects is None or e.name in effects]
    fits: dict[str, tuple[FitResult, int | None]] = {}
    directions: dict[str, np.ndarray] = {}
    for effect in library:  # every effect: its start grid and a first local step
        fits[effect.name] = _fit_effect(effect, search, base, nominal, w_measured, w_train, M, directions)
    # the rest of the local search only for the effects that fit the training rows best: a term
    # far behind after its grid and first step is not the answer, and the comparison that
    # matters (the best against the runner-up) is between fully fitted hypotheses
    leaders = sorted(fits, key=lambda n: fits[n][0].sse_train)[:FULLY_FITTED]
    for name in leaders:
        f, option = fits[name]
        effect = get(name)
        more = fit(search, effect.params, _maker(effect, nominal, option), w_measured, w_train,
                   shared=base, iterations=ITERATIONS - FIRST_ITERATIONS, resume=f)  # fmt: skip
        fits[name] = (more, option)
    if search is replayer:
        tip_nominal = replayer.tips([nominal])[0]
    else:  # fine: every hypothesis replayed once on the whole recording (one batch)
        whole = replayer.tips([nominal, base.knobs] + [f.knobs for f, _ in fits.values()])
        tip_nominal = whole[0]

        def on_whole(f: FitResult, tip: np.ndarray) -> FitResult:
            return replace(f, tip=tip, sse_train=float(np.sum(residual(tip, measured, train) ** 2)))

        base = on_whole(base, whole[1])
        fits = {n: (on_whole(f, t), o) for (n, (f, o)), t in zip(fits.items(), whole[2:])}
        for key, d in directions.items():  # NaN where nothing was replayed
            directions[key] = np.vstack([d, np.full((len(measured) - len(d), 3), np.nan)])
    # 4. the choice
    sse_held = {"none": float(np.sum((base.tip[held] - measured[held]) ** 2))}
    for name, (f, _) in fits.items():
        sse_held[name] = float(np.sum((f.tip[held] - measured[held]) ** 2))
    n_held = int(held.sum()) * 3
    best_name = min(sse_held, key=sse_held.get)
    best_tip = base.tip if best_name == "none" else fits[best_name][0].tip
    corr_len = _correlation_length((best_tip - measured)[held])
    n_eff = max(3.0, n_held / corr_len)
    score = {}
    for name, sse in sse_held.items():
        k = (
            0
            if name == "none"
            else fits[name][0].n_params + math.log(_options(get(name), M, replayer.groups))
        )
        score[name] = -0.5 * n_eff * math.log(max(sse, 1e-30)) - 0.5 * k * math.log(n_eff)
    prob = probabilities(score)
    heldout_none = math.sqrt(sse_held["none"] / n_held)
    tips_of = {"none": base.tip} | {n: f.tip for n, (f, _) in fits.items()}
    best_effect = max((n for n in score if n != "none"), key=score.get, default=None)
    # at the noise floor: none, unless the best effect is better on the held-out segments (paired)
    at_floor = heldout_none <= NOISE_MARGIN * noise
    if at_floor and best_effect is not None and score[best_effect] > score["none"]:
        vs_none = paired_comparison(tips_of[best_effect], base.tip, measured, held)
        at_floor = vs_none["t"] < vs_none["critical_t"]
    if at_floor:
        rest = (1 - P_NONE_AT_FLOOR) / max(1, len(prob) - 1)
        prob = {"none": P_NONE_AT_FLOOR} | {k: rest for k in prob if k != "none"}
    first, second, paired, ambiguous, beats_none = choose(prob, tips_of, measured, held, at_floor)
    confident = prob[first] >= CONFIDENT and not ambiguous
    verdict = {
        "answer": first, "probability": prob[first], "confident": confident, "ambiguous": ambiguous,
        "alternatives": [second] if ambiguous else [], "n_eff": n_eff, "paired": paired,
        # no library term pays, yet the re-fitted model stays well above the marker noise
        "unexplained": first == "none" and heldout_none > 3 * noise,
        "reason": "the re-fitted model reproduces the held-out blocks at the noise floor" if at_floor else
        "better than none on the held-out segments (paired test), though its parameter penalty ranks "
        "none first" if beats_none else "held-out likelihood with a parameter penalty",
    }  # fmt: skip
    candidates = []
    for name in prob:  # largest probability first
        f = base if name == "none" else fits[name][0]
        candidates.append({
            "name": name, "probability": prob[name], "heldout_rms_m": math.sqrt(sse_held[name] / n_held),
            "rms_m": _rms((f.tip - measured)[train]), "delta_score": score[first] - score[name],
            "score": score[name],
            **_muscles(rec.muscles, None if name == "none" else fits[name][1]),
            "parameters": {} if name == "none" else _own(name, f.values),
        })  # fmt: skip
    found = []
    after = base
    if first != "none":
        f, muscle = fits[first]
        after = f
        e = get(first)
        found.append({
            "name": first, "parameters": _own(first, f.values), "refit_parameters": _shared(first, f.values),
            **_muscles(rec.muscles, muscle),
            "heldout_rms_before_m": heldout_none, "heldout_rms_after_m": math.sqrt(sse_held[first] / n_held),
            "equation": e.equation, "summary": e.summary, "delta_bic": score["none"] - score[first],
            "identifiable": not ambiguous, "probability": prob[first], "switch_on": e.switch_on,
        })  # fmt: skip
    located = locate(
        rec.time_s,
        rec.command_Pa,
        rec.muscles,
        replayer.groups,
        base.tip - measured,
        valid,
        noise,
        directions,
    )
    next_exp = None
    if ambiguous and first != "none" or (ambiguous and second != "none"):
        hyp = {n: (base.knobs if n == "none" else fits[n][0].knobs) for n in (first, second)}
        next_exp = design.recommend(replayer, hyp, noise)
    return ArmDiagnosis(
        effects=found,
        rms_before_m=_rms((base.tip - measured)[train]),
        rms_after_m=_rms((after.tip - measured)[train]),
        heldout_rms_before_m=heldout_none,
        heldout_rms_after_m=math.sqrt(sse_held[first] / n_held),
        heldout_rms_nominal_m=_rms((tip_nominal - measured)[held]),
        noise_m=noise,
        located=located,
        candidates=candidates,
        decisions={
            "held_out_blocks": [b + 1 for b in HELD_OUT_BLOCKS],
            "blocks": BLOCKS,
            "train_samples": int(train.sum()),
            "heldout_samples": int(held.sum()),
            "search_window_s": window_s,
            "rollouts": replayer.rollouts,
            "simulated_s": replayer.simulated_s,
            "unstable_variants": replayer.unstable,
            "mujoco_warnings_caught": replayer.warnings,
        },  # fmt: skip
        refit={"parameters": base.values, "bounds": {p.key: [p.lo, p.hi] for p in rparams}},
        probabilities=prob,
        verdict=verdict,
        next_experiment=next_exp,
        seconds=time.process_time() - clock,
        n_samples=len(rec),
        sources=[rec.meta.get("source", "")],
        knobs_before=base.knobs,
        knobs_after=after.knobs,
        time_s=rec.time_s,
        measured=measured,
        tip_nominal=tip_nominal,
        tip_before=base.tip,
        tip_after=after.tip,
        heldout=held,
        candidate_tips=tips_of,
    )


def probabilities(score: dict, temperature: float | None = None) -> dict:
    """Normalised exp(score / T), largest first (T: :data:`PROBABILITY_TEMPERATURE`)."""
    T = PROBABILITY_TEMPERATURE if temperature is None else temperature
    top = max(score.values())
    weights = {k: math.exp((v - top) / T) for k, v in score.items()}
    total = sum(weights.values())
    return {k: w / total for k, w in sorted(weights.items(), key=lambda kv: -kv[1])}


def choose(prob: dict, tips_of: dict, measured, held, at_floor: bool) -> tuple[str, str, dict, bool, bool]:
    """(answer, runner-up, their paired comparison, ambiguous, overruled) from the probabilities
    (largest first) and the paired held-out test (:func:`paired_comparison`, answer against
    runner-up).

    The answer is the most probable hypothesis, with one exception: when that is ``none``, the
    model is not at the noise floor, and the runner-up is better than ``none`` on the held-out
    segments beyond chance, the data have separated the two in the effect's favour (only its
    parameter penalty ranks it second): the effect is the answer (``overruled``; its probability
    stays as computed, below the confidence bar). At the noise floor the same question was
    already asked of the best effect (``at_floor`` is False when it won). An effect answer is
    ambiguous when the runner-up is not clearly worse; a ``none`` answer never is (nothing
    separated from it does better)."""
    ranked = list(prob)
    first, second = ranked[0], ranked[1]
    paired = paired_comparison(tips_of[first], tips_of[second], measured, held)
    overruled = first == "none" and not at_floor and paired["t"] < -paired["critical_t"]
    if overruled:
        first, second = second, first
        paired = paired_comparison(tips_of[first], tips_of[second], measured, held)
    ambiguous = first != "none" and paired["t"] < paired["critical_t"]
    return first, second, paired, ambiguous, overruled


def paired_comparison(tip_a, tip_b, measured, held) -> dict:
    """Is b's held-out tip error larger than a's, beyond chance? A batch-means paired test.

    The held-out rows are cut into contiguous segments of at least the correlation length of the
    per-row loss difference ``|e_b|^2 - |e_a|^2`` (``1 + 2 sum rho``, so that segments are about
    independent), between :data:`SEGMENTS_MIN` and :data:`SEGMENTS_MAX` of them; while the
    segment statistics still correlate from one segment to the next (lag-1 autocorrelation above
    its 95 % bound ``1.645 / sqrt(S)``), neighbouring segments are merged (S halved, not below
    the minimum). Per segment the statistic is ``log(SSE_b / SSE_a)``: scale-free, so a few
    segments where the arm moves fast (large errors for both) do not swamp the rest, as raw
    excess errors do. One-sided Student t of its mean with S - 1 degrees of freedom
    (t > critical_t: b is worse)."""
    from scipy.stats import t as student

    rows = np.flatnonzero(held)
    err_a = np.sum((tip_a[rows] - measured[rows]) ** 2, axis=1)
    err_b = np.sum((tip_b[rows] - measured[rows]) ** 2, axis=1)
    corr = max(
        _correlation_length(tip_a[rows] - measured[rows]),
        _correlation_length(tip_b[rows] - measured[rows]),
        _correlation_length((err_b - err_a)[:, None]),
    )
    segments = int(np.clip(len(rows) // max(2.0, corr), SEGMENTS_MIN, SEGMENTS_MAX))
    while True:
        parts = np.array_split(np.arange(len(rows)), segments)
        stat = np.array([math.log(max(err_b[p].sum(), 1e-300) / max(err_a[p].sum(), 1e-300)) for p in parts])
        centred = stat - stat.mean()
        var = float(centred @ centred)
        lag1 = float(centred[:-1] @ centred[1:]) / var if var > 0 else 0.0
        if lag1 > 1.645 / math.sqrt(segments) and segments // 2 >= SEGMENTS_MIN:
            segments //= 2
            continue
        break
    # the variance of the mean with the segments' remaining lag-1 correlation (only ever
    # widened: a chance negative correlation does not narrow it)
    spread = float(np.std(stat, ddof=1)) * math.sqrt(1 + 2 * max(0.0, lag1))
    mean = float(np.mean(stat))
    if spread > 0:
        t = mean / (spread / math.sqrt(segments))
    else:  # the same error ratio in every segment: identical predictions (0), or a sure difference
        t = 0.0 if mean == 0 else math.copysign(T_SURE, mean)
    return {
        "segments": segments, "t": float(t), "critical_t": float(student.ppf(PAIRED_LEVEL, segments - 1)),
        "worse_in_segments": int(np.sum(stat > 0)), "loss_correlation_rows": corr, "lag1": lag1,
        "mean_log_sse_ratio": mean,
    }  # fmt: skip


def _options(effect, M: int, groups) -> int:
    """How many ways the effect can be placed (muscles, muscle pairs, or one)."""
    if effect.per_pair:
        return sum(len(g) * (len(g) - 1) for g in groups)
    return M + (effect.name == "pressure_lag") if effect.per_muscle else 1


def _muscles(names, option) -> dict:
    """``muscle`` (the one an effect belongs to, the receiving one of a pair) and ``source_muscle``."""
    if isinstance(option, tuple):
        return {"muscle": names[option[0]], "source_muscle": names[option[1]]}
    return {"muscle": names[option] if option is not None else None, "source_muscle": None}


def _own(name: str, values: dict) -> dict:
    """The effect's own parameters of a joint fit."""
    return {p.key: float(values[p.key]) for p in get(name).params}


def _shared(name: str, values: dict) -> dict:
    """The re-fit's parameters of a joint fit (fitted together with the effect)."""
    own = {p.key for p in get(name).params}
    return {k: float(v) for k, v in values.items() if k not in own}


def _maker(effect, nominal: Knobs, option=None):
    """Parameter values -> knobs: the re-fit's terms plus ``effect`` (on ``option``: a muscle
    index or a (receiving, source) pair)."""
    return lambda v: effect.knobs(refit_knobs(nominal, v), v, option)


def _fit_effect(effect, replayer, base: FitResult, nominal: Knobs, measured, train, M, directions):
    """(fit, muscle index or None) of one library effect, jointly with the re-fit's parameters:
    its start grid (per-muscle effects: screened for every option) and :data:`FIRST_ITERATIONS`
    local steps."""

    def maker(m=None):
        return _maker(effect, nominal, m)

    if not effect.per_muscle:
        return fit(
            replayer, effect.params, maker(), measured, train, shared=base, iterations=FIRST_ITERATIONS
        ), None
    if effect.per_pair:
        options = [(i, j) for g in replayer.groups for i in g for j in g if i != j]
    else:
        options = list(range(M)) + ([None] if effect.name == "pressure_lag" else [])
    # the options are screened (start grid, no local search) on the recording's first SCREEN_S
    # only: the screen ranks muscles, and the chosen one is then fitted on every training row
    head = replayer.head(SCREEN_S)
    n = len(head.time_s)
    screens = {
        m: fit(head, effect.params, maker(m), measured[:n], train[:n], iterations=0, shared=base)
        for m in options
    }
    # directions for locating: the tip's change when one muscle's pressure is scaled / delayed
    # (over the screen window; NaN after it)
    kind = {"weak_muscle": "gain", "pressure_lag": "lag"}.get(effect.name)
    if kind:
        probe = {**base.values, **{p.key: p.start if p.start is not None else p.lo for p in effect.params}}
        probe[effect.params[0].key] = effect.params[0].grid[len(effect.params[0].grid) // 2]
        tips = head.tips([maker(m)(probe) for m in range(M)])
        for m in range(M):
            direction = np.full_like(base.tip, np.nan)
            direction[:n] = tips[m] - base.tip[:n]
            directions[f"{replayer.muscles[m]}:{kind}"] = direction
    # the SCREENED_OPTIONS best screened options get a local step each (jointly with the re-fit's
    # parameters), the best after it is kept: a screen holds the re-fit's values fixed, and where
    # the re-fit has leaned on its bounds to take up the effect (a leak answered by the common
    # offset and lag) the right muscle can screen second (options are ints, None or tuples: they
    # are ranked through their screens' errors, never compared with each other)
    ranked = sorted(screens, key=lambda m: screens[m].sse_train)[:SCREENED_OPTIONS]
    stepped = {}
    for option in ranked:
        start = {p.key: screens[option].values[p.key] for p in effect.params}
        stepped[option] = fit(replayer, effect.params, maker(option), measured, train, start=start,
                              shared=base, iterations=FIRST_ITERATIONS, grid=False)  # fmt: skip
    best = min(stepped, key=lambda m: stepped[m].sse_train)
    return stepped[best], best
