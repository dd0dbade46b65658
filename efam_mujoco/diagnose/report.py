"""The diagnosis in words, JSON and figures, and the ``efam diagnose`` command."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..units import visible
from . import Diagnosis, _for_recording, diagnose
from .effects import get


def text(d: Diagnosis) -> str:
    """A plain-text report: data, re-fit, located mismatch, candidates, what was found."""
    out = []
    out.append(f"efam diagnose: {d.n_samples} samples from {len(d.sources)} recording(s), {d.seconds:.1f} s")
    m = d.muscle_before
    out.append(
        f"Re-fitted model: law {d.refit.law}, dead band {m.deadband_Pa / 1e3:.2f} kPa, braid angle "
        f"{m.theta_rest_deg:.3f} deg, resting diameter {m.rest_diameter_m * 1e3:.2f} mm, bladder volume "
        f"{m.bladder_volume_m3 * 1e6:.3f} cm^3"
    )
    out.append("  in-sample RMS per law: " + ", ".join(f"{k} {v:.2f} N" for k, v in d.refit.by_law.items()))
    shift = d.refit_shift()
    if shift:
        out.append(
            f"  moved from the muscle given: braid angle {shift['theta_rest_deg']:+.3f} deg, dead band "
            f"{shift['deadband_kPa']:+.2f} kPa, resting diameter {shift['rest_diameter_pct']:+.2f} %, bladder volume "
            f"{shift['bladder_volume_pct']:+.2f} %"
        )
    caution = d.refit_caution()
    if caution:
        out.append(f"  CAUTION: {caution}")
    if d.structure:
        out.append(f"Test structure (read from the data): {d.structure}")
    out.append("")
    out.append("Located mismatch")
    out.extend("  " + line for line in d.located["summary"])
    out.append("")
    out.append(f"Candidates (held-out RMS; baseline without any effect: {d.heldout_rms_before_N:.2f} N)")
    out.append(f"  {'effect':18s} {'held-out N':>10s} {'dBIC':>12s} {'gain':>6s} {'excess cut':>10s}")
    for c in d.candidates:
        out.append(
            f"  {c['name']:18s} {c['heldout_rms_N']:10.3f} {c['delta_bic']:12.0f} {c['heldout_gain']:6.1%} "
            f"{c['excess_cut']:10.1%}"
        )
    out.append("")
    if d.verdict is not None:
        out.append("Confidence (held-out block bootstrap, calibrated; see docs/diagnosis.md)")
        out.append("  " + d.verdict.words())
        why = d.ambiguity_reason()
        if why:
            out.append("  " + why)
        if d.next_experiment and d.next_experiment.get("words"):
            out.append("  " + d.next_experiment["words"])
        out.append("")
    if not d.effects:
        out.append("Found: none -- no candidate beats the noise floor on held-out cycles.")
    for i, e in enumerate(d.effects, 1):
        out.append(f"Found {i}: {e['name']} -- {e['summary']}")
        out.append(f"  equation: {e['equation']}")
        params = ", ".join(_value(k, v) for k, v in e["parameters"].items())
        out.append(f"  parameters: {params}")
        out.append(f"  held-out RMS {e['heldout_rms_before_N']:.3f} N -> {e['heldout_rms_after_N']:.3f} N")
    if d.unexplained.get("summary"):
        out.append("")
        out.append("Outside the library")
        out.extend("  " + line for line in d.unexplained["summary"])
    out.append("")
    out.append(
        f"RMS in-sample {d.rms_before_N:.3f} N -> {d.rms_after_N:.3f} N; held out "
        f"{d.heldout_rms_before_N:.3f} N -> {d.heldout_rms_after_N:.3f} N; noise floor {d.noise_N:.3f} N"
    )
    if d.effects:
        out.append("Switch on: " + "; ".join(f"{e['name']}: {get(e['name']).plugin}" for e in d.effects))
        forces = [n for n in d.names if n != "force_offset"]
        plugin = f'efam.muscle config key effects="{",".join(forces)}"' if forces else ""
        sensor = "the load cell's zero (force_offset)" if "force_offset" in d.names else ""
        out.append(
            "In MuJoCo: " + " and ".join(x for x in (plugin, sensor) if x)
            + " (--report DIR writes DIR/rig_with_effects.xml)"
        )  # fmt: skip
    return "\n".join(out) + "\n"


def _value(key, value) -> str:
    if isinstance(value, list):
        return f"{key} = [" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{key} = {value:.4g}"


def effects_for_recording(d: Diagnosis, i: int = 0) -> list[tuple[str, dict]]:
    """The identified effects as ``[(name, parameters)]`` with recording ``i``'s own per-recording
    values (its load-cell zero): what ``EffectModel``, ``plugin_config`` and the rig take."""
    return _for_recording(d.effects, i)


def plugin_config(d: Diagnosis) -> dict[str, str]:
    """The efam.muscle ``<config>`` of the re-fitted muscle with the identified actuator-force
    effects switched on (keys ``effects`` and ``<effect>.<parameter>``; see docs/diagnosis.md).
    ``force_offset`` is a load-cell error: the rig adds it to its reading (``rig_with_effects``)."""
    from ..plugin import plugin_config as config

    return config(d.muscle_after, effects_for_recording(d))


def rig_with_effects(d: Diagnosis, i: int = 0) -> str:
    """The stroke rig (MJCF) for the re-fitted muscle with the identified effects switched on, the
    load-cell zero of recording ``i``: ``efam view`` opens it; ``rig.drive`` replays into it."""
    from ..rig import RigOptions, rig_xml

    xml = rig_xml(d.muscle_after, RigOptions(mode="stroke", effects=effects_for_recording(d, i)))
    names = ", ".join(d.names) or "none"
    source = d.sources[i] if i < len(d.sources) and d.sources[i] else f"recording {i + 1}"
    source = source.replace("--", "- -")  # an XML comment may not hold "--"
    note = f"  <!-- efam diagnose: effects switched on: {names}; load-cell zero of {source} -->\n"
    head, _, body = xml.partition("\n")
    return f"{head}\n{note}{body}"


def write_json(path, d: Diagnosis) -> Path:
    """The diagnosis as strict JSON (files.write_json_atomic: a non-finite value is an error)."""
    from ..files import write_json_atomic

    return write_json_atomic(path, d.to_json())


# ------------------------------------------------------------------------------- figures
def figures(d: Diagnosis, directory, prefix: str = "diagnose") -> list[Path]:
    """Residual maps and before/after overlays as PNG files in ``directory``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = [_residual_map(d, plt, directory / f"{prefix}_residual_map.png"),
             _overlay(d, plt, directory / f"{prefix}_overlay.png")]  # fmt: skip
    return paths


def _save(fig, path: Path, plt) -> Path:
    from ..files import save_figure  # a unique temporary, then a rename

    try:
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)


def _residual_map(d: Diagnosis, plt, path: Path) -> Path:
    ctx, lab = d.ctx, d.labels
    r = d.force - d.predicted_before
    iso = lab.isometric
    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    # (a) in time, holds shaded
    a = ax[0, 0]
    t = _global_time(ctx)
    a.plot(t, r, lw=0.4, color="0.3")
    for h in range(lab.hold_id.max() + 1):
        idx = np.flatnonzero(lab.hold_id == h)
        a.axvspan(t[idx[0]], t[idx[-1]], color="tab:orange", alpha=0.15, lw=0)
    a.axhline(0, color="k", lw=0.5)
    a.set(xlabel="time (s)", ylabel="residual, measured - model (N)",
          title=f"residual in time (holds shaded); noise floor {d.noise_N:.2f} N")  # fmt: skip
    # (b) map over the position variable, rising and falling
    a = ax[0, 1]
    pos = ctx.P / 1e3 if iso else ctx.x
    for dirn, colour, name in ((1, "tab:red", "rising"), (-1, "tab:blue", "falling")):
        m = lab.direction == dirn
        centres, means = _binned(pos[m], r[m], 30)
        a.plot(centres, means, "o-", ms=3, color=colour, label=name)
    a.axhline(0, color="k", lw=0.5)
    a.set(xlabel="pressure (kPa)" if iso else "strain L/L_rest - 1", ylabel="mean residual (N)",
          title="residual map by direction")  # fmt: skip
    a.legend()
    # (c) factor strengths
    a = ax[1, 0]
    f = d.located["factors"]
    names = list(f)
    values = [f[k]["strength_N"] for k in names]
    colours = ["tab:red" if f[k]["above_noise"] else "0.6" for k in names]
    a.barh(names, values, color=colours)
    a.axvline(0.25 * d.noise_N, color="k", ls="--", lw=0.8, label="0.25 x noise floor")
    a.set(xlabel="strength: RMS of bin means (N)", title="what organises the residual (red: above noise)")
    a.legend()
    # (d) residual by pressure level and cycle (stroke data) or by pressure bin (isometric)
    a = ax[1, 1]
    if iso or not len(lab.levels_Pa):
        key = "pressure"
        bins = f[key]["bins"]
        a.bar([b["bin"] for b in bins], [b["mean_N"] for b in bins], color="tab:purple")
        a.tick_params(axis="x", rotation=45)
        a.set(ylabel="mean residual (N)", title="by pressure")
    else:
        for c in range(min(lab.cycle_in_level.max() + 1, 4)):
            means = [np.mean(r[(lab.level == j) & (lab.cycle_in_level == c)]) if np.any((lab.level == j) & (lab.cycle_in_level == c)) else np.nan
                     for j in range(len(lab.levels_Pa))]  # fmt: skip
            a.plot(lab.levels_Pa / 1e3, means, "o-", label=f"cycle {c + 1} at the level")
        a.axhline(0, color="k", lw=0.5)
        a.set(xlabel="pressure level (kPa)", ylabel="mean residual (N)", title="by pressure and cycle number")
        a.legend()
    fig.tight_layout()
    return _save(fig, path, plt)


def _overlay(d: Diagnosis, plt, path: Path) -> Path:
    ctx, lab = d.ctx, d.labels
    iso = lab.isometric
    fig, ax = plt.subplots(1, 3, figsize=(16, 5))
    pos = ctx.P / 1e3 if iso else ctx.x
    a = ax[0]
    step = max(1, ctx.n // 6000)
    a.plot(pos[::step], d.force[::step], ".", ms=1.5, color="0.6", label="measured")
    a.plot(pos[::step], d.predicted_before[::step], ".", ms=1, color="tab:blue", label="model (re-fitted)")
    a.plot(
        pos[::step],
        d.predicted_after[::step],
        ".",
        ms=1,
        color="tab:red",
        label="model + " + (" + ".join(d.names) or "nothing"),
    )
    a.set(xlabel="pressure (kPa)" if iso else "strain L/L_rest - 1", ylabel="push force (N)", title="overlay")
    a.legend(markerscale=6)
    # zoom: the cycle where the effect matters most
    r0 = d.force - d.predicted_before
    r1 = d.force - d.predicted_after
    cyc = [c for c in np.unique(lab.cycle)]
    worst = max(cyc, key=lambda c: np.mean(r0[lab.cycle == c] ** 2))
    m = lab.cycle == worst
    a = ax[1]
    # measured and both models less the re-fitted model: the mismatch loop and how much is left
    a.plot(pos[m], r0[m], ".", ms=2, color="0.5", label="measured - model")
    a.plot(pos[m], d.predicted_after[m] - d.predicted_before[m], "-", lw=1.2, color="tab:red",
           label="identified effect")  # fmt: skip
    a.axhline(0, color="tab:blue", lw=1, label="re-fitted model")
    a.set(xlabel="pressure (kPa)" if iso else "strain L/L_rest - 1", ylabel="force relative to the model (N)",
          title=f"cycle {worst + 1} (largest mismatch)")  # fmt: skip
    a.legend()
    a = ax[2]
    t = _global_time(ctx)
    a.plot(t, r0, lw=0.4, color="tab:blue", label=f"before: RMS {np.sqrt(np.mean(r0**2)):.2f} N")
    a.plot(t, r1, lw=0.4, color="tab:red", label=f"after: RMS {np.sqrt(np.mean(r1**2)):.2f} N")
    a.set(xlabel="time (s)", ylabel="residual (N)", title="residual before and after")
    a.legend()
    fig.tight_layout()
    return _save(fig, path, plt)


def _global_time(ctx) -> np.ndarray:
    """Concatenated recordings on one time axis (each starts where the previous ended)."""
    t = ctx.t.copy()
    for i, s in enumerate(ctx.starts[1:], 1):
        end = ctx.starts[i + 1] if i + 1 < len(ctx.starts) else ctx.n
        t[s:end] += t[s - 1] + (t[s - 1] - t[s - 2] if s >= 2 else 0.0)
    return t


def _binned(x, y, n):
    if len(x) == 0:
        return np.array([]), np.array([])
    edges = np.linspace(np.min(x), np.max(x) + 1e-12, n + 1)
    idx = np.clip(np.searchsorted(edges, x) - 1, 0, n - 1)
    counts = np.bincount(idx, minlength=n)
    sums = np.bincount(idx, weights=y, minlength=n)
    ok = counts > 3
    return ((edges[:-1] + edges[1:]) / 2)[ok], sums[ok] / counts[ok]


# ----------------------------------------------------------------------------------- CLI
def register_cli(subparsers) -> None:
    """Add ``efam diagnose`` to the ``efam`` command line."""
    p = subparsers.add_parser(
        "diagnose",
        help="locate the model-vs-recording mismatch and name the missing physics",
        description=(
            "Replay recordings (CSV: time_s, length_m or displacement_mm, pressure_kPa/_Pa/_psi, "
            "force_N or tension_N) through the re-fitted model, locate where the residual stands "
            "above the noise floor, and identify the missing effect from a library of candidate "
            "physics with held-out cycles and BIC."
        ),
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="recording CSV files")
    p.add_argument("--muscle", required=True, help="preset (FAM1, FAM2) or muscle file: the starting model")
    p.add_argument("--json", help="write the JSON result here")
    p.add_argument("--report", metavar="DIR", help="write report.txt and the figures into DIR")
    p.add_argument("--tension-only", action="store_true", help="a muscle that cannot push (contractile)")
    from ..recordings import add_recording_arguments

    add_recording_arguments(p)
    p.set_defaults(run=run, file_inputs=("files", "muscle"), file_outputs=("json", "report"))


def run(args) -> int:
    """``efam diagnose``: read and check the recordings, diagnose, then write every output."""
    import sys
    from dataclasses import replace

    from ..files import OutputSet, check_replaceable_folder, replace_folder, strict_json
    from ..musclefile import check_tension_only, load_muscle
    from ..recordings import read_for_fit

    if args.report:
        check_replaceable_folder(args.report, "--report", "diagnose")
    muscle = load_muscle(args.muscle)
    if args.tension_only:
        muscle = replace(muscle, tension_only=True)
        check_tension_only(muscle, f"--tension-only with --muscle {args.muscle}")
    recordings = read_for_fit(args, muscle, warn=lambda line: print(line, file=sys.stderr))
    # read_for_fit ran the plausibility checks and said what --allow let through
    d = diagnose(recordings, muscle, allow="all")
    report = text(d)
    print(report, end="")
    outputs = OutputSet()
    if args.json:
        outputs.json(args.json, d.to_json())
    try:
        # written beside its place first: a --json that cannot be written fails before the
        # report folder is swapped in, so a failed run leaves neither
        outputs.prepare()
        if args.report:
            directory = Path(args.report)
            with replace_folder(directory, "--report", "diagnose") as staging:
                (staging / "report.txt").write_text(report)
                (staging / "rig_with_effects.xml").write_text(rig_with_effects(d))
                if args.json is None:
                    (staging / "diagnosis.json").write_text(strict_json(d.to_json()))
                names = [path.name for path in figures(d, staging)]
            shown = visible(str(directory))
            print(f"model: {shown}/rig_with_effects.xml (the re-fitted muscle, effects switched on)")
            for name in names:
                print(f"figure: {shown}/{name}")
        written = outputs.commit()
    finally:
        outputs.discard()
    for path in written:
        print(f"wrote {visible(str(path))}")
    return 0
