"""Property-based bad inputs (hypothesis): random mutations of a good recording CSV, of a good
muscle file, and random command lines. Whatever the mutation, the program either succeeds or
ends with one clear error line; never a traceback, never a changed input, never a stray file,
never non-standard JSON."""

from __future__ import annotations

import json
import re
import tempfile
from importlib import resources
from pathlib import Path

from _robust import run_cli, snapshot, strict_load
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from efam_mujoco.musclefile import MuscleFileError, load_muscle
from efam_mujoco.recordings import RecordingError, read_csv

SETTINGS = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
GOOD_CSV = "time_s,length_m,pressure_kPa,force_N\n" + "".join(
    f"{0.1 * i:.3f},{0.17018 + 0.0004 * i:.6f},{200 + i:.1f},{100 + 0.5 * i:.2f}\n" for i in range(40)
)
FAM1 = json.loads(resources.files("efam_mujoco.presets").joinpath("fam1.json").read_text())
NASTY = ["", "nan", "inf", "-1", "0", "1e300", "-1e300", "abc", "\x00", '"', ",", "\ufeff", "1,2", "\r", "\n",
         "é", "\xff", "1e-320", "--", "true", "null", "9" * 400]  # fmt: skip


def _mutate_text(data, text: str) -> bytes:
    """Insert, delete or replace a random span of ``text`` with a nasty or random piece."""
    raw = text.encode()
    ops = data.draw(st.integers(min_value=1, max_value=4))
    for _ in range(ops):
        at = data.draw(st.integers(min_value=0, max_value=len(raw)))
        length = data.draw(st.integers(min_value=0, max_value=12))
        piece = data.draw(
            st.one_of(
                st.sampled_from(NASTY).map(lambda s: s.encode("utf-8", "surrogatepass")),
                st.binary(max_size=8),
                st.text(max_size=8).map(lambda s: s.encode("utf-8", "surrogatepass")),
            )
        )
        raw = raw[:at] + piece + raw[at + length :]
    return raw


def _assert_clean_failure(err: str, names) -> None:
    assert "Traceback" not in err and "internal error" not in err, err
    line = err.strip().splitlines()[-1] if err.strip() else ""
    assert re.search(r"error: ", line), err
    assert any(name in err for name in names), err


@SETTINGS
@given(data=st.data())
def test_mutated_csv_is_read_or_refused_with_its_line(data):
    raw = _mutate_text(data, GOOD_CSV)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rec.csv"
        path.write_bytes(raw)
        try:
            recording = read_csv(path, rest_length_m=0.17)
        except RecordingError as err:
            message = str(err)
            assert message.startswith(str(path)), message
            assert re.search(r"line \d+|no header|fewer than 2", message), message
        else:
            for array in (recording.time_s, recording.length_m, recording.pressure_Pa, recording.force_N):
                assert all(abs(v) <= 1e9 for v in array)
        assert path.read_bytes() == raw


@SETTINGS
@given(data=st.data())
def test_mutated_csv_through_diagnose(data, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp("fuzz")
    raw = _mutate_text(data, GOOD_CSV)
    (folder / "rec.csv").write_bytes(raw)
    before = snapshot(folder)
    code, out, err = run_cli(
        ["diagnose", "rec.csv", "--muscle", "FAM1", "--json", "out.json"], folder, capsys
    )
    # 40 rows of a made-up muscle never pass the plausibility checks: always a clean refusal
    assert code == 2
    _assert_clean_failure(err, ["rec.csv"])
    assert snapshot(folder) == before


def _json_mutation(data, doc):
    """Replace one randomly chosen value (at any depth) with a random JSON value, or delete or
    rename a key."""
    doc = json.loads(json.dumps(doc))
    paths = []

    def walk(node, path):
        if isinstance(node, dict):
            for k, v in node.items():
                paths.append((*path, k))
                walk(v, (*path, k))

    walk(doc, ())
    path = data.draw(st.sampled_from(paths))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    action = data.draw(st.sampled_from(["value", "delete", "rename"]))
    if action == "delete":
        del parent[path[-1]]
    elif action == "rename":
        parent[data.draw(st.text(min_size=1, max_size=12))] = parent.pop(path[-1])
    else:
        parent[path[-1]] = data.draw(
            st.one_of(
                st.none(), st.booleans(), st.text(max_size=6),
                st.floats(allow_nan=False, allow_infinity=False), st.integers(-10**30, 10**30),
                st.lists(st.integers(), max_size=3), st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
            )
        )  # fmt: skip
    return doc


@SETTINGS
@given(data=st.data())
def test_mutated_muscle_file_is_read_or_refused_naming_it(data):
    doc = _json_mutation(data, FAM1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "muscle.json"
        text = json.dumps(doc)
        path.write_text(text)
        try:
            muscle = load_muscle(path)
        except MuscleFileError as err:
            assert str(err).startswith(str(path)), str(err)
        else:  # accepted: then it is a physical muscle whose force is finite everywhere
            import numpy as np

            lengths = np.linspace(muscle.min_length_m, muscle.max_length_m, 50)
            assert np.isfinite(muscle.push(300e3, lengths)).all()
            assert isinstance(muscle.tension_only, bool)
        assert path.read_text() == text


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_mutated_muscle_file_through_efam_muscle(data, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp("fuzz")
    doc = _json_mutation(data, FAM1)
    (folder / "m.json").write_text(json.dumps(doc))
    before = snapshot(folder)
    code, out, err = run_cli(
        ["muscle", "m.json", "--pressures-kPa", "300", "--json", "out.json"], folder, capsys
    )
    if code:
        _assert_clean_failure(err, ["m.json", "--pressures-kPa"])
        assert snapshot(folder) == before
    else:
        strict_load(folder / "out.json")
        after = snapshot(folder)
        assert set(after) - set(before) == {"out.json"}


FLAGS = ["--json", "--pressures-kPa", "--stress", "--out", "--muscle", "--figures", "--report", "--check",
         "--allow", "--max-samples", "--rated-pressure-kPa", "--on-bad-rows", "--tension-only", "--help",
         "--pressures", "--js", "--mujoco-log", "-", "--"]  # fmt: skip
VALUES = ["FAM1", "FAM2", "rec.csv", "m.json", "out.json", "x", "-1", "0", "1e300", "nan", "2000", "300",
          "linear", "ogden", "drop", ".", "..", "/", "force-dead", "10"]  # fmt: skip


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    command=st.sampled_from(["muscle", "demo", "view", "calibrate", "diagnose", "arm"]),
    tokens=st.lists(st.one_of(st.sampled_from(FLAGS), st.sampled_from(VALUES)), max_size=6),
)
def test_random_command_lines_never_traceback(command, tokens, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp("argv")
    (folder / "rec.csv").write_text(GOOD_CSV)
    (folder / "m.json").write_text(json.dumps(FAM1))
    if command in ("demo", "arm") or "--help" in tokens:
        tokens = [t for t in tokens if t not in ("--pressures-kPa", "--out", "--help")]
    if command == "arm":  # keep arm to what it can do quickly: write or refuse an MJCF
        tokens = [t for t in tokens if t not in ("--pressures-kPa",)] + ["--disks", "2"]
    before = snapshot(folder)
    code, out, err = run_cli([command, *tokens], folder, capsys)
    assert "Traceback" not in err and "internal error" not in err, err
    if code:
        assert err.strip(), "a failure must say why"
        assert snapshot(folder) == before
    for path in folder.rglob("*.json"):
        strict_load(path)
