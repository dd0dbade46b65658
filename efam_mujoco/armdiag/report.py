"""The arm diagnosis in words, JSON, an MJCF with the found terms on, figures, and the CLI verb."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..cli import bounded_int
from ..files import (
    OutputSet,
    check_replaceable_folder,
    replace_folder,
    save_figure,
    write_json_atomic,
    write_text_atomic,
)
from ..units import visible
from .diagnosis import ArmDiagnosis, diagnose_arm
from .recording import read_csv
from .replay import Replayer
from .specfile import load_arm_model

#: rollout threads at most: each holds a MuJoCo data copy; more than a large machine's cores
#: only costs memory (100000 were taken without a word)
MAX_THREADS = 256


def _mm(x) -> str:
    return f"{x * 1e3:.2f} mm"


def text(d: ArmDiagnosis) -> str:
    """A plain-text report: re-fit, located mismatch, candidates with probabilities, verdict."""
    out = [f"efam diagnose-arm: {d.n_samples} samples from {', '.join(d.sources)}; {d.seconds:.1f} s CPU"]
    out.append(
        "Re-fitted model (within calibration bounds): "
        + ", ".join(f"{k} {v:.4g}" for k, v in d.refit["parameters"].items())
    )
    out.append(
        f"Held-out blocks {d.decisions['held_out_blocks']} of {d.decisions['blocks']}: tip RMS as built "
        f"{_mm(d.heldout_rms_nominal_m)}, re-fitted {_mm(d.heldout_rms_before_m)}; marker noise {_mm(d.noise_m)}"
    )
    out += ["", "Located mismatch"] + ["  " + s for s in d.located["summary"]]
    out += ["", "Candidates (held-out tip RMS, probability)"]
    for c in d.candidates:
        muscle = f" [{c['muscle']}]" if c.get("muscle") else ""
        muscle = f" [{c['muscle']} from {c['source_muscle']}]" if c.get("source_muscle") else muscle
        out.append(f"  {c['name'] + muscle:26s} {_mm(c['heldout_rms_m']):>10s}  p = {c['probability']:.3f}")
    out.append("")
    v = d.verdict
    if v["answer"] == "none":
        out.append(f"Found: none ({v['reason']}; p = {v['probability']:.2f})")
    for e in d.effects:
        muscle = f" on muscle {e['muscle']}" if e.get("muscle") else ""
        muscle += f" (from muscle {e['source_muscle']})" if e.get("source_muscle") else ""
        out.append(f"Found: {e['name']}{muscle} -- {e['summary']} (p = {e['probability']:.2f})")
        out.append(f"  equation: {e['equation']}")
        out.append("  parameters: " + ", ".join(f"{k} = {val:.4g}" for k, val in e["parameters"].items()))
        out.append(
            "  re-fit with it: " + ", ".join(f"{k} {val:.4g}" for k, val in e["refit_parameters"].items())
        )
        out.append(f"  held-out tip RMS {_mm(e['heldout_rms_before_m'])} -> {_mm(e['heldout_rms_after_m'])}")
        out.append(f"  switched on in: {e['switch_on']}")
    if v.get("unexplained"):
        out.append(
            f"UNEXPLAINED: the held-out tip error stays at {_mm(d.heldout_rms_before_m)}, above 3 x the marker "
            "noise, and no library term explains it (see 'Located mismatch')."
        )
    if v["ambiguous"]:
        paired = v["paired"]
        out.append(
            f"AMBIGUOUS: {v['answer']} and {', '.join(v['alternatives'])} are not told apart by the held-out "
            f"data (paired comparison over {paired['segments']} segments: t = {paired['t']:.2f}, "
            f"needed {paired['critical_t']:.2f})."
        )
    elif not v["confident"]:
        out.append("Not confident (probability below 0.8).")
    if d.next_experiment:
        n = d.next_experiment
        best = n["candidates"][0]
        out.append(
            f"Next experiment to separate {' and '.join(n['between'])}: {n['recommended']} "
            f"(predicted tip difference {_mm(best['predicted_rms_difference_m'])}, "
            f"{best['over_noise']:.1f} x the marker noise)"
        )
    return "\n".join(out)


def write_json(path, d: ArmDiagnosis) -> Path:
    """The diagnosis as JSON (atomically)."""
    return write_json_atomic(path, d.to_json())


def write_model(path, spec, d: ArmDiagnosis) -> Path:
    """The arm model with the re-fit and the found effect switched on, as MJCF (the command map in
    custom numerics ``efam_ctrl_*``, which :class:`.replay.Replayer` applies)."""
    replayer = Replayer(spec, d.time_s[:2], np.zeros((2, len(spec.actuators))))
    out = replayer.model_with(d.knobs_after)
    out.compile()
    return write_text_atomic(path, out.to_xml())


def figures(d: ArmDiagnosis, directory, prefix: str = "armdiag") -> list[Path]:
    """Tip error over time (as built, re-fitted, with the found effect) and the located mismatch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    t = d.time_s
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for tip, label in (
        (d.tip_nominal, "model as built"),
        (d.tip_before, "re-fitted"),
        (d.tip_after, "with " + (", ".join(d.names) or "no effect")),
    ):
        axes[0].plot(t, 1e3 * np.linalg.norm(tip - d.measured, axis=1), lw=0.8, label=label)
    for ax in axes:
        for a, b in _spans(t, d.heldout):
            ax.axvspan(a, b, color="0.9", zorder=0)
    axes[0].set_ylabel("tip error (mm)")
    axes[0].legend(fontsize=8)
    axes[0].set_title("Tip error; grey: held-out blocks")
    for i, axis in enumerate("xyz"):
        axes[1].plot(t, 1e3 * d.measured[:, i], ".", ms=1.5, color=f"C{i}", label=f"recorded {axis}")
        axes[1].plot(t, 1e3 * d.tip_after[:, i], "-", lw=0.8, color=f"C{i}")
    axes[1].set_ylabel("tip (mm); lines: identified model")
    axes[1].set_xlabel("time (s)")
    fig.tight_layout()
    path = directory / f"{prefix}_tip.png"
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return [path]


def _spans(t, mask):
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(t[a], t[min(b, len(t)) - 1]) for a, b in zip(edges[::2], edges[1::2])]


def register_cli(subparsers) -> None:
    """``efam diagnose-arm RECORDING.csv --model ARM.json``."""
    p = subparsers.add_parser(
        "diagnose-arm",
        help="why a real arm's tip differs from the MuJoCo arm's: locate, name and model it",
        description="Replay an arm recording's commands in MuJoCo, re-fit, locate the mismatch, name the "
        "missing physics with held-out probabilities and write the model with it switched on.",
    )
    p.add_argument("recording", type=Path, help="CSV: time_s, p_<muscle>_kPa..., tip_x_m, tip_y_m, tip_z_m")
    p.add_argument("--model", type=Path, required=True, help="the arm: spec file (.json) or MJCF (.xml)")
    p.add_argument("--json", type=Path, help="write the diagnosis as JSON")
    p.add_argument(
        "--report", type=Path, help="directory: report.txt, diagnosis.json, arm_identified.xml, figures"
    )
    p.add_argument(
        "--threads", type=bounded_int(1, MAX_THREADS), default=None,
        help=f"rollout threads, 1 .. {MAX_THREADS} (default: the usable cores)",
    )  # fmt: skip
    p.set_defaults(
        run=run,
        file_inputs=("recording", "model"),
        file_inputs_referenced=referenced_muscle_files,
        file_outputs=("json", "report"),
        file_positionals=("recording",),
    )


def referenced_muscle_files(args) -> dict[str, list[str]]:
    """The muscle files a spec ``--model`` names by path (``sections[i].muscles[j]``), labelled
    as a user finds them: inputs too, which no output may overwrite. A spec that cannot be read
    here names none; the run then refuses it with its own message."""
    model = getattr(args, "model", None)
    if model is None or Path(model).suffix.lower() != ".json":
        return {}
    try:
        doc = json.loads(Path(model).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    sections = doc.get("sections") if isinstance(doc, dict) else None
    out = {}
    for i, section in enumerate(sections if isinstance(sections, list) else []):
        muscles = section.get("muscles") if isinstance(section, dict) else None
        for j, muscle in enumerate(muscles if isinstance(muscles, list) else []):
            if isinstance(muscle, str) and muscle.strip():
                out[f"--model {model}: sections[{i}].muscles[{j}]"] = [muscle]
    return out


def run(args) -> int:
    """Run ``efam diagnose-arm`` with parsed arguments; returns the exit status."""
    if args.report:  # replaced as a whole: refused now, not after the diagnosis, if not ours
        check_replaceable_folder(args.report, "--report", "diagnose-arm")
    spec = load_arm_model(args.model)
    muscles = [a.name for a in spec.actuators]
    rec = read_csv(args.recording, muscles)
    d = diagnose_arm(spec, rec, threads=args.threads)
    report = text(d)
    print(report)
    outputs = OutputSet()
    if args.json:
        outputs.json(args.json, d.to_json())
    try:
        # the --json is written beside its place before the report is swapped in, and renamed
        # after: a failed run leaves neither (as efam diagnose)
        outputs.prepare()
        if args.report:  # built beside, swapped in whole (files.replace_folder), as efam diagnose's
            with replace_folder(args.report, "--report", "diagnose-arm") as staging:
                write_text_atomic(staging / "report.txt", report + "\n")
                write_json(staging / "diagnosis.json", d)
                write_model(staging / "arm_identified.xml", spec, d)
                figures(d, staging)
        outputs.commit()
    finally:
        outputs.discard()
    if args.report:
        print(
            f"wrote {visible(str(args.report))}/report.txt, diagnosis.json, arm_identified.xml, armdiag_tip.png"
        )
    if args.json:
        print(f"wrote {visible(str(args.json))}")
    return 0


def main(argv=None) -> int:
    """``python -m efam_mujoco.armdiag.report ...`` = ``efam diagnose-arm ...`` (the same checks,
    one-line errors and warnings: the efam command line runs it)."""
    from ..cli import main as efam_main

    return efam_main(["diagnose-arm", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
