"""Recording CSV I/O: units, signs, and a clear message for every kind of bad input."""

from __future__ import annotations

import numpy as np
import pytest

from efam_mujoco.recordings import Recording, RecordingError, drop_report, read_csv, write_csv

PSI = 6894.757293168361


def write(tmp_path, text, name="rec.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = "time_s,length_m,pressure_kPa,force_N\n0,0.17,100,40\n0.1,0.18,100,30\n0.2,0.19,100,20\n"


def test_quantity_names_are_read_in_any_case_units_as_written(tmp_path):
    # 'Time_s, Length_mm, Pressure_kPa, Tension_N' as a logger writes it: the quantities are
    # case-free, the units are not (mN is not MN)
    text = "Time_s, Length_mm, Pressure_kPa, TENSION_N\n0,170,100,-40\n0.1,180,100,-30\n0.2,190,100,-20\n"
    rec = read_csv(write(tmp_path, text))
    assert np.allclose(rec.length_m, [0.17, 0.18, 0.19]) and np.allclose(rec.force_N, [40, 30, 20])
    assert np.allclose(rec.pressure_Pa, 1e5)
    with pytest.raises(RecordingError, match=r"unknown time unit 'S'.*case-sensitive: did you mean 's'\?"):
        read_csv(write(tmp_path, text.replace("Time_s", "TIME_S"), "upper.csv"))
    with pytest.raises(RecordingError, match=r"column 'Pressure' has no unit; write e\.g\. 'pressure_kPa'"):
        read_csv(write(tmp_path, text.replace("Pressure_kPa", "Pressure"), "nounit.csv"))


def test_reads_si_and_push_sign(tmp_path):
    rec = read_csv(write(tmp_path, GOOD))
    assert np.allclose(rec.time_s, [0, 0.1, 0.2])
    assert np.allclose(rec.length_m, [0.17, 0.18, 0.19])
    assert np.allclose(rec.pressure_Pa, 100e3)
    assert np.allclose(rec.force_N, [40, 30, 20])
    assert np.allclose(rec.tension_N, [-40, -30, -20])
    assert rec.meta["source"].endswith("rec.csv")
    assert rec.meta["dropped_rows"] == []


def test_other_units_tension_and_displacement(tmp_path):
    text = "# a comment line\ntime_ms,displacement_mm,pressure_psi,tension_N\n0,0,15,-40\n100,10,15,-30\n200,20,15,-20\n"
    rec = read_csv(write(tmp_path, text), rest_length_m=0.17)
    assert np.allclose(rec.time_s, [0, 0.1, 0.2])
    assert np.allclose(rec.length_m, [0.17, 0.18, 0.19])  # rest length + displacement
    assert np.allclose(rec.pressure_Pa, 15 * PSI)
    assert np.allclose(rec.force_N, [40, 30, 20])  # tension (pull) negated into push
    assert rec.meta["rest_length_m"] == 0.17
    rec = read_csv(write(tmp_path, "time_s,length_cm,pressure_Pa,force_N\n0,17,5,1\n1,18,5,2\n"))
    assert np.allclose(rec.length_m, [0.17, 0.18]) and np.allclose(rec.pressure_Pa, 5)


def test_displacement_needs_the_rest_length(tmp_path):
    path = write(tmp_path, "time_s,displacement_mm,pressure_kPa,force_N\n0,0,100,1\n1,1,100,2\n")
    with pytest.raises(RecordingError, match=r"rec\.csv.*'displacement_mm'.*resting length"):
        read_csv(path)


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        (GOOD.replace("0.1,0.18,100,30", "0.1,nan,100,30"), r"line 3, column 'length_m': not a finite number"),
        (GOOD.replace("0.1,0.18,100,30", "0.1,0.18,,30"), r"line 3, column 'pressure_kPa': empty value"),
        (GOOD.replace("0.1,0.18,100,30", "0.1,0.18,100,abc"), r"line 3, column 'force_N': not a number"),
        (GOOD.replace("0.1,0.18,100,30", "0.1,0.18,100"), r"line 3: 3 fields, the header has 4"),
        (GOOD.replace("0.2,0.19", "0.05,0.19"), r"line 4, column 'time_s': time goes backwards"),
        (GOOD.replace("0.2,0.19", "0.1,0.19"), r"line 4, column 'time_s': duplicate time"),
        (GOOD.replace("force_N", "force_N,temperature_C").replace("\n0", ",1\n0"), r"unknown column 'temperature_C'"),
        (GOOD.replace("pressure_kPa", "pressure"), r"column 'pressure' has no unit; write e.g. 'pressure_kPa'"),
        (GOOD.replace("pressure_kPa", "pressure_atm"), r"column 'pressure_atm'.*unknown pressure unit 'atm'"),
        (GOOD.replace("force_N", "tension_N"), None),  # fine: tension instead of force
        (GOOD.replace(",force_N", "").replace(",40\n", "\n").replace(",30\n", "\n").replace(",20\n", "\n"),
         r"missing a force column"),
        ("time_s,length_m,pressure_kPa,force_N,tension_N\n0,1,1,1,1\n1,1,1,1,1\n",
         r"columns 'force_N' and 'tension_N' both give the force"),
        ("", r"no header line"),
        ("time_s,length_m,pressure_kPa,force_N\n0,0.17,100,40\n", r"fewer than 2 usable data rows"),
        (GOOD.replace("0.1,0.18", "0.1,-0.18"), r"'length_m': a length <= 0 m"),
    ],
)  # fmt: skip
def test_bad_input_is_a_clear_error_naming_file_line_and_column(tmp_path, text, pattern):
    path = write(tmp_path, text)
    if pattern is None:
        read_csv(path)
        return
    with pytest.raises(RecordingError, match=pattern) as err:
        read_csv(path)
    assert str(path) in str(err.value)


def test_drop_policy_reports_what_it_dropped(tmp_path):
    text = (
        "time_s,length_m,pressure_kPa,force_N\n0,0.17,100,40\n0.1,0.18,100,nan\n0.2,0.19,100,20\n"
        "0.2,0.19,100,21\n0.15,0.2,100,19\n0.3,0.2,100,\n0.4,0.21,100,10\n"
    )
    path = write(tmp_path, text)
    before = path.read_bytes()
    with pytest.raises(RecordingError, match="on_bad_rows='drop'"):
        read_csv(path)
    rec = read_csv(path, on_bad_rows="drop")
    assert np.allclose(rec.time_s, [0, 0.2, 0.4])
    assert [d["line"] for d in rec.meta["dropped_rows"]] == [3, 5, 6, 7]
    reasons = " ".join(d["reason"] for d in rec.meta["dropped_rows"])
    assert (
        "not a finite" in reasons and "duplicate" in reasons and "backwards" in reasons and "empty" in reasons
    )
    report = drop_report(rec)
    assert "dropped 4 bad row(s)" in report and "line 3" in report and str(path) in report
    assert path.read_bytes() == before  # the input file is never modified
    with pytest.raises(ValueError, match="on_bad_rows"):
        read_csv(path, on_bad_rows="ignore")


def test_write_read_round_trip_and_input_protection(tmp_path):
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.01, 0.1, 50))
    rec = Recording(t, rng.uniform(0.1, 0.3, 50), rng.uniform(0, 6e5, 50), rng.normal(0, 100, 50))
    path = write_csv(tmp_path / "out.csv", rec)
    back = read_csv(path)
    for name in ("time_s", "length_m", "pressure_Pa", "force_N"):
        assert np.allclose(getattr(back, name), getattr(rec, name), rtol=1e-8, atol=1e-9)
    assert not (tmp_path / "out.csv.tmp").exists()
    with pytest.raises(RecordingError, match="refusing to overwrite"):
        write_csv(path, back)
    write_csv(tmp_path / "psi.csv", rec, pressure_unit="psi")
    assert (tmp_path / "psi.csv").read_text().startswith("time_s,length_m,pressure_psi,force_N")
    assert np.allclose(read_csv(tmp_path / "psi.csv").pressure_Pa, rec.pressure_Pa, rtol=1e-8)


def test_missing_file_names_it(tmp_path):
    with pytest.raises(RecordingError, match="nope.csv: cannot open"):
        read_csv(tmp_path / "nope.csv")


def test_a_file_name_with_control_characters_is_shown_escaped(tmp_path):
    """A name holding a terminal escape sequence and a newline is named escaped, never raw; the
    recording still keeps the real name (write_csv's input protection compares it)."""
    name = "run\x1b[31m\n.csv"
    with pytest.raises(RecordingError, match=r"run\\x1b\[31m\\n\.csv: fewer than 2") as err:
        read_csv(write(tmp_path, GOOD.split("0.1,")[0], name))
    assert "\x1b" not in str(err.value) and "\n" not in str(err.value)
    rec = read_csv(write(tmp_path, GOOD, name))
    assert rec.meta["source"] == str(tmp_path / name)
    with pytest.raises(RecordingError, match="refusing to overwrite"):
        write_csv(tmp_path / name, rec)


@pytest.mark.parametrize(
    "change, words",
    [
        ({"force_N": [0.0, float("nan"), 1.0]}, r"force_N\[1\] = nan is not a finite number"),
        ({"length_m": [[0.17, 0.17, 0.17]]}, "length_m must be one-dimensional"),
        ({"time_s": [0.0, 0.2, 0.1]}, "time_s must increase"),
        ({"pressure_Pa": ["a", "b", "c"]}, "pressure_Pa must be an array of numbers"),
    ],
)
def test_a_recording_built_in_python_is_checked_as_the_reader_checks_a_file(change, words):
    """Built in Python, a NaN or unsorted time reached calibrate() and diagnose() and ended in
    'SVD did not converge' or an IndexError deep inside a fit."""
    from efam_mujoco.recordings import Recording

    arrays = dict(time_s=[0.0, 0.1, 0.2], length_m=[0.17] * 3, pressure_Pa=[1e5] * 3, force_N=[0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match=words):
        Recording(**{**arrays, **change})


def test_calibrate_and_diagnose_refuse_what_is_not_a_recording():
    from efam_mujoco import load_muscle
    from efam_mujoco.calibrate import calibrate
    from efam_mujoco.diagnose import diagnose

    for run in (calibrate, diagnose):
        with pytest.raises(TypeError, match="must be Recording objects"):
            run(["a.csv"], load_muscle("FAM1"))  # a file name's 5 characters were counted as samples
