"""Blind benchmark of ``efam diagnose`` on the virtual bench: any protocol, effects in many forms.

Each case (``diagnose.virtual_bench``): a randomised truth muscle (FAM1 or FAM2 constants
perturbed, one of the paper's four laws), a protocol from one of four families (isobaric strokes
in shuffled pressure order, isometric ramps or staircases at fixed lengths, sinusoidal / random /
chirp strokes at any mean and amplitude, mixed files), a regulator with dynamics and ripple,
25 Hz - 1 kHz sampling, a CSV with random units read back by the package's reader, and a truth:
nothing (clean), one library effect in one of its truth forms, two effects, or an effect outside
the library. The truth effects are written independently of the library, in other functional
forms. The diagnosis sees the recording and the NOMINAL preset (FAM1 or FAM2, default law) only.

Scored per protocol family: top-1 among confident answers (in-library cases; right = the answer
is one of the concealed effects), false alarms on clean recordings (any effect named), the
fraction of in-library cases flagged ambiguous, the expected calibration error of the reported
probability of the answer (10 bins), the median held-out RMS reduction with an effect present;
outside the library: a physical name given with p >= 0.8, and whether the data-driven correction
lowers the held-out RMS; and, for ambiguous cases, whether the recommended next experiment (run
by the truth model and diagnosed together with the first recording) resolves them (a confident,
right answer).

Usage: python bench/bench_diagnose.py [--per-family 76] [--seed 40000] [--jobs 2]
       python bench/bench_diagnose.py --calibrate   (fits confidence.Calibration on its own seeds)
       python bench/bench_diagnose.py --calibrate --calibrate-rows A.json B.rows.jsonl   (from stored rows)
       python bench/bench_diagnose.py --speed --seed 89000   (30 000-sample recordings, one per family)
Writes bench/results/diagnose.json (or diagnose_calibration.json) and docs/figures/diagnose_*.png.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from dataclasses import asdict  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from efam_mujoco.diagnose import design, diagnose  # noqa: E402
from efam_mujoco.diagnose import virtual_bench as V  # noqa: E402
from efam_mujoco.diagnose.confidence import (  # noqa: E402
    CALIBRATION,
    CALIBRATION_SEEDS,
    OUTSIDE,
    Calibration,
    best_effect_z,
    bootstrap_blocks,
    insample_supported,
    none_features,
    physics_features,
    verdict,
)
from efam_mujoco.diagnose.design import FOCUSED, experiment, stroke_speed  # noqa: E402
from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.musclefile import load_muscle  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "diagnose.json"
CALIBRATION_RESULTS = ROOT / "bench" / "results" / "diagnose_calibration.json"
FIGURES = ROOT / "docs" / "figures"
SPEED_GOAL_S = 30.0
#: cases per family: clean, one library effect, two library effects, outside the library
MIX = {"clean": 0.16, "single": 0.52, "two": 0.16, "outside": 0.16}


def pin_one_core() -> str:
    if hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        cpu = cpus[os.getpid() % len(cpus)]
        os.sched_setaffinity(0, {cpu})
        return f"cpu {cpu}"
    return "not pinned"


def plan(per_family: int, seed: int) -> list[tuple[int, str, str]]:
    """(seed, family, kind) for every case, interleaved so that a partial run stays balanced."""
    counts = {k: max(1, int(round(per_family * f))) for k, f in MIX.items()}
    kinds = []
    for k in range(max(counts.values())):
        kinds += [kind for kind, c in counts.items() if k < c]
    cases = []
    for kind in kinds:
        for family in V.FAMILIES:
            cases.append((seed + len(cases), family, kind))
    return cases


def calibration_plan() -> list[tuple[int, str, str]]:
    """The calibration cases: every seed of ``CALIBRATION_SEEDS``, in the benchmark's own mix of
    kinds (``MIX``). A plan cut short after its first seeds would hold the interleaving's early
    rows (every kind in turn) and so far more clean and two-effect cases than the benchmark: the
    maps would learn another base rate of effects that are there but hard to see."""
    cases = []
    for lo, hi in CALIBRATION_SEEDS:
        cases += plan((hi - lo + 1) // len(V.FAMILIES), lo)
    return cases


def correct(answer: str, kind: str, truth: list[str], shows: bool = True) -> bool:
    """Right answer: ``none`` for a clean recording or an effect that does not show (the model's
    own parameters reproduce it: ``virtual_bench.identifiable``); outside the library:
    ``outside_library``; else one of the concealed effects."""
    if kind == "clean" or not shows:
        return answer == "none"
    if kind == "outside":
        return answer == OUTSIDE
    return answer in truth


def _verdict_inputs(d) -> dict:
    """What ``confidence.verdict`` weighed for diagnosis ``d`` (``rescore`` and the calibration re-use it)."""
    v = d.verdict
    return {"raw": v.raw, "excess_cut": v.excess_cut, "dd_gain": v.dd_gain, "n_blocks": v.n_blocks,
            "excess": v.excess, "dd_gain_none": v.dd_gain_none, "evidence": d.evidence,
            "pair": [e["name"] for e in d.effects[:2]] if len(d.effects) >= 2 else [],
            "delta_bic": {c["name"]: c["delta_bic"] for c in d.candidates}}  # fmt: skip


def try_recommendation(
    case, recording, nominal, d, seed: int, earlier=(), second_round: bool = False
) -> dict:
    """Run the recommended next experiment of diagnosis ``d`` with the concealed truth, diagnose
    it with ``recording`` (and the ``earlier`` next experiments), and judge the joined answer on
    the joined data. ``second_round``: when the joined answer is still ambiguous, run what its
    own diagnosis recommends too, as a lab would, and judge the three recordings together
    (``"second"``; beside the issue's line, which is one experiment)."""
    kind = case.kind
    rec = d.next_experiment["recommended"]
    e = experiment(rec["name"], d.ctx, stroke_speed(d.ctx, d.labels), rec.get("set_points"))
    extra = V.run_plan(case, e.t, e.L, e.P, min(case.sample_hz, 100.0), seed)
    recordings = [recording, *earlier, extra]
    # its own recommendation only where a second round may need it (made for an ambiguous answer only)
    d2 = diagnose(recordings, nominal, next_experiment=second_round)
    # the joined answer is judged on the joined data: the new test can make an effect show
    # that the first recording hid (or an effect that showed is still there)
    shows_joined, left_joined = (
        V.identifiable(case, recording, nominal, more=tuple(r.meta["noise_free"] for r in recordings[1:]))
        if case.effects
        else (True, 0.0)
    )
    out = {
        "experiment": rec["name"], "predicted_difference_rms_N": rec["predicted_difference_rms_N"],
        "ratio_to_noise": rec["ratio_to_noise"], "expected_z": rec.get("expected_z"),
        "blocks": rec.get("blocks"), "duration_s": rec.get("duration_s"), "answer": d2.verdict.answer,
        "probability": d2.verdict.probability, "confident": d2.verdict.confident,
        "ambiguous_after": d2.verdict.ambiguous,
        "correct": correct(d2.verdict.answer, kind, case.names, shows_joined),
        "shows_joined": shows_joined, "truth_left_joined_N": left_joined,
        # the joined verdict's inputs, so that a calibration can weigh the joined diagnoses too
        **_verdict_inputs(d2),
    }  # fmt: skip
    out["resolved"] = bool(out["confident"] and out["correct"])
    if second_round and d2.verdict.ambiguous and d2.next_experiment and d2.next_experiment.get("recommended"):
        second = try_recommendation(case, recording, nominal, d2, seed, earlier=recordings[1:])
        out["second"] = {k: second[k] for k in SECOND_KEYS}
    return out


#: what a second round's row keeps
SECOND_KEYS = ("experiment", "expected_z", "duration_s", "answer", "probability", "confident", "ambiguous_after",
               "correct", "resolved")  # fmt: skip


def run_case(spec: tuple[int, str, str], try_next: bool = True) -> dict:
    seed, family, kind = spec
    case = V.draw_case(seed, family, kind)
    recording = V.make(case)
    nominal = load_muscle(case.base_name)  # the diagnosis sees the nominal preset only
    shows, left = V.identifiable(case, recording, nominal) if case.effects else (True, 0.0)
    # reported beside the scored definition: what the diagnosis's own no-effect model leaves
    left_base = V.left_after_baseline(case, recording, nominal) if case.effects else 0.0
    t0 = time.perf_counter()
    d = diagnose([recording], nominal)
    seconds = time.perf_counter() - t0
    v = d.verdict
    row = {
        "seed": seed, "family": family, "kind": kind, "truth": case.names,
        "forms": [f for _, f in case.effects], "truth_params": case.params, "protocol": case.protocol,
        "sample_hz": case.sample_hz, "units": case.units, "truth_muscle": case.base_name,
        "truth_effect_rms_N": case.effect_rms_N, "force_noise_N": case.noise_N,
        "answer": v.answer, "probability": v.probability, "confident": v.confident, "ambiguous": v.ambiguous,
        "contenders": v.contenders, "probabilities": v.probabilities, **_verdict_inputs(d), "both": v.both,
        "named": d.names, "correct": correct(v.answer, kind, case.names, shows), "shows": shows,
        "truth_left_after_refit_N": left, "truth_left_after_baseline_N": left_base,
        "shows_after_baseline": bool(left_base >= 0.25 * case.noise_N) if case.effects else True,
        **d.rms_summary(),
        "dd_heldout_before_N": d.correction.heldout_rms_before_N, "dd_heldout_after_N": d.correction.heldout_rms_after_N,
        "dd_terms": d.correction.terms, "structured_left": d.unexplained.get("structured", False),
        "structure": d.structure, "samples": d.n_samples, "seconds": seconds,
        "tentative": v.tentative, "separation_z": v.separation_z, "outside_supported": v.outside_supported,
        "dd_raw_gain": d.correction.raw_gain,
        "next": None, "next_without_optimal": None,
    }  # fmt: skip
    # the next experiment is tried on every ambiguous case, whatever its family: the truth model
    # runs the recommended protocol with the concealed effect, and both recordings are diagnosed
    if try_next and v.ambiguous and d.next_experiment and d.next_experiment.get("recommended"):
        row["next"] = try_recommendation(case, recording, nominal, d, seed, second_round=True)
        # side by side in the same run: what the recommendation would have been, and done,
        # without the optimal-design candidate (it can also change which test is paired or
        # repeated, so the design is always made again; the same test is not run twice)
        design.OFFER_OPTIMAL = False
        try:
            d_alt = diagnose([recording], nominal)
        finally:
            design.OFFER_OPTIMAL = True
        alt = (d_alt.next_experiment or {}).get("recommended")
        if alt and (alt["name"], alt["duration_s"]) == (row["next"]["experiment"], row["next"]["duration_s"]):
            row["next_without_optimal"] = row["next"]
        elif alt:
            row["next_without_optimal"] = try_recommendation(case, recording, nominal, d_alt, seed)
    return row


def ece(probabilities, hits, bins: int = 10) -> float:
    """Expected calibration error: bin-weighted |mean probability - accuracy| (equal-width bins)."""
    p = np.asarray(probabilities, float)
    h = np.asarray(hits, float)
    if not len(p):
        return float("nan")
    idx = np.minimum((p * bins).astype(int), bins - 1)
    total = 0.0
    for b in range(bins):
        m = idx == b
        if m.any():
            total += m.sum() / len(p) * abs(p[m].mean() - h[m].mean())
    return float(total)


def _frac(xs) -> float | None:
    xs = list(xs)
    return float(np.mean(xs)) if xs else None


def summarise(rows: list[dict]) -> dict:
    out = {"cases": len(rows), "by_family": {}}
    for family in list(V.FAMILIES) + ["all"]:
        sub = [r for r in rows if family in ("all", r["family"])]
        inlib = [r for r in sub if r["kind"] in ("single", "two")]
        present = [r for r in inlib if r.get("shows", True)]
        conf = [r for r in inlib if r["confident"]]
        clean = [r for r in sub if r["kind"] == "clean"]
        outside = [r for r in sub if r["kind"] == "outside"]
        amb = [r for r in sub if r["next"] is not None]
        expected = [r for r in amb if (r["next"].get("expected_z") or 0.0) >= 1.0]
        out["by_family"][family] = {
            "n": len(sub), "in_library": len(inlib), "clean": len(clean), "outside": len(outside),
            "top1_confident": _frac(r["correct"] for r in conf), "confident": len(conf),
            # beside it (not the goal's figure): an effect counts as present only if it survives
            # the diagnosis's own no-effect model (virtual_bench.left_after_baseline)
            "top1_confident_baseline_detectable": _frac(
                correct(r["answer"], r["kind"], r["truth"], r.get("shows_after_baseline", r.get("shows", True)))
                for r in conf
            ),
            "top1_all": _frac(r["correct"] for r in inlib),
            "false_alarm": _frac(r["answer"] != "none" for r in clean),
            "false_alarm_confident": _frac(r["answer"] != "none" and r["confident"] for r in clean),
            "ambiguous_in_library": _frac(r["ambiguous"] for r in inlib),
            "tentative_in_library": _frac(r.get("tentative", False) for r in inlib),
            "top1_tentative": _frac(r["correct"] for r in inlib if r.get("tentative", False)),
            "ece": ece([r["probability"] for r in sub], [r["correct"] for r in sub]),
            "median_heldout_reduction": float(np.median([1 - r["heldout_rms_after_N"] / r["heldout_rms_before_N"] for r in present])) if present else None,
            # beside it: what a model leaving only the noise would reach (1 - noise floor / the
            # model alone's held-out RMS): an effect the re-fit has mostly absorbed caps it
            "median_reduction_bound": float(np.median([1 - r["noise_N"] / r["heldout_rms_before_N"] for r in present])) if present else None,
            "effects_not_showing": len(inlib) - len(present),
            "outside_wrong_name_p08": _frac(r["answer"] not in ("none", OUTSIDE) and r["probability"] >= 0.8 for r in outside),
            "outside_dd_improves": _frac(r["dd_heldout_after_N"] < 0.98 * r["dd_heldout_before_N"] for r in outside),
            "next_tried": len(amb), "next_resolved": _frac(r["next"]["resolved"] for r in amb),
            # beside it: the same cases with the recommendation made without the optimal-design
            # candidate (run side by side; rows from before it was recorded give None)
            "next_resolved_without_optimal": _frac(r["next_without_optimal"]["resolved"] for r in amb)
            if all(r.get("next_without_optimal") for r in amb) else None,
            "next_optimal_recommended": sum(FOCUSED in r["next"]["experiment"] for r in amb),
            # beside it: the cases whose recommendation the design expected to decide (z >= 1;
            # below, the report says it is not expected to), and how many of them it resolved
            "next_expected_to_decide": len(expected),
            "next_resolved_expected": _frac(r["next"]["resolved"] for r in expected),
            # beside it: resolved by the recommended experiment, or by a second one where the
            # joined answer was still ambiguous (as a lab would go on); rows from before the second
            # round was run count their first round only
            "next_resolved_within_two": _frac(
                r["next"]["resolved"] or (r["next"].get("second") or {}).get("resolved", False) for r in amb
            ),
            "next_second_tried": sum(bool(r["next"].get("second")) for r in amb),
            # beside it (not the goal's figure): the pair told apart and the answer right, at any
            # probability (rows from before the field was recorded give None)
            "next_separated_right": _frac(
                r["next"]["correct"] and not r["next"]["ambiguous_after"] for r in amb
            ) if all("ambiguous_after" in r["next"] for r in amb) else None,
        }  # fmt: skip
    seconds = [r["seconds"] for r in rows] or [float("nan")]
    big = [r for r in rows if r["samples"] >= 25000]
    out["seconds_median"] = float(np.median(seconds))
    out["seconds_max"] = float(np.max(seconds))
    out["samples_max"] = int(max((r["samples"] for r in rows), default=0))
    out["seconds_max_25k_plus"] = float(max((r["seconds"] for r in big), default=float("nan")))
    out["speed_goal_s"] = SPEED_GOAL_S
    return out


def print_summary(s: dict) -> None:
    keys = ("n", "top1_confident", "confident", "false_alarm", "ambiguous_in_library", "tentative_in_library", "ece",
            "median_heldout_reduction", "median_reduction_bound", "outside_wrong_name_p08", "outside_dd_improves", "next_tried", "next_resolved",
            "next_resolved_without_optimal", "next_resolved_within_two")  # fmt: skip
    print(f"\n{'family':12s}" + "".join(f"{k[:14]:>15s}" for k in keys))
    for fam, b in s["by_family"].items():
        cells = []
        for k in keys:
            v = b[k]
            cells.append(f"{'-':>15s}" if v is None else f"{v:15d}" if isinstance(v, int) else f"{v:15.3f}")
        print(f"{fam:12s}" + "".join(cells))
    print(
        f"\none diagnosis: median {s['seconds_median']:.1f} s, max {s['seconds_max']:.1f} s (largest file "
        f"{s['samples_max']} samples; max over files >= 25 000 samples {s['seconds_max_25k_plus']:.1f} s) on one core; goal < 30 s"
    )


# ------------------------------------------------------------------------- calibration
#: ridge weights tried for the per-term offsets of the physics map (ten-fold cross-validation picks one)
OFFSET_RIDGES = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0)


def _logistic_fit(X: np.ndarray, w0, ridge: float = 0.0, n_free: int | None = None) -> np.ndarray:
    """Weighted logistic regression by maximum likelihood. ``X`` columns: features..., right
    (0/1), weight. Every coefficient carries a tiny ridge (1e-3); those past the first ``n_free``
    (intercept included) carry ``ridge`` (a Gaussian prior of variance 1/(2 ridge))."""
    from scipy.optimize import minimize

    k = X.shape[1] - 2
    n_free = k + 1 if n_free is None else n_free

    def nll(w):
        z = w[0] + X[:, :k] @ w[1:]
        p = np.clip(1 / (1 + np.exp(-z)), 1e-9, 1 - 1e-9)
        right, weight = X[:, -2], X[:, -1]
        prior = 1e-3 * np.sum(w * w) + ridge * np.sum(w[n_free:] ** 2)
        return -np.sum(weight * (right * np.log(p) + (1 - right) * np.log(1 - p))) + prior

    return minimize(nll, np.array(w0, float), method="BFGS").x


def _heldout_log_loss(X: np.ndarray, w0, ridge: float, n_free: int, folds: int = 10) -> float:
    """Weighted log-loss of ``_logistic_fit`` on each of ``folds`` folds, fitted on the others
    (fixed fold draw: every ridge weight is judged on the same folds)."""
    fold = np.random.default_rng(0).integers(0, folds, len(X))
    k, loss = X.shape[1] - 2, 0.0
    for f in range(folds):
        w = _logistic_fit(X[fold != f], w0, ridge, n_free)
        T = X[fold == f]
        p = np.clip(1 / (1 + np.exp(-(w[0] + T[:, :k] @ w[1:]))), 1e-9, 1 - 1e-9)
        loss -= float(np.sum(T[:, -1] * (T[:, -2] * np.log(p) + (1 - T[:, -2]) * np.log(1 - p))))
    return loss / float(X[:, -1].sum())


def fit_calibration(rows: list[dict]) -> Calibration:
    """The two logistic maps of ``confidence`` by maximum likelihood on the calibration cases:
    (a, b, c) from (excess cut, data-driven gain) to 'the best library term is the physics', with
    an offset of the log-odds per library term (shrunk by a ridge weight that ten-fold
    cross-validation on these cases picks from ``OFFSET_RIDGES``), over the cases whose raw winner
    is an effect (weighted by its win fraction); (an, bn, cn, dn) from (excess over the noise,
    data-driven gain, best effect's separation from none / 5) to 'nothing is missing', over those
    won by none (weighted by none's win fraction)."""
    effect_rows, tops, none_rows = [], [], []
    for r in rows:
        raw = insample_supported(r["raw"], r.get("delta_bic"))
        effects = {k: v for k, v in raw.items() if k != "none"}
        if effects:
            top = max(effects, key=effects.get)
            right = r["kind"] in ("single", "two") and r.get("shows", True) and top in r["truth"]
            weight = sum(effects.values())
            if weight > 0:
                effect_rows.append((*physics_features(r["excess_cut"], r["dd_gain"]), float(right), weight))
                tops.append(top)
        if raw.get("none", 0) > 0:
            effect_z = best_effect_z((r.get("evidence") or {}).get("block_sse"))
            none_rows.append((*none_features(r["excess"], r["dd_gain_none"], effect_z),
                              float(r["kind"] == "clean" or not r.get("shows", True)), raw["none"]))  # fmt: skip
    print(f"calibration rows: {len(effect_rows)} won by an effect, {len(none_rows)} by none")
    names = sorted(set(tops))
    E = np.array(effect_rows)
    one_hot = np.array([[float(t == n) for n in names] for t in tops]).reshape(len(tops), len(names))
    X = np.column_stack([E[:, :2], one_hot, E[:, 2:]])
    w0 = [0.0, 3.0, -10.0] + [0.0] * len(names)
    losses = {ridge: _heldout_log_loss(X, w0, ridge, n_free=3) for ridge in OFFSET_RIDGES}
    ridge = min(losses, key=losses.get)
    print("held-out log-loss by ridge weight on the per-term offsets: "
          + ", ".join(f"{k:g}: {v:.4f}" for k, v in losses.items()) + f" (chosen {ridge:g})")  # fmt: skip
    w = _logistic_fit(X, w0, ridge, n_free=3)
    wn = _logistic_fit(np.array(none_rows), [3.0, 0.0, -10.0, 0.0])
    return Calibration(concentration=CALIBRATION.concentration, a=float(w[0]), b=float(w[1]), c=float(w[2]),
                       tie_margin=CALIBRATION.tie_margin, an=float(wn[0]), bn=float(wn[1]), cn=float(wn[2]),
                       dn=float(wn[3]), effect_offset={n: float(v) for n, v in zip(names, w[3:])},
                       offset_ridge=float(ridge))  # fmt: skip


def stored_rows(paths: list[str], cases: list[tuple[int, str, str]]) -> list[dict]:
    """The rows of ``cases`` read from stored runs (``.rows.jsonl`` lines or a JSON's ``cases``),
    each checked against its planned family and kind; a missing case is an error (a calibration
    on part of its plan learns another mix)."""
    found: dict[int, dict] = {}
    for path in paths:
        try:
            text = Path(path).read_text()
            if path.endswith(".jsonl"):
                rows = [json.loads(line) for line in text.splitlines() if line.strip()]
            else:
                rows = json.loads(text)["cases"]
            for r in rows:
                found[int(r["seed"])] = r
        except OSError as e:
            raise SystemExit(f"{path}: cannot read stored rows ({e.strerror})") from None
        except (ValueError, KeyError, TypeError) as e:
            raise SystemExit(f"{path}: not a benchmark run's rows (.rows.jsonl lines, or a JSON with 'cases' "
                             f"whose rows have a 'seed'): {type(e).__name__}: {e}") from None  # fmt: skip
    out, missing = [], []
    for seed, family, kind in cases:
        r = found.get(seed)
        if r is None:
            missing.append(seed)
            continue
        if (r["family"], r["kind"]) != (family, kind):
            raise SystemExit(
                f"stored row of seed {seed} is {r['family']}/{r['kind']}, the plan says {family}/{kind}"
            )
        out.append(r)
    if missing:
        raise SystemExit(
            f"{len(missing)} calibration cases are not in the stored rows (first: seed {missing[0]})"
        )
    return out


def with_current_bootstrap(row: dict) -> dict:
    """``row`` with its raw win fractions drawn again from its stored per-block evidence under
    this code's bootstrap (its tie rule, its concentration) and the in-sample check: stored rows
    then calibrate the bootstrap as it now decides. A row without the evidence is kept as it is."""
    sse = (row.get("evidence") or {}).get("block_sse")
    if not sse:
        return row
    raw = bootstrap_blocks({h: np.asarray(v, float) for h, v in sse.items()},
                           concentration=CALIBRATION.concentration, tie_margin=CALIBRATION.tie_margin)  # fmt: skip
    return row | {"raw": insample_supported(raw, row.get("delta_bic"))}


def rescore(rows: list[dict], cal: Calibration) -> list[dict]:
    """Rows with their verdicts recomputed under another calibration (the raw quantities kept)."""
    out = []
    for r in rows:
        pair = tuple(r["pair"]) if r.get("pair") else None
        ev = r.get("evidence") or {}
        v = verdict(
            insample_supported(r["raw"], r.get("delta_bic")),
            r["excess_cut"],
            r["dd_gain"],
            r["n_blocks"],
            cal,
            r["excess"],
            r["dd_gain_none"],
            pair,
            block_sse=ev.get("block_sse"),
            dd_z=ev.get("dd_z"),
            dd_z_none=ev.get("dd_z_none"),
            excess_left=ev.get("excess_left"),
        )
        out.append(r | {"answer": v.answer, "probability": v.probability, "confident": v.confident,
                        "ambiguous": v.ambiguous, "tentative": v.tentative, "outside_supported": v.outside_supported,
                        "correct": correct(v.answer, r["kind"], r["truth"], r.get("shows", True))})  # fmt: skip
    return out


# ------------------------------------------------------------------------------ figures
def write_figures(rows: list[dict], summary: dict) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    p = np.array([r["probability"] for r in rows])
    h = np.array([r["correct"] for r in rows], float)
    bins = np.linspace(0, 1, 11)
    idx = np.minimum((p * 10).astype(int), 9)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.6))
    a = ax[0]
    a.plot([0, 1], [0, 1], "k--", lw=0.8, label="perfect calibration")
    xs, ys, ns = [], [], []
    for b in range(10):
        m = idx == b
        if m.sum():
            xs.append(p[m].mean())
            ys.append(h[m].mean())
            ns.append(int(m.sum()))
    a.plot(xs, ys, "o-", color="tab:red", label="benchmark")
    for x, y, n in zip(xs, ys, ns):
        a.annotate(str(n), (x, y), textcoords="offset points", xytext=(4, -10), fontsize=7)
    a.set(xlabel="reported probability of the answer", ylabel="fraction right",
          title=f"reliability ({len(rows)} recordings, ECE {summary['by_family']['all']['ece']:.3f})",
          xlim=(0, 1), ylim=(0, 1.02))  # fmt: skip
    a.legend(loc="upper left")
    a = ax[1]
    a.hist(p, bins=bins, color="0.6")
    a.set(xlabel="reported probability of the answer", ylabel="recordings", title="how sure the answers are")
    fig.tight_layout()
    path = FIGURES / "diagnose_reliability.png"
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
    return [path]


def run(cases, jobs: int, try_next: bool, log: Path | None = None) -> list[dict]:
    """Diagnose every case; each row is also appended to ``log`` (JSON lines) as it finishes, so
    that a run cut short can still be summarised (``--summarise LOG``)."""
    rows = []
    if log is not None:
        log.parent.mkdir(parents=True, exist_ok=True)
        log.write_text("")

    def keep(row):
        rows.append(row)
        if log is not None:
            with log.open("a") as f:
                f.write(json.dumps(row) + "\n")

    if jobs > 1:
        from functools import partial
        from multiprocessing import Pool

        with Pool(jobs, initializer=pin_one_core) as pool:
            for row in progress(
                pool.imap_unordered(partial(run_case, try_next=try_next), cases), "diagnose", len(cases)
            ):
                keep(row)
                _line(row, len(rows), len(cases))
    else:
        pin_one_core()
        for case in progress(cases, "diagnose", len(cases)):
            keep(run_case(case, try_next))
            _line(rows[-1], len(rows), len(cases))
    return sorted(rows, key=lambda r: r["seed"])


def speed(seed: int, samples: int = 30000) -> dict:
    """The speed line: a case's protocol re-recorded by its truth model at the rate that gives
    ``samples`` samples (trimmed to exactly that many), diagnosed on one core (with the next
    experiment, as a user would run it)."""
    pin_one_core()
    out = []
    for family in V.FAMILIES:
        case = V.draw_case(seed, family, "single")
        first = V.make(case)
        t, L, P = first.time_s - first.time_s[0], first.length_m, first.pressure_Pa
        while True:
            extra = V.run_plan(case, t, L, P, 1.06 * samples / float(t[-1]), seed)
            if len(extra) >= samples:
                break
            # too short a test for that many samples at the truth's highest rate: run it twice over
            t, L, P = np.r_[t, t[-1] + 1.0 + t], np.r_[L, L], np.r_[P, P]
        keep = np.arange(min(samples, len(extra)))
        recording = extra.subset(keep)
        nominal = load_muscle(case.base_name)
        t0 = time.perf_counter()
        d = diagnose([recording], nominal)
        seconds = time.perf_counter() - t0
        out.append({"family": family, "seed": seed, "samples": len(recording), "seconds": seconds,
                    "answer": d.verdict.answer, "truth": case.names})  # fmt: skip
        print(
            f"{family:10s} {len(recording):6d} samples: {seconds:.1f} s (goal < {SPEED_GOAL_S:.0f} s)",
            flush=True,
        )
    return {"cases": out, "seconds_max": max(r["seconds"] for r in out), "goal_s": SPEED_GOAL_S}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--per-family", type=int, default=76, help="recordings per protocol family (4 families)")
    ap.add_argument("--seed", type=int, default=40000, help="first seed")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (each pinned to one core)")
    ap.add_argument(
        "--calibrate", action="store_true", help="fit the probability map on the calibration seeds"
    )
    ap.add_argument(
        "--calibrate-rows",
        nargs="+",
        metavar="FILE",
        help="with --calibrate: fit on the rows stored in these files (a run's .rows.jsonl, or a JSON with 'cases') "
        "instead of running the calibration cases; every calibration seed must be there",
    )
    ap.add_argument("--no-next", action="store_true", help="do not try the recommended next experiments")
    ap.add_argument("--out", default=None)
    ap.add_argument(
        "--summarise", metavar="LOG", help="summarise the rows of a (possibly cut short) run's log and stop"
    )
    ap.add_argument(
        "--speed", action="store_true", help="time 30 000-sample recordings (one per family) and stop"
    )
    args = ap.parse_args(argv)
    start = time.perf_counter()
    if args.speed:
        result = speed(args.seed)
        path = write_json_atomic(args.out or RESULTS.with_name("diagnose_speed.json"), result)
        print(f"wrote {path}")
        return 0
    if args.summarise:
        rows = sorted((json.loads(line) for line in Path(args.summarise).read_text().splitlines() if line.strip()),
                      key=lambda r: r["seed"])  # fmt: skip
        planned = len(plan(args.per_family, args.seed))
        summary = summarise(rows)
        summary["planned"] = planned
        print_summary(summary)
        print(f"\n{len(rows)} of {planned} planned recordings ran")
        out = {"summary": summary, "settings": {"per_family": args.per_family, "seed": args.seed, "calibration": asdict(CALIBRATION),
               "note": f"summarised from the run's log: {len(rows)} of {planned} planned recordings ran"}, "cases": rows}  # fmt: skip
        path = write_json_atomic(args.out or RESULTS, out)
        print(f"wrote {path}")
        if path == RESULTS:  # the documented figures belong to the documented run alone
            for fig in write_figures(rows, summary):
                print(f"figure: {fig}")
        return 0
    if args.calibrate:
        cases = calibration_plan()
        if args.calibrate_rows:
            rows = [with_current_bootstrap(r) for r in stored_rows(args.calibrate_rows, cases)]
        else:
            rows = run(cases, args.jobs, try_next=False)
        cal = fit_calibration(rows)
        summary = summarise(rescore(rows, cal))
        print_summary(summary)
        print(f"\nfitted: {cal}")
        write_json_atomic(
            args.out or CALIBRATION_RESULTS, {"calibration": asdict(cal), "summary": summary, "cases": rows}
        )
        return 0
    cases = plan(args.per_family, args.seed)
    rows = run(
        cases, args.jobs, try_next=not args.no_next, log=Path(args.out or RESULTS).with_suffix(".rows.jsonl")
    )
    summary = summarise(rows)
    print_summary(summary)
    out = {
        "summary": summary,
        "settings": {"per_family": args.per_family, "seed": args.seed, "jobs": args.jobs, "calibration": asdict(CALIBRATION)},
        "machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine()},
        "wall_s": time.perf_counter() - start,
        "cases": rows,
    }  # fmt: skip
    path = write_json_atomic(args.out or RESULTS, out)
    print(f"\nwrote {path} ({out['wall_s']:.0f} s)")
    if path == RESULTS:
        for fig in write_figures(rows, summary):
            print(f"figure: {fig}")
    return 0


def _line(row: dict, k: int, n: int) -> None:
    mark = "ok " if row["correct"] else "BAD"
    flag = "conf" if row["confident"] else "AMB " if row["ambiguous"] else "tent"
    nxt = ""
    if row["next"]:
        nxt = f" next {row['next']['experiment']} -> {row['next']['answer']} ({'resolved' if row['next']['resolved'] else 'not resolved'})"
        if second := row["next"].get("second"):
            nxt += f", then {second['experiment']} -> {second['answer']} ({'resolved' if second['resolved'] else 'not resolved'})"
        alt = row.get("next_without_optimal")
        if alt and alt is not row["next"]:  # the same test is stored as the same row
            nxt += f"; without the optimal design {alt['experiment']} -> {alt['answer']} ({'resolved' if alt['resolved'] else 'not resolved'})"
    print(
        f"[{k:3d}/{n}] {mark} {flag} {row['family']:10s} {row['kind']:7s} {'+'.join(row['truth']) or 'none':32s} -> "
        f"{row['answer']:16s} p={row['probability']:.2f} held-out {row['heldout_rms_before_N']:.2f}->{row['heldout_rms_after_N']:.2f} N "
        f"{row['samples']:6d} smp {row['seconds']:.1f} s{nxt}",
        flush=True,
    )


if __name__ == "__main__":
    raise SystemExit(main())
