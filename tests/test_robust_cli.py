"""The command line as a whole: exact flags, outputs that never overwrite inputs, atomic files and
report folders, strict JSON, a quiet closed pipe, MuJoCo's log, the Python entry points' unit
checks. Each bad input ends in a clear error, no traceback, no data loss, no stray file."""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import stat
import subprocess
import sys
import sysconfig
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from _robust import csv_text, run_bad, run_cli, snapshot, strict_load

from efam_mujoco import rig
from efam_mujoco.cli import build_parser, main
from efam_mujoco.files import (
    REPORT_MARKER,
    OutputError,
    check_outputs,
    replace_folder,
    safe_name,
    save_figure,
    strict_json,
    write_json_atomic,
    write_text_atomic,
)
from efam_mujoco.musclefile import load_muscle
from efam_mujoco.units import PressureUnitWarning, RangeError

ROOT = Path(__file__).resolve().parents[1]
GOOD_ROWS = [[0.2 * i, 0.17018 + 0.001 * i, 100.0 + 5 * i, 40.0 + 3 * i] for i in range(30)]


@pytest.fixture
def folder(tmp_path):
    """A user's folder: a recording, a muscle file, and a file named like a naive temporary."""
    (tmp_path / "rec.csv").write_text(csv_text(GOOD_ROWS))
    (tmp_path / "muscle.json").write_text(json.dumps(json.loads(load_muscle_text()), indent=1))
    (tmp_path / "notes.txt").write_text("the user's notes\n")
    return tmp_path


def load_muscle_text() -> str:
    from importlib import resources

    return resources.files("efam_mujoco.presets").joinpath("fam1.json").read_text()


# ----------------------------------------------------------------- exact flag matching
ABBREVIATIONS = [
    (["muscle", "FAM1", "--pressures", "75"], "--pressures"),
    (["muscle", "FAM1", "--press", "75"], "--press"),
    (["muscle", "FAM1", "--js", "x.json"], "--js"),
    (["muscle", "FAM1", "--stre", "linear"], "--stre"),
    (["demo", "--mus", "FAM1"], "--mus"),
    (["demo", "--o", "x"], "--o"),
    (["view", "models/rig_free_fam1.xml", "--ch"], "--ch"),
    (["arm", "--radius", "20", "--xml", "x.xml"], "--radius"),
    (["arm", "--payload", "1", "--xml", "x.xml"], "--payload"),
    (["arm", "--pressures", "75", "75", "75"], "--pressures"),
    (["arm", "--sec", "2", "--xml", "x.xml"], "--sec"),
    (["arm", "--write", "--xml", "x.xml"], "--write"),
    (["calibrate", "rec.csv", "--mus", "FAM1"], "--mus|--muscle"),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--fig", "f"], "--fig"),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--keep"], "--keep"),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--base"], "--base"),
    (["diagnose", "rec.csv", "--muscle", "FAM1", "--rep", "r"], "--rep"),
    (["diagnose", "rec.csv", "--muscle", "FAM1", "--js", "d.json"], "--js"),
    (["--mujoco", "log.txt", "muscle", "FAM1"], "--mujoco"),
    (["--vers"], "--vers"),
]


@pytest.mark.parametrize("argv, flag", ABBREVIATIONS, ids=[" ".join(a) for a, _ in ABBREVIATIONS])
def test_abbreviated_flags_are_refused(folder, capsys, argv, flag):
    run_bad(
        argv,
        folder,
        capsys,
        rf"unrecognized arguments: .*({flag})|required: --muscle|the following|invalid choice",
    )


USAGE = [
    ([], r"required: COMMAND|the following arguments are required"),
    (["bogus"], r"invalid choice: 'bogus'"),
    (["muscle"], r"required: muscle"),
    (["muscle", "FAM1", "--pressures-kPa"], r"expected at least one argument"),
    (["muscle", "FAM1", "--pressures-kPa", "abc"], r"--pressures-kPa: takes a plain decimal number.*'abc'"),
    (
        ["muscle", "FAM1", "--pressures-kPa", "2000"],
        r"--pressures-kPa: 2000 kPa is outside the rig's control range",
    ),
    (["muscle", "FAM1", "--pressures-kPa", "-5"], r"--pressures-kPa: -5 kPa is outside"),
    # said by the command's own parser (was 'efam: error: unrecognized arguments')
    (
        ["diagnose-arm", "r.csv", "r.csv", "--model", "m.xml"],
        r"^efam diagnose-arm: error: unrecognized arguments: r\.csv",
    ),
    (["muscle", "FAM1", "--bogus"], r"^efam muscle: error: unrecognized arguments: --bogus"),
    # the value as typed, not rounded into the range (was '1000 kPa is outside ... 0 .. 1000 kPa')
    (["muscle", "FAM1", "--pressures-kPa", "1000.0001"], r"--pressures-kPa: 1000\.0001 kPa is outside"),
    (["muscle", "FAM1", "--pressures-kPa", "nan"], r"--pressures-kPa: takes a plain decimal number.*'nan'"),
    (["muscle", "FAM1", "--pressures-kPa", "inf"], r"--pressures-kPa: takes a plain decimal number.*'inf'"),
    (["muscle", "FAM1", "--pressures-kPa", "1e300"], r"--pressures-kPa: 1e\+300 kPa"),
    (["muscle", "FAM1", "--pressures-kPa", *["100"] * 60], r"at most 50 pressures"),
    (["muscle", "FAM1", "--stress", "ogden"], r"invalid choice: 'ogden'"),
    (["muscle", "FAM9"], r"'FAM9' is neither a preset"),
    (["muscle", "notes.txt"], r"notes\.txt: line 1, column 1: not valid JSON"),
    (["muscle", "."], r"is a folder"),
    (["demo", "--muscle", "nope.json"], r"'nope\.json' is neither a preset"),
    (["demo", "--stress", "sigmoid"], r"no coefficients for stress law 'sigmoid'"),
    (["view"], r"required: file"),
    (["view", "nope.xml", "--check"], r"nope\.xml: no such model file"),
    (["view", "notes.txt", "--check"], r"notes\.txt: the model does not compile"),
    (["view", "muscle.json", "--check"], r"muscle\.json: the model does not compile"),
    (["view", "rec.csv", "--check"], r"rec\.csv: the model does not compile"),
    (["view", "rec.csv"], r"rec\.csv: the model does not compile"),
    (
        ["calibrate", "rec.csv", "./rec.csv", "--muscle", "FAM1"],
        r"FILE \./rec\.csv: the same recording as rec\.csv",
    ),
    (["diagnose", "rec.csv", "rec.csv", "--muscle", "FAM1"], r"given twice"),
    (["calibrate", "rec.csv"], r"required: --muscle"),
    (["calibrate", "--muscle", "FAM1"], r"required: FILE"),
    (["diagnose", "rec.csv"], r"required: --muscle"),
    (["arm", "--sections", "0", "--xml", "x.xml"], r"--sections"),
    (["arm", "--muscles-per-section", "2", "--xml", "x.xml"], r"--muscles-per-section"),
    (["arm", "--muscle", "FAM1", "FAM2", "--xml", "x.xml"], r"--muscle: give 1 muscle"),
    (["arm", "--orientation", "sideways"], r"invalid choice: 'sideways'"),
    (["arm", "--disks", "many"], r"takes a whole number"),
    (["arm", "--pressures-kPa", "100", "100"], r"--pressures-kPa: need 3"),
    (["arm", "--pressures-kPa", "100", "100", "-1"], r"--pressures-kPa: -1 kPa is outside 0 \.\. 517"),
    (["arm", "--pressures-kPa", "2000", "100", "100"], r"--pressures-kPa: 2000 kPa is outside .*clamp"),
    (
        ["arm", "--pressures-kPa", "nan", "100", "100"],
        r"--pressures-kPa: takes a plain decimal number.*'nan'",
    ),
    (["arm", "--disks", "1000", "--xml", "x.xml"], r"--disks: 1000 is outside 1 \.\. 40"),
    (["arm", "--disks", "0", "--xml", "x.xml"], r"--disks: 0 is outside"),
    (["arm", "--payload-kg", "1e300", "--xml", "x.xml"], r"--payload-kg: 1e\+300 kg is outside"),
    (["arm", "--payload-kg", "-1", "--xml", "x.xml"], r"--payload-kg: -1 kg"),
    (["arm", "--payload-kg", "inf", "--xml", "x.xml"], r"--payload-kg: takes a plain decimal number.*'inf'"),
    (["arm", "--radius-mm", "0", "--xml", "x.xml"], r"--radius-mm: 0 mm is outside"),
    (["arm", "--radius-mm", "1e308", "--xml", "x.xml"], r"--radius-mm"),
    (["arm", "--sections", "100000", "--xml", "x.xml"], r"--sections: 100000 is outside"),
    (["arm", "--muscles-per-section", "5000", "--xml", "x.xml"], r"--muscles-per-section: 5000"),
    (["arm", "--pressure-lag-s", "-1", "--xml", "x.xml"], r"--pressure-lag-s: -1 s"),
    # an empty name ran the default task without a word
    (["suite", "--domain", "", "--task", "reach"], r"--domain: an empty name"),
    (["suite", "--task", " "], r"--task: an empty name"),
]


@pytest.mark.parametrize("argv, pattern", USAGE, ids=[" ".join(a)[:60] or "nothing" for a, _ in USAGE])
def test_usage_errors_name_the_flag(folder, capsys, argv, pattern):
    run_bad(argv, folder, capsys, pattern)


REPEATED = [
    (
        ["muscle", "FAM1", "--stress", "linear", "--stress", "sigmoid"],
        r"--stress: given twice \('linear', then 'sigmoid'\)",
    ),
    (
        ["muscle", "FAM1", "--pressures-kPa", "75", "150", "--pressures-kPa", "300"],
        r"--pressures-kPa: given twice \('75 150', then '300'\)",
    ),
    (["arm", "--payload-kg", "1", "--payload-kg", "2", "--xml", "x.xml"], r"--payload-kg: given twice"),
    (
        ["calibrate", "rec.csv", "--muscle", "FAM1", "--muscle", "FAM2"],
        r"--muscle: given twice \('FAM1', then 'FAM2'\)",
    ),
    (["diagnose", "rec.csv", "--muscle", "FAM1", "--muscle=FAM2"], r"--muscle: given twice"),
    (["--mujoco-log", "a.log", "--mujoco-log", "b.log", "muscle", "FAM1"], r"--mujoco-log: given twice"),
]


@pytest.mark.parametrize("argv, pattern", REPEATED, ids=[" ".join(a)[:60] for a, _ in REPEATED])
def test_a_value_flag_given_twice_is_refused(folder, capsys, argv, pattern):
    # argparse keeps the last value: the first list of pressures was dropped without a word
    run_bad(argv, folder, capsys, pattern)


def test_every_value_flag_of_every_command_refuses_a_second_value():
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    parsers = {"efam": parser, **{f"efam {name}": sub for name, sub in commands.choices.items()}}
    plain = [
        f"{prog} {'/'.join(action.option_strings)}"
        for prog, p in parsers.items()
        for action in p._actions
        if action.option_strings and type(action) is argparse._StoreAction
    ]
    assert not plain, f"value flags that keep the last of two values silently: {plain}"
    # and parsing the same command line twice with one parser is not a repeat
    for _ in range(2):
        args = parser.parse_args(["muscle", "FAM1", "--stress", "linear"])
        assert args.stress == "linear"


@pytest.mark.parametrize("verb", ["calibrate", "diagnose"])
def test_a_copy_of_a_recording_under_another_name_is_refused(folder, capsys, verb):
    # the same samples under another name would count twice (every error bar halved)
    (folder / "copy.csv").write_bytes((folder / "rec.csv").read_bytes())
    run_bad([verb, "rec.csv", "copy.csv", "--muscle", "FAM1"], folder, capsys,
            r"FILE copy\.csv: the same samples as rec\.csv \(a copy")  # fmt: skip


# ------------------------------------------------------------- outputs never overwrite inputs
OVERWRITES = [
    (
        ["muscle", "muscle.json", "--json", "muscle.json"],
        r"--json muscle\.json would overwrite the input MUSCLE muscle\.json",
    ),
    (["muscle", "muscle.json", "--json", "./sub/../muscle.json"], r"would overwrite the input"),
    (["muscle", "muscle.json", "--json", "link.json"], r"would overwrite the input"),
    (
        ["calibrate", "rec.csv", "--muscle", "FAM1", "--out", "rec.csv"],
        r"--out rec\.csv would overwrite the input FILE rec\.csv",
    ),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--json", "rec.csv"], r"--json rec\.csv would overwrite"),
    (
        ["calibrate", "rec.csv", "--muscle", "muscle.json", "--out", "muscle.json"],
        r"--out muscle\.json would overwrite the input --muscle",
    ),
    (
        ["calibrate", "rec.csv", "--muscle", "muscle.json", "--json", "muscle.json"],
        r"would overwrite the input --muscle",
    ),
    (
        ["calibrate", "rec.csv", "--muscle", "FAM1", "--out", "x.json", "--json", "x.json"],
        r"--out and --json are the same file",
    ),
    (
        # the muscle file named as one of the figures: refused by its name first (JSON as .png)
        ["calibrate", "rec.csv", "--muscle", "FAM1", "--figures", "fig", "--out", "fig_blocked.png"],
        r"--out fig_blocked\.png: writes JSON, but '\.png' names another kind of file",
    ),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--figures", "rec.csv"], r""),
    (
        ["diagnose", "rec.csv", "--muscle", "FAM1", "--json", "rec.csv"],
        r"--json rec\.csv would overwrite the input FILE",
    ),
    (
        ["diagnose", "rec.csv", "--muscle", "muscle.json", "--json", "muscle.json"],
        r"would overwrite the input --muscle",
    ),
    (
        ["diagnose", "rec.csv", "--muscle", "FAM1", "--report", "."],
        r"--report \. would overwrite the input FILE rec\.csv",
    ),
    (
        ["diagnose", "rec.csv", "--muscle", "FAM1", "--report", "rec.csv"],
        r"is a file, not a folder|would overwrite",
    ),
    (
        ["diagnose", "rec.csv", "--muscle", "FAM1", "--report", "userdir"],
        r"--report userdir exists, is not empty and is not an efam report",
    ),
    (
        ["arm", "--muscle", "muscle.json", "--xml", "muscle.json"],
        r"--xml muscle\.json would overwrite the input --muscle",
    ),
    (
        ["arm", "--muscle", "muscle.json", "--pressures-kPa", "1", "1", "1", "--json", "muscle.json"],
        r"would overwrite the input --muscle",
    ),
    (["demo", "--muscle", "muscle.json", "--out", "."], r"--out \. would overwrite the input --muscle"),
    (["demo", "--out", "userdir"], r"--out userdir exists, is not empty and is not an efam report"),
    (["demo", "--out", "notes.txt"], r"is a file, not a folder"),
    (
        ["--mujoco-log", "rec.csv", "view", "rec.csv", "--check"],
        r"--mujoco-log rec\.csv would overwrite the input FILE",
    ),
    (
        ["--mujoco-log", "muscle.json", "muscle", "muscle.json"],
        r"--mujoco-log muscle\.json would overwrite the input",
    ),
    (["muscle", "FAM1", "--json", "."], r"--json: '\.' is not a file name"),
    (["muscle", "FAM1", "--json", ""], r"--json: an empty file name"),
    (["muscle", "FAM1", "--json", "sub"], r"sub: is a folder"),
    (
        ["muscle", "FAM1", "--json", "notes.txt/x.json"],
        r"--json notes\.txt/x\.json: notes\.txt is a file, not a folder",
    ),
    (
        ["calibrate", "rec.csv", "--muscle", "FAM1", "--out", "o.json", "--figures", "notes.txt/f"],
        r"--figures .*notes\.txt is a file",
    ),
    # a folder as the prefix wrote 'sub/_blocked.png' (and '--figures .' the hidden '._blocked.png')
    (
        ["calibrate", "rec.csv", "--muscle", "FAM1", "--figures", "sub"],
        r"--figures sub: is a folder; give a prefix",
    ),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--figures", "."], r"e\.g\. fam1 writes fam1_blocked\.png"),
    (["calibrate", "rec.csv", "--muscle", "FAM1", "--figures", "new/"], r"--figures new/: is a folder"),
    (
        ["diagnose", "rec.csv", "--muscle", "FAM1", "--report", "notes.txt/r"],
        r"--report notes\.txt/r: notes\.txt is a file",
    ),
    # verbs whose file flags were not declared: their outputs overwrote their inputs, and a
    # figure asked into a folder was written beside it as <folder>.png
    (
        [
            "size",
            "--stroke",
            "0.5",
            "--force",
            "0",
            "--pressure",
            "300",
            "--stress-from",
            "muscle.json",
            "--json",
            "muscle.json",
        ],
        r"--json muscle\.json would overwrite the input --stress-from muscle\.json",
    ),  # fmt: skip
    (
        ["size", "--stroke", "0.5", "--force", "0", "--pressure", "300", "--figure", "sub"],
        r"--figure sub: is a folder",
    ),
    (
        ["diagnose-arm", "rec.csv", "--model", "muscle.json", "--json", "rec.csv"],
        r"--json rec\.csv would overwrite the input RECORDING rec\.csv",
    ),
    (
        ["diagnose-arm", "rec.csv", "--model", "muscle.json", "--json", "muscle.json"],
        r"--json muscle\.json would overwrite the input --model muscle\.json",
    ),
    (
        ["diagnose-arm", "rec.csv", "--model", "sub/arm.xml", "--report", "sub"],
        r"--report sub would overwrite the input --model sub/arm\.xml",
    ),
    (["suite", "--episodes", "1", "--strip", "sub"], r"--strip sub: is a folder"),
    (["--mujoco-log", "sub", "muscle", "FAM1"], r"--mujoco-log sub: is a folder; give a log file's name"),
    (["--mujoco-log", "", "muscle", "FAM1"], r"--mujoco-log: '' is not a file name"),
]


@pytest.mark.parametrize("argv, pattern", OVERWRITES, ids=[" ".join(a)[:70] for a, _ in OVERWRITES])
def test_an_output_never_overwrites_an_input(folder, capsys, argv, pattern):
    (folder / "link.json").symlink_to(folder / "muscle.json")
    (folder / "sub").mkdir()
    (folder / "sub" / "arm.xml").write_text("<mujoco/>\n")  # an input inside an output folder
    (folder / "userdir").mkdir()
    (folder / "userdir" / "precious.csv").write_text("1,2\n")
    (folder / "rec.csv_blocked.png").write_bytes(b"not really")  # an input-like figure name
    if argv[-1] == "rec.csv_":
        argv = ["calibrate", "rec.csv", "rec.csv_blocked.png", "--muscle", "FAM1", "--figures", "rec.csv"]
        pattern = r"would overwrite the input FILE rec\.csv_blocked\.png"
    run_bad(argv, folder, capsys, pattern)


def test_a_file_named_like_a_preset_is_not_silently_shadowed(folder, capsys):
    (folder / "fam1").write_text((folder / "muscle.json").read_text())
    run_bad(["muscle", "fam1"], folder, capsys, r"'fam1' is both a preset and a file here; write \./fam1")
    code, out, err = run_cli(["muscle", "./fam1", "--pressures-kPa", "300"], folder, capsys)
    assert code == 0, err


def test_never_writes_into_site_packages(folder, capsys):
    site = Path(sysconfig.get_paths()["purelib"])
    run_bad(["arm", "--write-models", "--models-dir", str(site / "efam_models")], folder, capsys,
            r"--models-dir .* is inside the installed package")  # fmt: skip
    run_bad(
        ["muscle", "FAM1", "--json", str(site / "x.json")], folder, capsys, r"inside the installed package"
    )
    assert not (site / "efam_models").exists() and not (site / "x.json").exists()
    with pytest.raises(OutputError, match="inside the installed package"):
        rig.write_models(str(site / "efam_models"))


# ---------------------------------------------------------------------- atomic outputs
def test_a_file_named_like_a_temporary_survives(folder, capsys):
    (folder / "out.json.tmp").write_text("the user's own file\n")
    code, out, err = run_cli(["muscle", "FAM1", "--json", "out.json"], folder, capsys)
    assert code == 0, err
    assert (folder / "out.json.tmp").read_text() == "the user's own file\n"
    assert strict_load(folder / "out.json")["rows"][0]["pressure_kPa"] == pytest.approx(103.42, abs=0.01)
    assert not [p for p in os.listdir(folder) if "efam-tmp" in p]


def test_failed_write_keeps_the_old_file_and_leaves_nothing(tmp_path):
    path = write_text_atomic(tmp_path / "out.json", '{"kept": true}\n')
    with pytest.raises(OutputError, match=r"\$\.rows\[1\]\.force is inf"):
        write_json_atomic(path, {"rows": [{"force": 1.0}, {"force": float("inf")}]})
    with pytest.raises(OutputError, match=r"\$\.x is nan"):
        write_json_atomic(path, {"x": np.float64("nan")})
    with pytest.raises(TypeError):
        write_json_atomic(path, {"bad": object()})
    assert path.read_text() == '{"kept": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_an_output_set_that_fails_on_its_second_file_leaves_the_first_as_it_was(tmp_path, monkeypatch):
    from efam_mujoco import files

    (tmp_path / "a.json").write_text('{"mine": 1}\n')
    real = files._temporary_beside

    def refuse(path, suffix=""):
        if path.name == "b.json":
            raise OutputError(f"cannot write {path} (Permission denied)")
        return real(path, suffix)

    monkeypatch.setattr(files, "_temporary_beside", refuse)
    outputs = files.OutputSet()
    outputs.json(tmp_path / "a.json", {"new": 1})
    outputs.json(tmp_path / "b.json", {"new": 2})
    with pytest.raises(OutputError, match=r"cannot write .*b\.json"):
        outputs.commit()
    assert (tmp_path / "a.json").read_text() == '{"mine": 1}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]


@pytest.mark.parametrize(
    "argv, pattern",
    [
        (
            ["muscle", "FAM1", "--json", "table.png"],
            r"--json table\.png: writes JSON, but '\.png' names another kind",
        ),
        (["arm", "--xml", "arm.json"], r"--xml arm\.json: writes XML, but '\.json' names another kind"),
        (["muscle", "FAM1", "--json", "table.xml"], r"--json table\.xml: writes JSON, but '\.xml'"),
    ],
)
def test_a_text_output_named_like_another_kind_of_file_is_refused(folder, capsys, argv, pattern):
    run_bad(argv, folder, capsys, pattern)


REPLACED = [
    # a recording saved as .txt, a muscle file, a note: an output of another kind does not replace them
    (["muscle", "FAM1", "--json", "table.txt"], "table.txt", "time_s,length_m,pressure_kPa,force_N\n0,0.17,100,5\n",
     r"--json table\.txt: the file exists and does not hold JSON \(it begins 'time_s,length_m"),
    (["muscle", "FAM1", "--json", "notes.txt"], None, None, r"--json notes\.txt: the file exists and does not hold JSON"),
    (["muscle", "FAM1", "--json", "mine.json"], "mine.json", None, r"--json mine\.json: the file is a muscle file \(efam_mujoco\.muscle/1\)"),
    (["arm", "--xml", "notes.xml"], "notes.xml", "a note\n", r"--xml notes\.xml: the file exists and does not hold XML"),
]  # fmt: skip


@pytest.mark.parametrize("argv, name, text, pattern", REPLACED, ids=[" ".join(a) for a, *_ in REPLACED])
def test_an_output_does_not_replace_a_file_of_another_kind(folder, capsys, argv, name, text, pattern):
    if name is not None:
        (folder / name).write_text(text if text is not None else load_muscle_text())
    run_bad(argv, folder, capsys, pattern)


def test_an_output_replaces_its_own_kind(folder, capsys):
    # a second run over its own table, and calibrate's muscle file over a muscle file
    for _ in range(2):
        code, _, err = run_cli(
            ["muscle", "FAM1", "--pressures-kPa", "100", "--json", "t.json"], folder, capsys
        )
        assert code == 0, err
    assert json.loads((folder / "t.json").read_text())
    (folder / "blank.json").write_text("\n  \n")  # blank: nothing to lose
    code, _, err = run_cli(
        ["muscle", "FAM1", "--pressures-kPa", "100", "--json", "blank.json"], folder, capsys
    )
    assert code == 0 and json.loads((folder / "blank.json").read_text()), err
    from efam_mujoco.files import check_replaced_kind
    from efam_mujoco.musclefile import FORMAT

    check_replaced_kind("--out", folder / "muscle.json", "JSON", FORMAT)  # no error
    with pytest.raises(OutputError, match="is a muscle file"):
        check_replaced_kind("--json", folder / "muscle.json", "JSON")


def test_a_recording_after_allow_is_told_as_a_file(folder, capsys):
    # --allow takes every word after it: the recording was reported as an invalid check
    run_bad(["calibrate", "--muscle", "FAM1", "--allow", "force-dead", "rec.csv"], folder, capsys,
            r"--allow: 'rec\.csv' is not a check but looks like a file: .*give the recordings before --allow")  # fmt: skip


def test_strict_json_converts_numpy_and_refuses_non_finite():
    text = strict_json({"a": np.arange(3), "b": np.float32(1.5), "c": (1, 2), "d": None})
    assert json.loads(text) == {"a": [0, 1, 2], "b": 1.5, "c": [1, 2], "d": None}
    for bad in (float("nan"), float("-inf"), np.array([1.0, np.inf]), 1e308 * 10):
        with pytest.raises(OutputError, match="not a finite number"):
            strict_json({"v": bad})


def test_figure_is_written_whole_or_not_at_all(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    path = save_figure(fig, tmp_path / "f.png")
    old = path.read_bytes()
    assert old.startswith(b"\x89PNG")

    class Failing:
        def savefig(self, target, **kw):
            Path(target).write_bytes(b"\x89PNG half")
            raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        save_figure(Failing(), path)
    assert path.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.png"]
    plt.close(fig)


def test_report_folder_is_replaced_as_a_whole(tmp_path):
    report = tmp_path / "report"
    with replace_folder(report) as staging:
        (staging / "a.txt").write_text("first run")
        (staging / "old_figure.png").write_bytes(b"x")
    assert (report / REPORT_MARKER).is_file()
    with pytest.raises(RuntimeError), replace_folder(report) as staging:  # a run that dies midway
        (staging / "a.txt").write_text("half")
        raise RuntimeError("killed")
    assert (report / "a.txt").read_text() == "first run"
    with replace_folder(report) as staging:
        (staging / "a.txt").write_text("second run")
    assert sorted(p.name for p in report.iterdir()) == [REPORT_MARKER, "a.txt"]  # nothing stale
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]  # no temporaries


def test_a_report_folder_holding_anything_but_its_report_is_not_replaced(tmp_path):
    """The marker lists the report's files with their sha256: a file the user added, a report
    file the user edited, or a hand-made marker makes the folder the user's, never replaced."""
    report = tmp_path / "report"
    with replace_folder(report) as staging:
        (staging / "a.txt").write_text("first run")
        (staging / "figures").mkdir()
        (staging / "figures" / "f.png").write_bytes(b"png")
    with replace_folder(report) as staging:  # untouched: replaced
        (staging / "a.txt").write_text("second run")
    (report / "my_notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"my_notes\.txt is not a file the report wrote"):
        with replace_folder(report) as staging:
            pass
    (report / "my_notes.txt").unlink()
    (report / "a.txt").write_text("second run, with my notes")
    with pytest.raises(OutputError, match=r"a\.txt was changed after the report wrote it"):
        with replace_folder(report):
            pass
    assert (report / "a.txt").read_text() == "second run, with my notes"
    forged = tmp_path / "forged"
    forged.mkdir()
    (forged / REPORT_MARKER).write_text("")
    (forged / "thesis.tex").write_text("years of work")
    with pytest.raises(OutputError, match="lists no report files"):
        with replace_folder(forged):
            pass
    assert (forged / "thesis.tex").read_text() == "years of work"


def test_a_report_folder_given_through_a_link_is_written_where_it_points(tmp_path):
    target = tmp_path / "target"
    link = tmp_path / "link"
    link.symlink_to(target, target_is_directory=True)
    with pytest.raises(OutputError, match="does not exist"):  # a dangling link: not replaced by a folder
        with replace_folder(link):
            pass
    target.mkdir()
    with replace_folder(link) as staging:
        (staging / "a.txt").write_text("through the link")
    assert link.is_symlink() and (target / "a.txt").read_text() == "through the link"


def test_demo_refuses_its_out_folder_before_the_work(folder, capsys, monkeypatch):
    import efam_mujoco.report as report

    monkeypatch.setattr(report, "compare", lambda *a, **k: pytest.fail("computed before refusing --out"))
    (folder / "a_file").write_text("x")
    code, _, err = run_cli(["demo", "--out", "a_file"], folder, capsys)
    assert code == 2 and "is a file, not a folder" in err
    code, _, err = run_cli(["demo", "--out", "."], folder, capsys)
    assert code == 2 and "is the folder you are in" in err


def test_no_output_lands_inside_the_package_folder_even_in_a_checkout():
    """An editable install's presets are inputs (a preset name reads them): --json over
    efam_mujoco/presets/fam1.json replaced FAM1 for every later command."""
    from importlib import resources

    preset = Path(str(resources.files("efam_mujoco.presets").joinpath("fam1.json")))
    with pytest.raises(OutputError, match="inside the installed package"):
        check_outputs({"--json": str(preset)}, {})


@pytest.mark.parametrize(
    "name, expected",
    [
        ("../../evil", "evil"),
        ("/etc/passwd", "etc_passwd"),
        ("..", "muscle"),
        ("", "muscle"),
        ("a/b\\c", "a_b_c"),
        (".hidden", "hidden"),
        ("FAM1", "FAM1"),
        ("x" * 300, "x" * 80),
        ("nul\x00byte", "nul_byte"),
        ("名前", "muscle"),
        ("a..b", "a.b"),
        ("CON", "CON"),
    ],
)
def test_safe_name(name, expected):
    assert safe_name(name, "muscle") == expected


def test_muscle_name_cannot_write_outside_out(folder, capsys):
    doc = json.loads(load_muscle_text())
    doc["name"] = "../../escaped"
    (folder / "evil.json").write_text(json.dumps(doc))
    code, out, err = run_cli(["demo", "--muscle", "evil.json", "--out", "demo_out"], folder, capsys)
    assert code == 0, err
    assert sorted(p.name for p in (folder / "demo_out").iterdir()) == [
        REPORT_MARKER, "demo.json", "force_stroke_escaped.png",
    ]  # fmt: skip
    assert not list(folder.parent.glob("*escaped*")) and not list(folder.glob("*escaped*"))
    strict_load(folder / "demo_out" / "demo.json")


def test_a_muscle_name_cannot_break_the_generated_xml(tmp_path):
    import mujoco

    from efam_mujoco.plugin import load

    load()
    muscle = load_muscle("FAM1")
    from dataclasses import replace

    evil = replace(muscle, name="x --> <worldbody><body/></worldbody> <!-- \n y-")
    xml = rig.rig_xml(evil)
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.nbody == rig.build_rig(muscle)[0].nbody


def test_demo_replaces_its_previous_folder_only(folder, capsys):
    assert run_cli(["demo", "--out", "d"], folder, capsys)[0] == 0
    assert "force_stroke_fam1.png" in os.listdir(folder / "d")
    assert run_cli(["demo", "--muscle", "FAM2", "--out", "d"], folder, capsys)[0] == 0
    assert "force_stroke_fam1.png" not in os.listdir(folder / "d")  # the earlier report's, gone
    (folder / "d" / "my_notes.txt").write_text("mine")  # a file the user keeps there: not deleted
    code, _, err = run_cli(["demo", "--out", "d"], folder, capsys)
    assert code == 2 and "my_notes.txt is not a file the report wrote" in err
    assert (folder / "d" / "my_notes.txt").read_text() == "mine"


def test_check_outputs_api(tmp_path):
    a = tmp_path / "a.csv"
    a.write_text("x")
    with pytest.raises(OutputError, match="--json .*a.csv would overwrite the input FILE"):
        check_outputs({"--json": a}, {"FILE": [a]})
    with pytest.raises(OutputError, match="same file"):
        check_outputs({"--out": tmp_path / "o", "--json": tmp_path / "o"}, {})
    check_outputs({"--json": tmp_path / "b.json", "--x": None}, {"FILE": [a, None]})


# ------------------------------------------------------------------------ the CLI itself
def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("efam_mujoco ")


def test_every_flag_has_help_and_shows_its_default():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    missing = []
    for name, command in sub.choices.items():
        assert command.allow_abbrev is False, name
        for action in command._actions:
            if not action.option_strings or action.dest == "help":
                continue
            help_text = command.formatter_class(name)._get_help_string(action)
            if name == "arm" and not action.help:
                missing.append(f"arm {action.option_strings[0]}")  # arm.py is being rewritten
                continue
            assert action.help, f"{name} {action.option_strings[0]} has no help"
            if action.default not in (None, False, []) and action.nargs != 0:
                assert "default" in help_text.lower(), f"{name} {action.option_strings[0]}: {help_text}"
    assert missing in ([], ["arm --orientation"])


def test_closed_pipe_ends_quietly(tmp_path):
    """`efam muscle FAM1 | head`: the reader goes away; no 'Broken pipe' traceback."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "efam_mujoco.cli", "muscle", "FAM1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path,
    )  # fmt: skip
    proc.stdout.close()  # closed before anything is written: every write fails with EPIPE
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0, err
    assert "Traceback" not in err and "Broken pipe" not in err and "BrokenPipe" not in err, err
    assert os.listdir(tmp_path) == []


def test_sigterm_leaves_no_half_report(tmp_path):
    """A diagnose killed (SIGTERM) while it works: the previous report stays whole, no
    temporaries are left."""
    from efam_mujoco.diagnose.synth import synthesize
    from efam_mujoco.recordings import write_csv

    rec, _ = synthesize(1, effect="friction", base="fam1")
    write_csv(tmp_path / "rec.csv", rec)
    with replace_folder(tmp_path / "rep") as staging:
        (staging / "report.txt").write_text("previous run\n")
    before = snapshot(tmp_path)
    ready = (
        "import sys; import efam_mujoco.diagnose; from efam_mujoco.cli import main; "
        "print('ready', flush=True); sys.exit(main(sys.argv[1:]))"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", ready, "diagnose", "rec.csv", "--muscle", "FAM1", "--report", "rep"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path,
    )  # fmt: skip
    assert proc.stdout.readline().strip() == b"ready"  # imports done: main() is about to run
    time.sleep(1.5)  # inside the diagnosis (several seconds)
    proc.send_signal(signal.SIGTERM)
    err = proc.stderr.read().decode()
    code = proc.wait(timeout=60)
    if code == 0:  # finished before the signal (a fast machine): the report was replaced whole
        assert (tmp_path / "rep" / "report.txt").read_text() != "previous run\n"
    else:
        assert code == 130 and "interrupted" in err and "Traceback" not in err, err
        assert snapshot(tmp_path) == before
    assert not [p for p in os.listdir(tmp_path) if "efam-" in p]


def test_view_without_a_display_says_so(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    model = ROOT / "models" / "rig_free_fam1.xml"
    run_bad(["view", str(model)], tmp_path, capsys, r"no display to open a window on.*--check")


def test_mujoco_log_goes_where_the_user_says(tmp_path, capsys):
    unstable = tmp_path / "unstable.xml"
    unstable.write_text(
        '<mujoco><option timestep="1"/><worldbody><body><joint name="j" type="slide" axis="1 0 0"/>'
        '<geom size="0.01" mass="1e-9"/></body></worldbody><actuator><motor joint="j" gear="1e12" '
        'ctrllimited="true" ctrlrange="0 1e12"/></actuator></mujoco>'
    )
    err = run_bad(["view", "unstable.xml", "--check"], tmp_path, capsys, r"unstable with every actuator")
    assert "MuJoCo warning" in err or "unstable" in err
    code, out, err = run_cli(["--mujoco-log", "log.txt", "view", "unstable.xml", "--check"], tmp_path, capsys)
    assert code == 2 and "unstable" in err
    assert "Nan, Inf or huge value" in (tmp_path / "log.txt").read_text()
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_view_check_refuses_a_law_that_overflows(tmp_path, capsys):
    from efam_mujoco.stress import StressLaw

    muscle = load_muscle("FAM1").with_stress(
        StressLaw("exponential_decay", (1.479e6, 1.9771, 121646.0, 5000.0))
    )
    (tmp_path / "nan.xml").write_text(rig.rig_xml(muscle, rig.RigOptions(mode="free")))
    run_bad(
        ["view", "nan.xml", "--check"],
        tmp_path,
        capsys,
        r"nan\.xml: efam\.muscle instance 'muscle'.*not finite",
    )
    (tmp_path / "bad.xml").write_text(
        rig.rig_xml(load_muscle("FAM1")).replace(
            'key="rest_length_m" value="', 'key="rest_length_m" value="-'
        )
    )
    run_bad(
        ["view", "bad.xml", "--check"],
        tmp_path,
        capsys,
        r"config key 'rest_length_m'.*must be in 0.0001 .. 10 m",
    )


def test_rejected_configs_then_a_good_one(tmp_path):
    """Plugin init failures free what MuJoCo allocated (no double free, no crash): a model whose
    second instance is bad is refused with the key named, over and over, then a good one runs."""
    import mujoco

    from efam_mujoco.plugin import load

    load()
    muscle = load_muscle("FAM1")
    good = rig.rig_xml(muscle)
    instance = good.split("<instance")[1].split("</instance>")[0]
    second = (
        "<instance"
        + instance.replace('name="muscle"', 'name="spare"').replace(
            'key="deadband_Pa" value="', 'key="deadband_Pa" value="-'
        )
        + "</instance>"
    )
    bad = good.replace("</instance>", "</instance>\n" + second, 1)
    for _ in range(200):
        with pytest.raises(ValueError, match=r"instance 'spare'.*deadband_Pa"):
            mujoco.MjModel.from_xml_string(bad)
    model = mujoco.MjModel.from_xml_string(good)
    data = mujoco.MjData(model)
    data.ctrl[0] = 300e3
    mujoco.mj_step(model, data)
    assert np.isfinite(data.actuator_force).all()


# ---------------------------------------------------------- Python entry points and units
def test_pressure_in_kpa_given_as_pa_warns():
    muscle = load_muscle("FAM1")
    for call in (
        lambda: muscle.blocked_push(300),
        lambda: muscle.blocked_tension([0, 300]),
        lambda: muscle.free_length(500),
        lambda: rig.stroke_forces(muscle, 300, [muscle.rest_length_m]),
    ):
        with pytest.warns(PressureUnitWarning, match=r"300 Pa|500 Pa"):
            call()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        muscle.blocked_push(300e3)  # Pa: no warning
        muscle.blocked_push(0.0)


def test_arm_reference_checks_the_section_pressure_set_not_each_muscle():
    """A strongly differential section (one muscle near 0 Pa, the others at hundreds of kPa) is a
    genuine pressure set; a section whose every pressure is a few hundred "Pa" is a unit slip."""
    from efam_mujoco.arm import SectionSpec, continuum

    section = SectionSpec(muscles=(load_muscle("FAM1"),) * 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        continuum.solve_arm([section], [[404.0, 400e3, 420e3]])
    with pytest.warns(PressureUnitWarning, match="420 Pa"):
        continuum.solve_arm([section], [[404.0, 400.0, 420.0]])


def test_saturation_is_never_silent():
    muscle = load_muscle("FAM1")
    with pytest.raises(RangeError, match=r"2e\+06 Pa is outside \[0, 1e\+06\] Pa"):
        rig.stroke_forces(muscle, 2e6, [muscle.rest_length_m])
    with pytest.raises(RangeError, match="outside"):
        rig.equilibrium_length(muscle, -5e3)
    from efam_mujoco.report import compare

    with pytest.raises(RangeError, match="pressures_Pa"):
        compare(muscle, [300e3, 1.5e6])


def test_blocked_force_names_carry_their_sign():
    muscle = load_muscle("FAM1")
    p = 300e3
    assert muscle.blocked_push(p) == pytest.approx(-muscle.blocked_tension(p))
    assert muscle.blocked_push(p) > 0  # an EFAM pushes
    assert rig.blocked_push(muscle, p) == pytest.approx(muscle.blocked_push(p), rel=0.005)
    assert rig.blocked_tension(muscle, p) == pytest.approx(muscle.blocked_tension(p), rel=0.005)
    with pytest.warns(DeprecationWarning, match="blocked_tension"):
        assert muscle.blocked_force(p) == muscle.blocked_tension(p)
    with pytest.warns(DeprecationWarning, match="blocked_push"):
        assert rig.blocked_force(muscle, p) == rig.blocked_push(muscle, p)


def test_muscle_json_is_strict_and_complete(folder, capsys):
    code, out, err = run_cli(
        ["muscle", "FAM1", "--json", "table.json", "--pressures-kPa", "0", "1000"], folder, capsys
    )
    assert code == 0, err
    doc = strict_load(folder / "table.json")
    assert [r["pressure_kPa"] for r in doc["rows"]] == [0.0, 1000.0]
    assert doc["sign"].startswith("blocked_force_N positive = the muscle pushes")
    assert doc["rows"][1]["blocked_push_N"] == doc["rows"][1]["blocked_force_N"]
    assert doc["rows"][1]["blocked_push_N"]["analytic"] > 0  # an EFAM pushes


def test_mujoco_log_that_cannot_be_written_is_not_silent(tmp_path, capsys):
    """A log whose folder cannot be made (a file is in its way) is refused before the work (a
    missing folder is made, as for every output); a log that fails while writing (a full disk)
    still shows the warning on standard error instead of dropping it."""
    from efam_mujoco import files

    (tmp_path / "notes.txt").write_text("the user's notes\n")
    run_bad(["--mujoco-log", "notes.txt/mujoco.log", "muscle", "FAM1"], tmp_path, capsys,
            r"--mujoco-log notes\.txt/mujoco\.log: notes\.txt is a file, not a folder")  # fmt: skip
    if Path("/dev/full").exists():
        try:
            files.route_mujoco_log("/dev/full")
            files._mujoco_warning("Nan, Inf or huge value in QACC at DOF 0")
        finally:
            files.route_mujoco_log(None)
        err = capsys.readouterr().err
        assert "huge value in QACC" in err and "not written to --mujoco-log /dev/full" in err


@pytest.mark.parametrize("value", ["1_000", "\uff17\uff15", "nan", "inf", "0x10", "75 kPa"])
def test_number_flags_read_plain_decimals_only(tmp_path, capsys, value):
    """Python's float() reads '1_000', full-width digits, 'nan' and 'inf': every float and int
    flag of every command reads plain ASCII decimals, as the recordings do."""
    code, _, err = run_cli(["muscle", "FAM1", f"--pressures-kPa={value}"], tmp_path, capsys)
    assert code == 2 and "argument --pressures-kPa" in err and repr(value) in err
    if value not in ("nan", "inf"):
        code, _, err = run_cli(["suite", f"--seed={value}"], tmp_path, capsys)
        assert code == 2 and "argument --seed" in err


@pytest.mark.parametrize(
    "argv", [["muscle", "FAM1", "--pressures-kPa", "abc"], ["bogus"], [], ["suite", "--seed"]]
)
def test_usage_errors_are_one_line_with_where_the_help_is(tmp_path, capsys, argv):
    code, _, err = run_cli(argv, tmp_path, capsys)
    assert code == 2 and err.count("\n") == 1 and "usage:" not in err and "--help)" in err


def test_outputs_never_replace_a_device_a_pipe_or_a_link(tmp_path, capsys):
    """Renaming a temporary over the path turned /dev/null (as root), a FIFO, or a link into a
    regular file: a device or pipe is refused; a link is written through, and kept."""
    os.mkfifo(tmp_path / "pipe.json")
    code, _, err = run_cli(["muscle", "FAM1", "--json", "pipe.json"], tmp_path, capsys)
    assert code == 2 and "is not a regular file (a device, a pipe or a socket)" in err
    assert stat.S_ISFIFO(os.lstat(tmp_path / "pipe.json").st_mode)
    (tmp_path / "real.json").write_text("{}")
    (tmp_path / "link.json").symlink_to(tmp_path / "real.json")
    assert run_cli(["muscle", "FAM1", "--json", "link.json"], tmp_path, capsys)[0] == 0
    assert (tmp_path / "link.json").is_symlink() and '"FAM1"' in (tmp_path / "real.json").read_text()


def test_a_file_output_inside_a_report_folder_is_refused(tmp_path):
    """--json rep/report.txt with --report rep: one silently replaced the other."""
    with pytest.raises(OutputError, match="is inside the --report folder"):
        check_outputs({"--json": tmp_path / "rep" / "report.txt", "--report": tmp_path / "rep"}, {})


def test_the_python_api_refuses_the_same_samples_twice():
    from efam_mujoco import load_muscle
    from efam_mujoco.calibrate import calibrate
    from efam_mujoco.diagnose import diagnose
    from efam_mujoco.recordings import Recording, RecordingError

    t = np.linspace(0, 10, 2000)
    rec = Recording(t, 0.17 + 0.01 * np.sin(t), 2e5 + 0 * t, 50 + np.sin(t), {"source": "a.csv"})
    twin = Recording(rec.time_s.copy(), rec.length_m.copy(), rec.pressure_Pa.copy(), rec.force_N.copy())
    for fit in (calibrate, diagnose):
        with pytest.raises(RecordingError, match=r"recordings\[1\]: the same samples as a\.csv"):
            fit([rec, twin], load_muscle("FAM1"))


@pytest.mark.parametrize("verb", [["view"], ["muscle"], ["calibrate", "--muscle", "FAM1"]])
def test_a_control_character_in_a_file_name_reaches_the_terminal_escaped(folder, capsys, verb):
    # an escape sequence in a name (here: switch to red) must not be sent to the terminal as is
    name = "\x1b[31mred.csv"
    err = run_bad([*verb, name], folder, capsys, r"\\x1b\[31mred\.csv")
    assert "\x1b" not in err


def test_a_written_file_with_an_escape_sequence_in_its_name_is_reported_escaped(folder, capsys):
    # the success line too: the file is written under its own name, the terminal sees the escape
    name = "arm\x1b[31mred.xml"
    code, out, err = run_cli(["arm", "--xml", name], folder, capsys)
    assert code == 0, err
    assert (folder / name).is_file()
    assert "\x1b" not in out and "arm\\x1b[31mred.xml" in out, out


def test_an_unrecognised_argument_with_an_escape_sequence_is_shown_escaped(folder, capsys):
    err = run_bad(["muscle", "FAM1", "\x1b[31mX"], folder, capsys, r"unrecognized arguments: \\x1b\[31mX")
    assert "\x1b" not in err


def test_a_message_keeps_spaces_and_accents_and_escapes_only_control_characters(folder, capsys):
    # two spaces in a name are part of it, a no-break space and an accent are printable
    err = run_bad(["view", "my  r\u00e9c\u00a0 file.xml"], folder, capsys, "my  r\u00e9c\u00a0 file\\.xml")
    assert "\\u" not in err and "\\x" not in err


def test_a_small_pressure_flag_is_warned_about_once_in_the_flags_unit(folder, capsys):
    # 0.5 kPa: one warning in kPa; the Pa-level check inside must not ask "did you mean 500 kPa?"
    code, out, err = run_cli(["muscle", "FAM1", "--pressures-kPa", "0.5"], folder, capsys)
    assert code == 0 and err.count("warning") == 1 and "below 1 kPa" in err and "did you mean" not in err


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["arm", "--pressures-kPa", "0.3", "0.3", "0.3"], "--pressures-kPa 0.3"),
        (["size", "--stroke", "0.5", "--force", "10", "--pressure", "0.3"], "--pressure 0.3"),
    ],
)
def test_other_commands_warn_of_a_small_pressure_once_in_the_flags_unit(folder, capsys, argv, flag):
    # before: two or three warnings in Pa naming internal functions (arm.settle, Muscle.free_length)
    _, _, err = run_cli(argv, folder, capsys)
    assert err.count("is below 1 kPa") == 1 and f"warning: {flag} is below 1 kPa" in err, err
    assert "Pa is below 1000 Pa" not in err and "did you mean" not in err, err


def test_demo_refuses_a_contractile_muscle_before_printing(folder, capsys):
    """Before: the table was printed, then the figure's stroke failed with the rig's internal
    words ('stroke_forces: lengths_m: 0.221 m is outside [-0.0104231, 0.209928] m')."""
    from importlib import resources

    doc = json.loads(resources.files("efam_mujoco.presets").joinpath("fam1.json").read_text())
    doc["constants"] = {"theta_rest_deg": 60.0}
    (folder / "mckibben.json").write_text(json.dumps(doc))
    run_bad(["demo", "--muscle", "mckibben.json", "--out", "d"], folder, capsys,
            r"mckibben\.json: the muscle is contractile \(braid angle 60 deg, above the neutral 35\.26 deg\)",
            r"`efam muscle` gives this one's table")  # fmt: skip
    assert "stroke_forces" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["size", "--stroke", "0.5", "--force", "10", "--pressure", "300", "--json", "data.csv"],
        ["arm", "--xml", "data.csv"],
        ["muscle", "FAM1", "--json", "data.csv"],
    ],
    ids=["size --json", "arm --xml", "muscle --json"],
)
def test_an_output_never_replaces_an_existing_recording(folder, capsys, argv):
    """Before: a CSV that is not the command's input (data.csv beside it, a slip of the tab key)
    was overwritten with JSON or MJCF without a word."""
    (folder / "data.csv").write_text("time_s,length_m,pressure_kPa,force_N\n0,0.17,0,0\n")
    run_bad(argv, folder, capsys, r"data\.csv: an existing \.csv file \(a recording\?\) would be replaced")


UNSTABLE_XML = (
    '<mujoco><option timestep="1"/><worldbody><body><joint name="j" type="slide" axis="1 0 0"/>'
    '<geom size="0.01" mass="1e-9"/></body></worldbody><actuator><motor joint="j" gear="1e12" '
    'ctrllimited="true" ctrlrange="0 1e12"/></actuator></mujoco>'
)


@pytest.mark.parametrize(
    "name, text",
    [
        ("keep.json", '{"name": "mine"}\n'),  # a muscle file: a warning appended made it invalid JSON
        ("notes", "<mujoco/>"),  # XML whatever its name
        ("rec.txt", "time_s,length_m,pressure_kPa,force_N\n0,0.1,0,0\n"),  # a recording saved as .txt
        ("fig.png", "not really a png"),
    ],
)
def test_mujoco_log_is_never_appended_to_a_data_file(tmp_path, capsys, name, text):
    (tmp_path / "unstable.xml").write_text(UNSTABLE_XML)
    (tmp_path / name).write_text(text)
    run_bad(["--mujoco-log", name, "view", "unstable.xml", "--check"], tmp_path, capsys,
            rf"--mujoco-log {re.escape(name)}: the file exists and holds data, not a log")  # fmt: skip
    assert (tmp_path / name).read_text() == text


def test_mujoco_log_appends_on_a_line_of_its_own(tmp_path, capsys):
    (tmp_path / "unstable.xml").write_text(UNSTABLE_XML)
    log = tmp_path / "run.log"
    log.write_text("my notes, no newline at the end")
    code, _, err = run_cli(["--mujoco-log", "run.log", "view", "unstable.xml", "--check"], tmp_path, capsys)
    assert code == 2 and "unstable" in err
    lines = log.read_text().splitlines()
    assert lines[0] == "my notes, no newline at the end"
    assert lines[1].startswith("Nan, Inf or huge value")


def test_a_figure_format_that_needs_tex_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """``.pgf`` is matplotlib's, but its backend measures text with TeX: without it the figure
    failed after the command had run and written its JSON. Refused up front, nothing written."""
    import shutil as sh

    monkeypatch.setattr(sh, "which", lambda name, *a, **k: None)
    run_bad(["size", "--stroke", "0.5", "--force", "20", "--pressure", "300", "--top", "1",
             "--figure", "f.pgf", "--json", "sz.json"], tmp_path, capsys,
            r"--figure f\.pgf: '\.pgf' is not a figure format")  # fmt: skip
    assert not (tmp_path / "sz.json").exists()


@pytest.mark.parametrize("argv", [["muscle", "FAM1", "--json", "FAM1"], ["demo", "--out", "fam2"],
                                  ["arm", "--xml", "sub/Fam1"]])  # fmt: skip
def test_an_output_is_never_named_like_a_preset(tmp_path, capsys, argv):
    """Written as ./FAM1, a file made every later '--muscle FAM1' in that folder ambiguous."""
    (tmp_path / "sub").mkdir()
    run_bad(argv, tmp_path, capsys, r"is the name of a preset muscle; give another name")


def test_a_report_folder_is_replaced_only_by_the_command_that_wrote_it(tmp_path, capsys):
    """`efam diagnose --report` over `efam demo`'s folder removed the demo's files without a word:
    the marker names the command, and another command's report is refused before any work."""
    code, _, err = run_cli(["demo", "--out", "shared"], tmp_path, capsys)
    assert code == 0, err
    before = sorted(p.name for p in (tmp_path / "shared").iterdir())
    assert "command: efam demo" in (tmp_path / "shared" / ".efam_report").read_text()
    (tmp_path / "rec.csv").write_text("time_s,length_m,pressure_kPa,force_N\n0,0.17,0,0\n1,0.17,0,0\n")
    run_bad(["diagnose", "--muscle", "FAM1", "--report", "shared", "rec.csv"], tmp_path, capsys,
            r"--report shared exists, is not empty and is not only this command's efam report: it is the "
            r"report of 'efam demo', not of 'efam diagnose'")  # fmt: skip
    assert sorted(p.name for p in (tmp_path / "shared").iterdir()) == before
    code, _, err = run_cli(["demo", "--out", "shared"], tmp_path, capsys)  # its own command replaces it
    assert code == 0, err


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_mujoco_log_takes_dev_null_but_not_a_pipe(tmp_path, capsys):
    """The log is appended to, never renamed over: /dev/null (to discard the warnings) was refused
    with a message about renaming; a pipe is refused (opening it would wait for a reader)."""
    code, out, err = run_cli(
        ["--mujoco-log", os.devnull, "muscle", "FAM1", "--pressures-kPa", "100"], tmp_path, capsys
    )
    assert code == 0, err
    os.mkfifo(tmp_path / "pipe")
    run_bad(["--mujoco-log", "pipe", "muscle", "FAM1"], tmp_path, capsys,
            r"--mujoco-log pipe is a pipe or a socket: opening it for the log would wait for a reader")  # fmt: skip


# ------------------------------------------------------------ second outside sweep (outputs)
def test_an_output_name_longer_than_the_file_system_takes_is_refused_before_the_work(tmp_path, capsys):
    """A 300-byte --json name failed after the work with 'cannot write ... (File name too long)';
    the message now names the flag and the limit, before anything runs."""
    name = "x" * 300 + ".json"
    run_bad(["muscle", "FAM1", "--json", name], tmp_path, capsys,
            r"--json x+\.json: the name 'x{40}\.\.\.' is 305 bytes long; the file system takes names of at "
            r"most \d+ bytes")  # fmt: skip
    # in a folder that does not exist yet too (judged by the nearest folder that does)
    run_bad(["muscle", "FAM1", "--json", f"new/{name}"], tmp_path, capsys, r"is 305 bytes long")
    assert not (tmp_path / "new").exists()


def test_an_output_name_near_the_file_systems_limit_is_written(tmp_path, capsys):
    """A 250-byte name is a good name, but its temporary '.NAME.XXXXXXXX.efam-tmp' was not one:
    the command did its work and then said 'File name too long'."""
    name = "y" * 245 + ".json"
    code, _, err = run_cli(["muscle", "FAM1", "--pressures-kPa", "100", "--json", name], tmp_path, capsys)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    assert strict_load(tmp_path / name)["name"] == "FAM1"


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="no /proc here")
def test_an_output_through_a_link_to_a_pipe_is_refused_before_the_work(tmp_path, capsys):
    """--json /dev/stdout on a pipe (/proc/self/fd/1 -> 'pipe:[123]', a name realpath cannot
    follow) was taken for a new file: the work was done, then 'cannot write
    /proc/123/fd/pipe:[456] (No such file or directory)'."""
    read_end, write_end = os.pipe()
    try:
        target = f"/proc/self/fd/{write_end}"
        run_bad(["muscle", "FAM1", "--json", target], tmp_path, capsys,
                rf"--json {re.escape(target)} is not a regular file \(a device, a pipe or a socket\)")  # fmt: skip
    finally:
        os.close(read_end)
        os.close(write_end)


def test_an_output_inside_an_existing_report_folder_is_refused(tmp_path, capsys):
    """`efam muscle --json rep/x.json` after `efam diagnose --report rep` wrote into the report: the
    next `diagnose --report rep` refused the folder as the user's ('x.json is not a file the report
    wrote'); over the report's own file it edited the report. The log and --models-dir too."""
    with replace_folder(tmp_path / "rep", command="diagnose") as staging:
        (staging / "report.txt").write_text("a report\n")
    said = r"is inside the efam report folder rep, which its command replaces as a whole"
    run_bad(["muscle", "FAM1", "--json", "rep/x.json"], tmp_path, capsys, r"--json rep/x\.json " + said)
    run_bad(["muscle", "FAM1", "--json", "rep/report.txt"], tmp_path, capsys, said)
    run_bad(
        ["--mujoco-log", "rep/log.txt", "muscle", "FAM1"],
        tmp_path,
        capsys,
        r"--mujoco-log rep/log\.txt " + said,
    )
    run_bad(["arm", "--write-models", "--models-dir", "rep"], tmp_path, capsys, r"--models-dir rep " + said)
    run_bad(["demo", "--out", "rep/inner"], tmp_path, capsys, r"--out rep/inner " + said)
    # the report folder itself is still replaced by its own command's output flag, and a file
    # beside it is written
    code, _, err = run_cli(
        ["muscle", "FAM1", "--pressures-kPa", "100", "--json", "beside.json"], tmp_path, capsys
    )
    assert code == 0, err


def test_install_plugin_never_installs_inside_the_package(tmp_path, capsys):
    """`efam install-plugin --dir efam_mujoco/presets` put the library among the presets (nothing is
    written inside the package folder); its own folder is still 'nothing to install there'."""
    import efam_mujoco

    package = Path(efam_mujoco.__file__).resolve().parent
    before = sorted(p.name for p in (package / "presets").iterdir())
    try:
        run_bad(["install-plugin", "--dir", package / "presets"], tmp_path, capsys,
                r"--dir .*presets: is inside the efam_mujoco package .*; give a folder outside it")  # fmt: skip
        assert sorted(p.name for p in (package / "presets").iterdir()) == before
    finally:  # a failing run must not leave a library among the presets
        for path in (package / "presets").iterdir():
            if path.name not in before:
                path.unlink()
    code, out, err = run_cli(["install-plugin", "--dir", package / "plugin"], tmp_path, capsys)
    assert code == 0 and "nothing to install there" in out, err


@pytest.mark.parametrize("command", ["arm", "suite"])
def test_a_commands_description_is_not_cut_mid_sentence(command):
    """`efam arm --help` ended its description '... under pressures and compare the' (the first
    line of the module's docstring); `efam suite --help` '... and the random baseline,'."""
    import argparse

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    description = sub.choices[command].description
    assert description.rstrip().endswith("."), description


# ------------------------------------------------- a third sweep: JSON named as data, log folders, -0
@pytest.mark.parametrize(
    "argv, flag",
    [
        (["muscle", "FAM1", "--json", "out.csv"], "--json out.csv"),
        (["muscle", "FAM1", "--json", "out.TSV"], "--json out.TSV"),
        (["calibrate", "rec.csv", "--muscle", "FAM1", "--out", "m.csv"], "--out m.csv"),
        (["calibrate", "rec.csv", "--muscle", "FAM1", "--out", "m.json", "--json", "c.tsv"], "--json c.tsv"),
        (["diagnose", "rec.csv", "--muscle", "FAM1", "--json", "d.csv"], "--json d.csv"),
        (["arm", "--pressures-kPa", "0", "0", "0", "--json", "a.csv"], "--json a.csv"),
        (["suite", "--json", "s.csv"], "--json s.csv"),
    ],
)
def test_a_json_output_named_like_a_recording_is_refused(folder, capsys, argv, flag):
    """`efam muscle FAM1 --json out.csv` (a new file) wrote JSON under a recording's name, which a
    later command read as a recording; calibrate's --out muscle file likewise."""
    stem = flag.split()[1].rsplit(".", 1)[0]
    run_bad(argv, folder, capsys, rf"{re.escape(flag)}: writes JSON, but '\.\w+' is a recording's suffix",
            rf"give it a \.json name \(e\.g\. {stem}\.json\)")  # fmt: skip


def test_an_xml_output_named_like_a_recording_is_refused(folder, capsys):
    """`efam arm --xml a.csv` wrote the MJCF under a recording's name."""
    run_bad(["arm", "--pressures-kPa", "0", "0", "0", "--xml", "a.csv"], folder, capsys,
            r"--xml a\.csv: writes XML, but '\.csv' is a recording's suffix", r"give it a \.xml name")  # fmt: skip


@pytest.mark.parametrize("name", ["table", "table.txt", "table.JSON", "table.csv.json"])
def test_a_json_output_of_any_other_name_is_still_written(folder, capsys, name):
    code, _, err = run_cli(["muscle", "FAM1", "--pressures-kPa", "100", "--json", name], folder, capsys)
    assert code == 0, err
    assert strict_load(folder / name)["rows"][0]["pressure_kPa"] == 100.0


def test_the_python_api_refuses_a_muscle_or_arm_json_named_like_a_recording(tmp_path):
    from efam_mujoco import arm
    from efam_mujoco.armdiag import save_spec
    from efam_mujoco.musclefile import save_muscle

    with pytest.raises(OutputError, match=r"save_muscle .*m\.csv: writes JSON.*e\.g\. .*m\.json"):
        save_muscle(tmp_path / "m.csv", load_muscle("FAM1"))
    with pytest.raises(OutputError, match=r"save_spec .*a\.tsv: writes JSON"):
        save_spec(tmp_path / "a.tsv", arm.ArmSpec(sections=(arm.paper_section(disks=2),)))
    assert not list(tmp_path.iterdir())


def test_the_mujoco_log_gets_its_missing_folder_like_every_other_output(tmp_path, capsys):
    """`--mujoco-log newdir/log.txt` was refused ('cannot append to it') while `--json
    nodir/x.json` made its folder."""
    code, _, err = run_cli(
        ["--mujoco-log", "newdir/sub/log.txt", "muscle", "FAM1", "--pressures-kPa", "100",
         "--json", "nodir/x.json"], tmp_path, capsys,
    )  # fmt: skip
    assert code == 0, err
    assert (tmp_path / "newdir" / "sub" / "log.txt").is_file() and (tmp_path / "nodir" / "x.json").is_file()


def test_number_flags_read_a_negative_zero_as_zero(tmp_path, capsys):
    """`--pressures-kPa -0` was printed as '-0.0' in the table and the JSON."""
    from efam_mujoco.cli import plain_float

    for text in ("-0", "-0.0", "-0e5", "-.0"):
        value = plain_float(text)
        assert value == 0.0 and math.copysign(1.0, value) == 1.0, text
    code, out, err = run_cli(
        ["muscle", "FAM1", "--pressures-kPa", "-0", "--json", "t.json"], tmp_path, capsys
    )
    assert code == 0, err
    assert "-0.0" not in out and re.search(r"^\s+0\.0\s", out, re.MULTILINE), out
    assert "-0.0" not in (tmp_path / "t.json").read_text()
    code, out, err = run_cli(["arm", "--disks", "2", "--pressures-kPa", "-0", "0", "-0.0"], tmp_path, capsys)
    assert code == 0 and "-0" not in out, err


@pytest.mark.parametrize(
    "argv",
    [
        ["muscle", "FAM1", "--json", "m.json/"],
        ["arm", "--pressures-kPa", "100", "--json", "a.json/"],
        ["arm", "--xml", "arm.xml/"],
        ["suite", "--episodes", "1", "--json", "s.json/"],
        ["suite", "--episodes", "1", "--strip", "strip.png/"],
    ],
)
def test_a_file_output_ending_in_a_separator_is_refused(tmp_path, capsys, argv):
    """Before: '--json m.json/' (a folder meant) wrote the file m.json; the flags read as paths
    (arm, suite) lost the separator before any check could see it."""
    name = argv[-1].rstrip("/")
    run_bad(argv, tmp_path, capsys, rf"{argv[-2]} {re.escape(argv[-1])}: ends in '/', which names a folder",
            rf"e\.g\. {re.escape(name)}\)")  # fmt: skip


def _read_only(monkeypatch, ro: Path) -> None:
    """Writes into ``ro`` fail as in a read-only folder (faked: the sandbox runs as root, where a
    chmod stops nothing): creating a file there raises EACCES, as the kernel would."""
    import errno
    import tempfile

    real_mkstemp, real_mkdtemp = tempfile.mkstemp, tempfile.mkdtemp

    def refused(dir=None):
        return dir is not None and Path(dir).resolve() == ro.resolve()

    def mkstemp(*args, dir=None, **kwargs):
        if refused(dir):
            raise PermissionError(errno.EACCES, "Permission denied", str(ro))
        return real_mkstemp(*args, dir=dir, **kwargs)

    def mkdtemp(*args, dir=None, **kwargs):
        if refused(dir):
            raise PermissionError(errno.EACCES, "Permission denied", str(ro))
        return real_mkdtemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    monkeypatch.setattr(tempfile, "mkdtemp", mkdtemp)


@pytest.mark.parametrize(
    "argv",
    [["muscle", "FAM1", "--json", "ro/out.json"], ["demo", "--out", "ro/demo"]],
    ids=["json-file", "report-folder"],
)
def test_an_output_folder_that_refuses_writes_is_named_and_left_as_it_was(folder, capsys, monkeypatch, argv):
    """A read-only output folder: one line naming the output and the system's reason, no
    traceback, and the folder (an earlier output in it) left as it was."""
    ro = folder / "ro"
    ro.mkdir()
    (ro / "out.json").write_text('{"an": "earlier output"}\n')
    _read_only(monkeypatch, ro)
    run_bad(argv, folder, capsys, r"ro", r"permission denied")
