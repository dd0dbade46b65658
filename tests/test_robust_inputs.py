"""Inputs that read as valid but cannot be built or recorded, found by an adversarial review:
a muscle longer than its sleeve's threads or its bladder, clamps longer than the bladder, a dead
band above the rated pressure, a stress law other than the default that overflows, a catalogue
with a fibre fraction of 5 or in another encoding, a figure in a format no backend writes, a
negative seed, and a time column in ms headed ``time_s``. Each is refused through the command
line, naming the file, key, unit or flag, before any work and with no file written."""

from __future__ import annotations

import contextlib
import json
import re
import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from _robust import run_bad, run_cli

from efam_mujoco import musclefile, rig
from efam_mujoco.calibrate.synth import synthesize
from efam_mujoco.files import FIGURE_OUTPUTS, OutputError, check_figure_path
from efam_mujoco.musclefile import load_muscle
from efam_mujoco.recordings import DEFAULT_RATED_PRESSURE_PA, Recording, check_plausibility, write_csv
from efam_mujoco.size import CatalogueError, load_catalogue

CATALOGUE = resources.files("efam_mujoco.size").joinpath("catalogue.json")


def _fam1() -> dict:
    return json.loads(resources.files("efam_mujoco.presets").joinpath("fam1.json").read_text())


def _muscle_file(folder: Path, edit) -> Path:
    doc = _fam1()
    edit(doc)
    path = folder / "muscle.json"
    path.write_text(json.dumps(doc))
    return path


# ------------------------------------------------------------- 1. geometry that cannot be built
@pytest.mark.parametrize(
    "edit, expect",
    [
        # 100 cm of muscle from a sleeve whose threads are 50.8 / sin 45 = 71.8 cm long
        (lambda d: d["geometry"].update(rest_length_m=1.0), [r"'rest_length_m' = 1\.0", r"braid threads", r"71\.84 cm"]),
        # 60 cm: shorter than the threads, but 3.7 x the 16.4 cm working bladder (it turned contractile)
        (lambda d: d["geometry"].update(rest_length_m=0.6), [r"'rest_length_m' = 0\.6", r"3\.66 x the working bladder"]),
        (lambda d: d["geometry"].update(rest_length_cm=60.0) or d["geometry"].pop("rest_length_m"),
         [r"'rest_length_cm' = 60\.0", r"working bladder length 16\.41 cm"]),
        # two 10 cm clamping channels on a 17.8 cm bladder (Eq. 7 alone let it through)
        (lambda d: d["geometry"].update(clamp_length_m=0.1), [r"'clamp_length_m' = 0\.1", r"17\.78 cm", r"swaging"]),
    ],
    ids=["rest-longer-than-threads", "rest-far-from-bladder", "rest-in-cm", "clamps-longer-than-bladder"],
)  # fmt: skip
def test_muscle_geometry_that_cannot_be_built_is_refused(tmp_path, capsys, edit, expect):
    path = _muscle_file(tmp_path, edit)
    run_bad(["muscle", path.name], tmp_path, capsys, r"muscle\.json: geometry", *expect)


def test_muscle_deadband_at_or_above_the_rated_pressure_is_refused(tmp_path, capsys):
    path = _muscle_file(tmp_path, lambda d: d.update(deadband_kPa=9999))
    run_bad(["muscle", path.name], tmp_path, capsys, r"'deadband_kPa' = 9999", r"1000 kPa", r"deadband_Pa")
    path = _muscle_file(
        tmp_path, lambda d: d.update(deadband_MPa=1.0, deadband_kPa=None) or d.pop("deadband_kPa")
    )
    run_bad(["muscle", path.name], tmp_path, capsys, r"'deadband_MPa' = 1\.0", r"never inflate")


def test_the_deadband_bound_is_the_rigs_and_the_rated_pressure():
    assert musclefile.MAX_DEADBAND_PA == rig.RigOptions().max_pressure_Pa == DEFAULT_RATED_PRESSURE_PA


def test_presets_and_a_high_but_possible_deadband_still_load(tmp_path, capsys):
    for name in ("FAM1", "FAM2"):
        for law in musclefile.available_laws(name):
            load_muscle(name, law)
    path = _muscle_file(tmp_path, lambda d: d.update(deadband_kPa=500.0))
    assert load_muscle(path).deadband_Pa == 500e3


# ------------------------------------------------------------- 2. every law, not only the default
def test_a_non_default_law_that_overflows_is_refused_naming_it(tmp_path, capsys):
    def edit(doc):
        doc["stress"]["default"] = "linear"
        doc["stress"]["laws"]["exponential_decay"]["E4"] = 5000.0  # exp overflows in compression

    path = _muscle_file(tmp_path, edit)
    run_bad(
        ["muscle", path.name],
        tmp_path,
        capsys,
        r"stress law 'exponential_decay'",
        r"not finite",
        r"'E4': 5000",
    )
    with pytest.raises(musclefile.MuscleFileError, match="stress law 'exponential_decay'"):
        load_muscle(path, "linear")


# ------------------------------------------------------------- 3-4. the size catalogue
SIZE = ["size", "--stroke", "0.5", "--force", "10", "--pressure", "500", "--top", "1"]


def _catalogue(folder: Path, edit) -> Path:
    doc = json.loads(CATALOGUE.read_text())
    edit(doc)
    path = folder / "catalogue.json"
    path.write_text(json.dumps(doc))
    return path


def test_catalogue_fibre_fraction_above_one_is_refused_through_the_cli(tmp_path, capsys):
    path = _catalogue(tmp_path, lambda d: d["sleeves"][1].update(fibre_fraction=5))
    run_bad([*SIZE, "--catalogue", path.name], tmp_path, capsys,
            r"catalogue\.json: sleeves\[1\] \('PET expandable 1/4 in'\)", r"'fibre_fraction' = 5", r"\(0, 1\]",
            r"not a percentage")  # fmt: skip


@pytest.mark.parametrize(
    "edit, expect",
    [
        (lambda d: d["tubings"][0].update(wall_in=3.0), r"tubings\[0\].*'wall_in' = 3\.0 \(76\.2 mm\).*50\] mm"),
        (lambda d: d["sleeves"][0].update(thickness_mm=51), r"sleeves\[0\].*'thickness_mm' = 51 \(51 mm\)"),
        (lambda d: d["sleeves"][0].update(max_diameter_in=300), r"'max_diameter_in' = 300 \(7620 mm\)"),
        (lambda d: d["sleeves"][0].update(density_kg_per_m3=1.38), r"'density_kg_per_m3' = 1\.38.*kg/m\^3"),
        (lambda d: d["sleeves"][-1].update(pressure_rating_kPa=690e6), r"'pressure_rating_kPa'.*kPa"),
        (lambda d: d["latex"].update(elongation_at_break=750), r"latex: key 'elongation_at_break' = 750"),
        (lambda d: d["latex"].update(strain_safety_factor=0.5), r"'strain_safety_factor' = 0\.5"),
        (lambda d: d["rules"].update(euler_length_factor=7), r"rules: key 'euler_length_factor' = 7.*\[0\.5, 2\]"),
        (lambda d: d["rules"].update(clamp_gap_per_wall=3), r"'clamp_gap_per_wall' = 3"),
        (lambda d: d["rules"].update(diameter_growth=-0.5), r"'diameter_growth' = -0\.5"),
        (lambda d: d["rules"].update(length_growth=4.0), r"'length_growth' = 4\.0"),
        (lambda d: d["rules"].update(max_gather_ratio=0.5), r"'max_gather_ratio' = 0\.5"),
        (lambda d: d["rules"].update(max_pressure_kPa=1e6), r"'max_pressure_kPa' = 1000000\.0 \(1e\+06 kPa\)"),
        (lambda d: d["rules"].update(thread_thickness_mm=15), r"'thread_thickness_mm' = 15 \(15 mm\)"),
        # 12.7 mm written as inches: a 32 cm latex tube passed the old half-metre bound
        (lambda d: d["tubings"][0].update(inner_diameter_in=12.7),
         r"tubings\[0\].*'inner_diameter_in' = 12\.7 \(322\.58 mm\).*\[0\.1, 200\] mm; was it in mm \(write 'inner_diameter_mm'\)"),
    ],
    ids=["wall", "thickness", "diameter", "density", "rating", "elongation", "safety", "euler", "clamp-gap",
         "diameter-growth", "length-growth", "gather", "max-pressure", "thread", "tube-bore-in-inches"],
)  # fmt: skip
def test_every_catalogue_quantity_has_a_physical_range(tmp_path, edit, expect):
    with pytest.raises(CatalogueError, match=expect):
        load_catalogue(_catalogue(tmp_path, edit))


def test_the_built_in_catalogue_is_inside_every_range():
    catalogue = load_catalogue()
    assert len(catalogue.sleeves) > 5 and len(catalogue.tubings) > 5


def test_a_binary_catalogue_names_line_and_column_not_the_codec(tmp_path, capsys):
    data = CATALOGUE.read_bytes()
    i = data.index(b"PET monofilament")
    (tmp_path / "catalogue.json").write_bytes(data[:i] + b"\xff\xfe" + data[i:])
    err = run_bad([*SIZE, "--catalogue", "catalogue.json"], tmp_path, capsys,
                  r"catalogue\.json: line \d+, column \d+: byte 0xff is not UTF-8")  # fmt: skip
    assert "codec" not in err


# ------------------------------------------------------------- 5. figure formats, up front
@pytest.mark.parametrize(
    "argv, flag",
    [
        ([*SIZE, "--figure", "x.txt"], "--figure"),
        (["suite", "--episodes", "1", "--strip", "x.json"], "--strip"),
    ],
)
def test_a_figure_format_no_backend_writes_is_refused_before_the_work(tmp_path, capsys, argv, flag):
    err = run_bad(
        argv, tmp_path, capsys, rf"{flag} x\.\w+: '\.\w+' is not a figure format", r"\.png", r"\.pdf"
    )
    assert "designs checked" not in err and "success" not in err
    code, out, _ = run_cli(argv, tmp_path, capsys)
    assert out == ""  # nothing ran: no sizing summary, no episode scores


def test_figure_paths_are_checked_by_the_shared_rule():
    assert set(FIGURE_OUTPUTS) >= {"--figure", "--strip"}
    with pytest.raises(OutputError, match=r"--figure a\.docx: '\.docx' is not a figure format"):
        check_figure_path("--figure", "a.docx")
    for good in ("a.png", "a.PDF", "a.svg"):
        try:
            check_figure_path("--figure", good)
        except OutputError as err:  # only when matplotlib is missing, and then it says so
            assert "needs matplotlib" in str(err)


# ------------------------------------------------------------- 6. integer flags
@pytest.mark.parametrize(
    "argv, expect",
    [
        (["--seed", "-1"], r"argument --seed: must be a whole number in 0 \.\. 4294967295"),
        (["--seed", str(2**32)], r"argument --seed: .*got 4294967296"),
        (["--seed", "1e3"], r"argument --seed: takes a whole number in plain digits, got '1e3'"),
        (["--episodes", "0"], r"argument --episodes: must be a whole number in 1 \.\. 10000"),
        (["--episodes", "-3"], r"argument --episodes: .*got -3"),
        (["--episodes", "1000000000"], r"argument --episodes: .*got 1000000000"),
        (["--seed", str(2**32 - 1), "--episodes", "2"], r"--seed 4294967295 with --episodes 2: the last episode's seed"),
    ],
)  # fmt: skip
def test_suite_seed_and_episodes_are_bounded_naming_the_flag(tmp_path, capsys, argv, expect):
    err = run_bad(["suite", *argv], tmp_path, capsys, expect)
    assert "Seed must be between" not in err  # numpy's own message


# ------------------------------------------------------------- 7. a time column in ms headed time_s
def test_ms_written_as_time_s_is_refused_by_the_stroke_speed(tmp_path, capsys):
    muscle = load_muscle("FAM1")
    recs = synthesize(muscle, pressures_Pa=(206.8e3, 413.7e3), rate_Hz=20.0)
    assert not check_plausibility(recs, muscle)  # the paper's 5.1 mm/s strokes every 50 ms
    for i, r in enumerate(recs):  # the same numbers, read as seconds: 50 s steps, 5.1 um/s
        slow = Recording(r.time_s * 1e3, r.length_m, r.pressure_Pa, r.force_N, dict(r.meta))
        assert 1.0 <= float(np.median(np.diff(slow.time_s))) <= 60.0  # the interval check passes
        write_csv(tmp_path / f"ms{i}.csv", slow)
    err = run_bad(["calibrate", "--muscle", "FAM1", "--stress", "linear", "ms0.csv", "ms1.csv"], tmp_path, capsys,
                  r"\[time-unit\] ms0\.csv: column 'time_s'", r"never faster than 5\.1 um/s", r"'time_ms'")  # fmt: skip
    assert len(re.findall(r"\[time-unit\]", err)) == 2


def _write_columns(path: Path, header: str, *columns) -> None:
    """A CSV of ``columns`` under ``header`` as written (no unit conversion)."""
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=header, comments="", fmt="%.9g")


def test_seconds_written_as_time_ms_are_refused_by_the_stroke_speed(tmp_path, capsys):
    # the other way round from the test above: seconds under 'time_ms' make every interval 1000
    # times shorter (10 ms reads 10 us, still a recorder's) and the paper's 5.1 mm/s strokes read
    # 5.1 m/s; every time constant the diagnosis fitted came out 1000 times off, without a word
    muscle = load_muscle("FAM1")
    recs = synthesize(muscle, pressures_Pa=(206.8e3, 413.7e3), rate_Hz=100.0)
    for i, r in enumerate(recs):
        _write_columns(tmp_path / f"s{i}.csv", "time_ms,length_m,pressure_kPa,force_N",
                       r.time_s, r.length_m, r.pressure_Pa / 1e3, r.force_N)  # fmt: skip
    run_bad(["diagnose", "--muscle", "FAM1", "s0.csv", "s1.csv"], tmp_path, capsys,
            r"\[time-unit\] s0\.csv: column 'time_ms': the muscle is stroked at 5\.\d+ m/s", r"'time_s'")  # fmt: skip
    # and a fast tester's strokes (0.5 m/s, sampled at 1 kHz) are a bench's
    fast = synthesize(muscle, pressures_Pa=(206.8e3,), rate_Hz=1000.0, speed_m_per_s=0.5)
    assert not [f for f in check_plausibility(fast, muscle) if f.check == "time-unit"]


@pytest.mark.parametrize(
    "unit, factor, hint", [("lbf", 4.4482216152605, "'force_lbf'"), ("kgf", 9.80665, None)]
)
def test_a_force_in_another_unit_under_force_N_is_refused(tmp_path, capsys, unit, factor, hint):
    # a load cell logging lbf (or kgf) under a 'force_N' header passed every check: calibrate
    # wrote a muscle with its braid angle at 33 deg and every law at its bound, and diagnose named
    # a drift at p 0.83
    muscle = load_muscle("FAM1")
    recs = synthesize(muscle, pressures_Pa=(206.8e3, 413.7e3), rate_Hz=20.0)
    assert not check_plausibility(recs, muscle)
    for i, r in enumerate(recs):
        write_csv(
            tmp_path / f"{unit}{i}.csv", Recording(r.time_s, r.length_m, r.pressure_Pa, r.force_N / factor)
        )
    words = [
        r"\[force-unit\] "
        + unit
        + r"0\.csv: column 'force_N': the recorded forces are 0\.\d+ x the muscle's model"
    ]
    err = run_bad(["calibrate", "--muscle", "FAM1", f"{unit}0.csv", f"{unit}1.csv"], tmp_path, capsys, *words)
    assert (hint in err) if hint else ("the numbers fit" not in err)


def test_a_displacement_under_a_length_header_is_said_so_without_force_noise(tmp_path, capsys):
    # displacements from the resting length written under 'length_mm' read as a muscle squashed
    # to a sixth of its length: the model's forces there are meganewtons, and the force checks
    # against it called the load cell dead and the forces 4e-5 x the model's
    muscle = load_muscle("FAM1")
    (r,) = synthesize(muscle, pressures_Pa=(206.8e3,), rate_Hz=20.0)
    _write_columns(tmp_path / "d.csv", "time_s,length_mm,pressure_kPa,force_N",
                   r.time_s, (r.length_m - muscle.rest_length_m) * 1e3 + 5.0, r.pressure_Pa / 1e3, r.force_N)  # fmt: skip
    err = run_bad(["diagnose", "--muscle", "FAM1", "d.csv"], tmp_path, capsys,
                  r"\[length-range\] d\.csv: .*column 'length_mm'", r"is the column 'displacement_mm'\?")  # fmt: skip
    assert "[force-dead]" not in err and "[force-unit]" not in err and "[pressure-" not in err


def test_the_python_entry_points_run_the_commands_checks():
    # the documented Python path (read_csv -> calibrate / diagnose) ran no plausibility check:
    # forces in lbf calibrated to E1 at its bound, lengths in mm were diagnosed as end effects
    import warnings as _warnings

    from efam_mujoco.calibrate import calibrate
    from efam_mujoco.diagnose import diagnose
    from efam_mujoco.recordings import PlausibilityError, PlausibilityWarning

    muscle = load_muscle("FAM1")
    recs = synthesize(muscle, pressures_Pa=(206.8e3, 413.7e3), rate_Hz=20.0)
    lbf = [Recording(r.time_s, r.length_m, r.pressure_Pa, r.force_N / 4.4482216152605) for r in recs]
    with pytest.raises(
        PlausibilityError, match=r"\[force-unit\].*calibrate: the allow argument with force-unit"
    ):
        calibrate(lbf, muscle, ("linear",), heldout=False)
    with pytest.raises(PlausibilityError, match=r"\[force-unit\]"):
        diagnose(lbf, muscle, next_experiment=False)
    in_mm = [Recording(r.time_s, r.length_m * 1e3, r.pressure_Pa, r.force_N) for r in recs]
    with pytest.raises(PlausibilityError, match=r"\[length-unit\]"):
        diagnose(in_mm, muscle, next_experiment=False)
    # allowed by name: the fit goes on, and the warning says what was let through
    with _warnings.catch_warnings(record=True) as caught:
        _warnings.simplefilter("always")
        calibrate(lbf, muscle, ("linear",), heldout=False, allow=("force-unit",))
    assert any(
        issubclass(w.category, PlausibilityWarning) and "[force-unit]" in str(w.message) for w in caught
    )


def test_calibrate_and_load_muscle_name_arguments_that_cannot_be():
    from efam_mujoco.calibrate import calibrate

    muscle = load_muscle("FAM1")
    recs = synthesize(muscle, pressures_Pa=(206.8e3,), rate_Hz=20.0)
    for n in (0, -1, 2.5, True):  # n = 0 fitted to the bounds with an Eq. 14 error of NaN
        with pytest.raises(ValueError, match=r"calibrate: n \(comparison points per pressure level\)"):
            calibrate(recs, muscle, ("linear",), heldout=False, n=n)
    with pytest.raises(ValueError, match="no stress law given"):  # was min()'s "empty sequence"
        calibrate(recs, muscle, ())
    with pytest.raises(TypeError, match="calibrate: muscle must be a Muscle"):
        calibrate(recs, None, ("linear",))
    with pytest.raises(musclefile.MuscleFileError, match="got an empty name"):  # was "'.': is a folder"
        load_muscle("")


def test_suite_list_honours_domain_and_task(tmp_path, capsys):
    code, out, _ = run_cli(["suite", "--list", "--domain", "arm"], tmp_path, capsys)
    assert code == 0 and out.strip() and all(line.startswith("arm-") for line in out.strip().splitlines())
    run_bad(["suite", "--list", "--domain", "foo", "--task", "bar"], tmp_path, capsys, r"no such task")
    # only the flags given (was '--list --domain foo --task None')
    err = run_bad(
        ["suite", "--list", "--domain", "foo"], tmp_path, capsys, r"--list --domain foo: no such task"
    )
    assert "None" not in err


def test_suite_list_refuses_the_flags_it_would_ignore(tmp_path, capsys):
    """--list runs no episode and writes nothing: --json, --strip, --episodes and --seed beside
    it exited 0 and wrote nothing; now refused, naming them."""
    run_bad(["suite", "--list", "--json", "l.json", "--episodes", "3"], tmp_path, capsys,
            r"--list only lists the tasks .*--json, --episodes would be ignored")  # fmt: skip
    run_bad(["suite", "--list", "--strip", "s.png", "--seed", "4"], tmp_path, capsys,
            r"--strip, --seed would be ignored")  # fmt: skip
    assert not (tmp_path / "l.json").exists() and not (tmp_path / "s.png").exists()


def test_real_muscles_held_near_their_full_contraction_pass_the_force_scale():
    # a Festo DMSP-10 held at 75 % of its contraction pulls 0.02-0.23 x what the nominal model
    # says (the model's relative error grows without bound towards the free length): judged only
    # where the model gives at least 60 % of its blocked force, no real file is called a unit
    # mix-up
    import sys

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "scripts"))
    try:
        import festo_diagnose as fd
    finally:
        sys.path.pop(0)
    if not (fd.DATA / "recordings.json").exists():
        pytest.skip("real Festo data absent")
    from efam_mujoco.recordings import read_csv

    meta = json.loads((fd.DATA / "recordings.json").read_text())
    for key, files in fd.groups(meta).items():
        recs = [read_csv(fd.DATA / "recordings" / name, on_bad_rows="drop") for name in files]
        muscle = fd.starting_muscle(key, files, meta, recs)
        for rec in recs:  # each file alone, as a user may diagnose it
            assert not [f.message for f in check_plausibility([rec], muscle) if f.check == "force-unit"]


def test_held_length_and_slow_sampled_recordings_still_pass_the_stroke_speed():
    muscle = load_muscle("FAM1")
    n = 2000
    t = np.arange(n) * 30.0  # a sample every 30 s for 16 h: a creep test at a held length
    held = Recording(t, np.full(n, muscle.rest_length_m), np.full(n, 300e3), np.full(n, 50.0) + np.sin(t))
    assert not [f for f in check_plausibility([held], muscle) if f.check == "time-unit"]
    recs = synthesize(muscle, pressures_Pa=(206.8e3,), rate_Hz=1000.0, speed_m_per_s=0.5e-3)
    assert not [f for f in check_plausibility(recs, muscle) if f.check == "time-unit"]  # 0.5 mm/s at 1 kHz


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda d: d["sleeves"][0].update(fibre_fracton=0.9), "unknown key 'fibre_fracton'"),  # was ignored
        (lambda d: d["rules"].update(extra_key_mm=1.0), "rules: unknown key 'extra_key_mm'"),
        (lambda d: d.update(surprise=1), "unknown key 'surprise'"),
        (lambda d: d["tubings"].append(dict(d["tubings"][0])), "is given to 2 entries"),
        (lambda d: d["sleeves"][0].pop("fibre_fraction"), "missing key 'fibre_fraction'"),
        # was an internal error ('int' object is not iterable) or dict()'s own words
        (lambda d: d.update(sources=5), "'sources' must be a JSON object"),
        (lambda d: d.update(sources=None), "'sources' must be a JSON object"),
        (lambda d: d.update(sources=["a paper"]), "'sources' must be a JSON object"),
        (lambda d: d.update(sources="a paper"), "'sources' must be a JSON object"),
        (
            lambda d: d["latex"].update(density_kg_per_m3=10**40),
            r"line 1, column \d+: .*integer of 41 digits",
        ),
    ],
)
def test_catalogue_keys_are_known_names_unique_and_present(tmp_path, edit, words):
    import json as _json
    from importlib import resources

    from efam_mujoco.size.catalogue import CatalogueError, load_catalogue

    doc = _json.loads(resources.files("efam_mujoco.size").joinpath("catalogue.json").read_text())
    edit(doc)
    path = tmp_path / "cat.json"
    path.write_text(_json.dumps(doc))
    with pytest.raises(CatalogueError, match=words):
        load_catalogue(path)


def test_a_catalogue_that_is_a_pipe_is_not_called_missing(tmp_path):
    import os

    from efam_mujoco.size.catalogue import CatalogueError, load_catalogue

    os.mkfifo(tmp_path / "cat.json")
    with pytest.raises(CatalogueError, match="not a regular file"):
        load_catalogue(tmp_path / "cat.json")


# ------------------------------------------------- Python entry points (a blind review's finds)


@pytest.mark.parametrize("pressure", [float("nan"), float("inf"), 1e12, None, "300"])
def test_blocked_force_refuses_what_no_fluid_pressure_can_be(pressure):
    """Before: NaN gave NaN, inf gave inf, 1e12 Pa a 5.8e8 N 'blocked force' (free_length refused
    all of them), and None or a text 0 N."""
    muscle = load_muscle("FAM1")
    # a text of digits also draws the below-1000-Pa warning on its way to the refusal
    with pytest.warns(UserWarning) if pressure == "300" else contextlib.nullcontext():
        with pytest.raises(ValueError, match=r"Muscle\.blocked_push: pressure"):
            muscle.blocked_push(pressure)
    assert muscle.blocked_push(300e3) == pytest.approx(-muscle.blocked_tension(300e3))


@pytest.mark.parametrize(
    "call, words",
    [
        # a negative length met the lock-out spring: -5.75e6 N over the 'stroke'
        (lambda m: m.force_stroke(300e3, -0.1), r"Muscle\.force_stroke: lengths_m: -0\.1 m is not a finite"),
        (lambda m: m.force_stroke(300e3, [0.2, np.nan]), r"lengths_m: nan m"),  # was 0 N
        (lambda m: m.force_stroke(300e3, 0.0), r"lengths_m: 0\.0 m .* above 0 m"),
        (lambda m: m.force_stroke(300e3, "0.2"), r"lengths_m must be numbers \(m\)"),
        (lambda m: m.force_stroke(np.nan, [0.17, 0.2]), r"Muscle\.force_stroke: pressure nan Pa"),  # was 0 N
        (lambda m: m.force_stroke(np.inf, 0.2), r"Muscle\.force_stroke: pressure inf Pa"),
        (lambda m: m.force_stroke(-5e5, 0.2), r"pressure -500000\.0 Pa is outside"),  # below vacuum
        (lambda m: m.outer_radius(-1.0), r"Muscle\.outer_radius: length_m: -1\.0 m"),  # was 0 m
        (lambda m: m.outer_radius(0.0), r"length_m: 0\.0 m"),  # was the thread's whole radius
        (lambda m: m.outer_radius([0.2, np.inf]), r"length_m: inf m"),
        (lambda m: m.outer_radius(None), r"length_m must be numbers \(m\), got None"),
    ],
)
def test_force_stroke_and_outer_radius_refuse_lengths_and_pressures_no_muscle_has(call, words):
    """Before: a NaN length or pressure gave a force-stroke curve of 0 N, a negative length a
    lock-out force of millions of N, and the radius of a NaN length was NaN, of 0 m or a negative
    length a number. The simulation's own force stays total (0 N, lock-out; test_muscle.py)."""
    with pytest.raises(ValueError, match=words):
        call(load_muscle("FAM1"))


def test_force_stroke_and_outer_radius_are_unchanged_for_lengths_a_muscle_has():
    """The checks change no number: beyond the admissible lengths the lock-out spring acts, past
    the thread length the radius is 0 m, and the force the diagnosis and arm call takes anything."""
    muscle = load_muscle("FAM1")
    L = np.linspace(0.5 * muscle.min_length_m, 1.2 * muscle.thread_length_m, 50)
    np.testing.assert_array_equal(muscle.force_stroke(300e3, L), muscle.tension(300e3, L))
    assert muscle.force_stroke(-50e3, 0.2) == muscle.tension(0.0, 0.2)  # under zero gauge: zero
    assert muscle.outer_radius(1.1 * muscle.thread_length_m) == 0.0
    assert muscle.outer_radius(muscle.rest_length_m) == pytest.approx(muscle.rest_diameter_m / 2, rel=1e-12)
    assert muscle.tension(300e3, np.nan) == 0.0 and np.isfinite(muscle.tension(300e3, -1.0))
    assert np.isnan(muscle.wall_thickness(np.nan))  # the clipped helpers: NaN in, NaN out, as before
    with pytest.warns(UserWarning, match=r"Muscle\.force_stroke: pressure 300 Pa is below 1000 Pa"):
        muscle.force_stroke(300.0, 0.2)


def test_arm_spec_refuses_text_flags_and_sizes_no_bench_arm_has():
    """Before: gravity='no' and hold_tip='false' were taken as true (a text is truthy); a radius in
    mm written as metres, a payload of 1e6 kg and an 11-day valve lag were accepted (the CLI
    flags had ranges, the spec file and the constructor none)."""
    from efam_mujoco import arm

    section = arm.paper_section(disks=2)
    for kw, words in [
        (dict(gravity="no"), "gravity must be True or False"),
        (dict(hold_tip="false"), "hold_tip must be True or False"),
        (dict(payload_kg=1e6), r"payload_kg = 1000000\.0 is outside 0 \.\. 50 kg"),
        (dict(pressure_tau_s=1e6), r"pressure_tau_s = 1000000\.0 is outside 0 \.\. 10 s"),
        (dict(bend_viscosity_N_m2_s=1e12), "bend_viscosity_N_m2_s"),
    ]:
        with pytest.raises(ValueError, match=words):
            arm.ArmSpec(sections=(section,), **kw)
    # kPa written as Pa: refused, not only warned of (before, an arm whose muscles can never
    # inflate was built, and diagnose-arm replayed every command as the arm at rest)
    with pytest.warns(UserWarning, match=r"max_pressure_Pa: pressure 517\.1 Pa is below 1000 Pa"):
        with pytest.raises(ValueError, match=r"max_pressure_Pa = 517\.1 Pa is within every muscle's dead band "
                           r"\(the lowest, FAM1's, ends at 33\.\d+ kPa\).*is it in kPa\?"):  # fmt: skip
            arm.ArmSpec(sections=(section,), max_pressure_Pa=517.1)
    muscle = load_muscle("FAM1")
    with pytest.raises(ValueError, match=r"radius_m = 18\.2 is outside 0\.001 \.\. 0\.5 m"):
        arm.SectionSpec(muscles=(muscle,) * 3, radius_m=18.2)
    with pytest.raises(ValueError, match=r"muscles\[0\] is a str, not a Muscle"):
        arm.SectionSpec(muscles=("FAM1",) * 3)
    assert arm.ArmSpec(sections=(section,), gravity=np.bool_(False)).gravity == np.bool_(False)


def test_diagnose_in_python_warns_of_kilopascals_given_as_pascals():
    """Before: recordings built in Python with kPa under pressure_Pa gave no warning, then
    'offset_N = 100 is outside [-100, 100]' (a fitted value a rounding past its bound: the fit
    now holds its amplitudes at the bounds the solver had)."""
    from efam_mujoco.diagnose import diagnose
    from efam_mujoco.diagnose.effects import check_values

    muscle = load_muscle("FAM1")
    t = np.arange(0.0, 6.0, 0.01)
    L = muscle.rest_length_m * (1.0 + 0.1 * (1 - np.cos(np.pi * t / 3.0)))
    P = np.full(len(t), 300.0)  # 300 kPa meant
    recording = Recording(t, L, P, muscle.push(300e3, L))
    with pytest.warns(UserWarning, match=r"diagnose: pressure 300 Pa is below 1000 Pa"):
        try:
            diagnose([recording], muscle, next_experiment=False)
        except ValueError:
            pass  # refusing these data is fine too: the warning came first
    # a value past its bound by a last digit is said with the digits that show it
    with pytest.raises(ValueError, match=r"offset_N' = 100\.0000001 is outside \[-100, 100\]"):
        check_values("force_offset", {"offset_N": 100.0000001})


def _five_pressure_levels(folder: Path) -> tuple[list[str], Path]:
    """The five FAM1 example recordings copied into ``folder``: their names, and the 45 psi one's path."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "recordings"
    names = [f"fam1_p{p}psi.csv" for p in (15, 30, 45, 60, 75)]
    for name in names:
        (folder / name).write_bytes((examples / name).read_bytes())
    return names, folder / "fam1_p45psi.csv"


def test_one_file_of_a_set_in_psi_under_a_kilopascal_header_is_refused(tmp_path, capsys):
    """Before: 45 psi written as '45 kPa' in one of five files passed every check; `calibrate`
    wrote a muscle with 46 N RMS error (its blocked-force stage dropped the level as an outlier)
    and `diagnose` named physics (`outside_library` 0.82, then a force offset and end effects)."""
    names, wrong = _five_pressure_levels(tmp_path)
    text = wrong.read_text()
    wrong.write_text(text.replace("pressure_psi", "pressure_kPa", 1))
    for verb in (
        ["calibrate", *names, "--muscle", "FAM1", "--out", "m.json"],
        ["diagnose", *names, "--muscle", "FAM1"],
    ):
        run_bad(verb, tmp_path, capsys, r"\[pressure-unit\] fam1_p45psi\.csv: column 'pressure_kPa'",
                "'pressure_psi'", "--allow pressure-unit")  # fmt: skip
    # the files as written pass it
    wrong.write_text(text)
    code, _, err = run_cli(["calibrate", *names, "--muscle", "FAM1", "--out", "m.json"], tmp_path, capsys)
    assert code == 0 and "pressure-unit" not in err


@pytest.mark.parametrize("header", ["displacement_in", "displacement_mm"])
def test_lengths_in_centimetres_under_another_length_header_are_refused(tmp_path, capsys, header):
    """Before: centimetres under 'displacement_in' put FAM1 at 2.5 times the strain it reached,
    still inside the threads' geometric reach, so every length check passed; `calibrate` wrote a
    muscle with 68 N RMS error (Eq. 14 error 469 %) and exit 0, and with one file of five
    mislabelled the force-unit check blamed the good force column. The forces fit the model
    re-read in centimetres, and the message says so; the files as written pass."""
    names, wrong = _five_pressure_levels(tmp_path)
    text = wrong.read_text()
    lines = text.splitlines()
    column = lines[0].split(",").index("length_m")
    rows = [lines[0].replace("length_m", header)]
    rest = load_muscle("FAM1").rest_length_m
    for line in lines[1:]:
        cells = line.split(",")
        cells[column] = f"{(float(cells[column]) - rest) * 100:.9g}"  # the displacement in centimetres
        rows.append(",".join(cells))
    wrong.write_text("\n".join(rows) + "\n")
    for verb in (
        ["calibrate", *names, "--muscle", "FAM1", "--out", "m.json"],
        ["diagnose", *names, "--muscle", "FAM1"],
    ):
        code, _, err = run_cli(verb, tmp_path, capsys)
        assert code == 2 and not (tmp_path / "m.json").exists(), err
        assert f"[length-unit] fam1_p45psi.csv: column '{header}'" in err and "'displacement_cm'" in err, err
        assert "force-unit" not in err, err  # the good load cell is not blamed
    wrong.write_text(text)
    code, _, err = run_cli(["calibrate", *names, "--muscle", "FAM1", "--out", "m.json"], tmp_path, capsys)
    assert code == 0 and "length-unit" not in err


def test_suite_actions_outside_the_pressure_range_are_said_not_silently_clipped():
    """Before: dm_control's step clipped 300 (kPa typed for a fraction), 1.5 or -1 without a word,
    and a NaN action reached MuJoCo's controls; the gym wrapper already warned."""
    from efam_mujoco import suite

    env = suite.load("bundle", "reach", task_kwargs={"random": 0})
    env.reset()
    with pytest.warns(RuntimeWarning, match=r"outside \[0, 1\]: clipped .* once per task"):
        env.step(np.full(3, 300.0))
    assert np.allclose(env.physics.data.ctrl, env.physics.layout.rated)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.step(np.full(3, 1.5))  # said once
        env.step(np.full(3, 0.5))
    with pytest.raises(ValueError, match=r"finite pressure fractions"):
        env.step(np.array([np.nan, 0.0, 0.0]))


@pytest.mark.parametrize(
    "action", [0.5, [0.5], [0.5, 0.5, 0.5, 0.5], [[0.5, 0.5, 0.5]]], ids=["scalar", "one", "four", "2-d"]
)
def test_suite_actions_of_another_shape_are_refused_by_name(action):
    """Before: a single number was spread over all three muscles without a word, and a wrong
    length ended in numpy's 'operands could not be broadcast together'."""
    from efam_mujoco import suite

    env = suite.load("bundle", "reach", task_kwargs={"random": 0})
    env.reset()
    with pytest.raises(
        ValueError, match=r"one pressure fraction per muscle, shape \(3,\) \(the action spec's\)"
    ):
        env.step(np.asarray(action))
    env.step(np.full(3, 0.5))  # the right shape still steps


def test_diagnose_in_python_checks_its_arguments():
    """Before: max_effects=-1 was accepted, laws='linear' was read letter by letter ('unknown
    stress law l'), and a muscle of None ended in an AttributeError deep inside."""
    from efam_mujoco.diagnose import diagnose

    muscle = load_muscle("FAM1")
    t = np.arange(0.0, 6.0, 0.01)
    L = muscle.rest_length_m * (1.0 + 0.1 * (1 - np.cos(np.pi * t / 3.0)))
    recording = Recording(t, L, np.full(len(t), 300e3), muscle.push(300e3, L))
    with pytest.raises(ValueError, match=r"max_effects must be a whole number >= 0, got -1"):
        diagnose([recording], muscle, max_effects=-1)
    with pytest.raises(TypeError, match=r"muscle must be a Muscle \(load_muscle\), got NoneType"):
        diagnose([recording], None)
    d = diagnose([recording], muscle, laws="linear", max_effects=0, next_experiment=False)
    assert d.to_json()["refit"]["law"] == "linear"


def test_calibrate_refuses_a_dead_load_cell_even_when_its_check_is_allowed(tmp_path, capsys):
    """Before: with --allow force-dead (and the force checks it implies) a load cell reading 0 N
    everywhere ended in scipy's 'c must not contain values inf, nan, or None'. And the new
    pressure-unit check must not blame the pressure for it (zeros sit nearer a muscle whose
    pressures are read a thousand times smaller)."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "recordings"
    names = [f"fam1_p{p}psi.csv" for p in (15, 45, 75)]
    for name in names:
        lines = (examples / name).read_text().splitlines()
        head = lines[0].split(",")
        k = next(i for i, c in enumerate(head) if c.startswith(("force", "tension")))
        rows = [",".join(c if i != k else "0" for i, c in enumerate(line.split(","))) for line in lines[1:]]
        (tmp_path / name).write_text("\n".join([lines[0], *rows]) + "\n")
    allow = ["--allow", "force-dead", "force-model", "force-sign", "force-range"]
    err = run_bad(["calibrate", *names, "--muscle", "FAM1", "--out", "m.json", *allow], tmp_path, capsys,
                  r"the force is 0 N in every sample", r"dead or disconnected load cell")  # fmt: skip
    assert "pressure-unit" not in err


def test_an_empty_file_name_is_said_to_be_empty(tmp_path, capsys):
    """Before: '' became '.' and the message was '.: is a folder, not a recording file'."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "recordings"
    (tmp_path / "r.csv").write_bytes((examples / "fam1_p45psi.csv").read_bytes())
    run_bad(["calibrate", "", "--muscle", "FAM1"], tmp_path, capsys, r"FILE: an empty file name")
    run_bad(["diagnose", "r.csv", "--muscle", ""], tmp_path, capsys, r"--muscle: an empty file name")
    # efam muscle takes the muscle as a positional argument: no '--muscle' flag to name
    run_bad(["muscle", ""], tmp_path, capsys, r"MUSCLE: an empty file name")
    run_bad(
        ["diagnose", "r.csv", "--muscle", "FAM1", "--json", " "],
        tmp_path,
        capsys,
        r"--json: an empty file name",
    )


# every type=Path argument: argparse had made '' the current folder ('.') before the check
# (efam diagnose-arm "" said '.: is a folder, not a recording file'; efam arm --xml "" said
# "--xml: '.' is not a file name")
EMPTY_PATH_ARGUMENTS = [
    (["diagnose-arm", "", "--model", "arm.xml"], "RECORDING"),
    (["diagnose-arm", "rec.csv", "--model", ""], "--model"),
    (["diagnose-arm", "rec.csv", "--model", "arm.xml", "--json", ""], "--json"),
    (["diagnose-arm", "rec.csv", "--model", "arm.xml", "--report", ""], "--report"),
    (["arm", "--xml", ""], "--xml"),
    (["arm", "--pressures-kPa", "0", "0", "0", "--json", ""], "--json"),
    (["arm", "--write-models", "--models-dir", ""], "--models-dir"),
    (["suite", "--episodes", "1", "--json", ""], "--json"),
    (["suite", "--episodes", "1", "--strip", ""], "--strip"),
]


@pytest.mark.parametrize(
    ("argv", "name"), EMPTY_PATH_ARGUMENTS, ids=[f"{argv[0]} {name}" for argv, name in EMPTY_PATH_ARGUMENTS]
)
def test_an_empty_path_argument_is_said_to_be_empty(argv, name, tmp_path, capsys):
    """Before: '' reached the command as Path('.') and the message named '.', not the argument."""
    # real inputs beside the empty argument, so that it is the only mistake
    (tmp_path / "arm.xml").write_bytes(
        (Path(__file__).resolve().parents[1] / "models" / "arm_1x3.xml").read_bytes()
    )
    (tmp_path / "rec.csv").write_text("time_s,p_m0_kPa,tip_x_m,tip_y_m,tip_z_m\n0,0,0,0,0.1\n")
    run_bad(argv, tmp_path, capsys, re.escape(f"efam {argv[0]}: error: {name}: an empty file name"))


def test_a_path_argument_still_arrives_as_a_path():
    """The empty-name check keeps '' as typed; every other value of a type=Path argument is
    still a Path for the command's code."""
    from efam_mujoco.cli import build_parser

    args = build_parser().parse_args(["diagnose-arm", "rec.csv", "--model", "arm.xml", "--report", "out"])
    assert (args.recording, args.model, args.report) == (Path("rec.csv"), Path("arm.xml"), Path("out"))
    assert all(isinstance(v, Path) for v in (args.recording, args.model, args.report))
    # an output file's name is kept as typed: Path() would drop the trailing '/' the output
    # check refuses (test_robust_cli: a file output ending in a separator)
    assert build_parser().parse_args(["arm", "--xml", "a.xml/"]).xml == "a.xml/"


def test_the_suite_script_runs_the_efam_command_and_its_checks(tmp_path, capsys, monkeypatch):
    """Before: ``python -m efam_mujoco.suite.cli`` built a parser of its own and skipped every
    check of ``efam suite`` (an empty file name, an output over a folder)."""
    from efam_mujoco.suite import cli as suite_cli

    monkeypatch.chdir(tmp_path)
    assert suite_cli.main(["--episodes", "1", "--json", ""]) == 2
    assert capsys.readouterr().err.strip() == "efam suite: error: --json: an empty file name"
    assert list(tmp_path.iterdir()) == []


def test_calibrate_refuses_an_output_folder_before_the_fit(tmp_path, capsys, monkeypatch):
    """Before: `--out adir` (a folder) was refused only after the whole fit."""
    from efam_mujoco.calibrate import cli as calibrate_cli

    examples = Path(__file__).resolve().parents[1] / "examples" / "recordings"
    (tmp_path / "r.csv").write_bytes((examples / "fam1_p45psi.csv").read_bytes())
    (tmp_path / "adir").mkdir()

    def no_fit(*args, **kwargs):
        raise AssertionError("the recordings were read (and would be fitted) before the output was checked")

    monkeypatch.setattr(calibrate_cli, "read_for_fit", no_fit)
    run_bad(["calibrate", "r.csv", "--muscle", "FAM1", "--out", "adir"], tmp_path, capsys,
            r"--out adir: is a folder, not a file")  # fmt: skip


def test_a_rated_pressure_below_the_dead_band_is_refused(tmp_path, capsys):
    """Before: --rated-pressure-kPa 0.001 was accepted and the data were blamed ('pressure 103.4
    kPa is above the rated pressure 0.001 kPa; the numbers fit pressure_Pa')."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "recordings"
    (tmp_path / "r.csv").write_bytes((examples / "fam1_p45psi.csv").read_bytes())
    run_bad(["diagnose", "r.csv", "--muscle", "FAM1", "--rated-pressure-kPa", "0.5"], tmp_path, capsys,
            r"--rated-pressure-kPa 0\.5 is at or below the muscle's dead band 33\.62 kPa")  # fmt: skip


def test_write_models_refuses_arm_flags_it_would_ignore(tmp_path, capsys):
    """Before: `efam arm --write-models --sections 3 --radius-mm 100` exited 0 and wrote the
    package's preset models, byte for byte, without a word about the flags."""
    run_bad(["arm", "--write-models", "--models-dir", "m", "--sections", "3", "--radius-mm", "100"], tmp_path,
            capsys, r"--write-models regenerates the package's preset models .* --sections, --radius-mm would "
            r"be ignored: drop them, or write this arm with --xml FILE")  # fmt: skip
    assert not (tmp_path / "m").exists()
    (tmp_path / "data.csv").write_text(
        "time_s\n0\n"
    )  # before: 'cannot write data.csv/arm_1x3.xml (File exists)'
    run_bad(["arm", "--write-models", "--models-dir", "data.csv"], tmp_path, capsys,
            r"--models-dir data\.csv: is a file, not a folder")  # fmt: skip


def test_a_constant_force_column_is_called_dead_without_a_unit_hint(tmp_path, capsys):
    """Before: a load cell reading 40 N in every row was also offered "the numbers fit
    'force_lbf'" (no unit puts a constant on the model), and a file of one row repeated was told
    "the model expects a range of 0 N: a dead or disconnected load cell?"."""
    examples = Path(__file__).resolve().parents[1] / "examples" / "recordings"
    lines = (examples / "fam1_p45psi.csv").read_text().splitlines()
    k = next(i for i, c in enumerate(lines[0].split(",")) if c.startswith(("force", "tension")))
    rows = [",".join(c if i != k else "40.0" for i, c in enumerate(line.split(","))) for line in lines[1:]]
    (tmp_path / "flat.csv").write_text("\n".join([lines[0], *rows]) + "\n")
    err = run_bad(["calibrate", "flat.csv", "--muscle", "FAM1", "--out", "m.json"], tmp_path, capsys,
                  r"flat\.csv: column '\w+': the force hardly changes \(range 0 N", r"dead or disconnected load cell")  # fmt: skip
    assert "force_lbf" not in err and "[force-unit]" not in err, err
    rows = [f"{0.01 * i:.2f},0.17018,45,160.0" for i in range(600)]
    (tmp_path / "one.csv").write_text("time_s,length_m,pressure_psi,force_N\n" + "\n".join(rows) + "\n")
    err = run_bad(["calibrate", "one.csv", "--muscle", "FAM1", "--out", "m.json"], tmp_path, capsys,
                  r"one\.csv: columns 'length_m' and 'pressure_psi' are both constant: nothing was tested")  # fmt: skip
    assert "expects a range of 0 N" not in err, err


# ------------------------------------------------------- scripts reading the shared data folder
SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def _script(name: str, argv, cwd: Path, **env_vars):
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("EFAM_SHARED_DIR", "EFAM_FESTO_DATA")}
    env.update(EFAM_PROGRESS="0", MPLBACKEND="Agg", **env_vars)
    return subprocess.run([sys.executable, str(SCRIPTS / name), *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)  # fmt: skip


@pytest.mark.parametrize(
    "script, argv",
    [("festo_calibrate.py", ["--quick", "--out", "r.json", "--figure", "f.png"]),
     ("festo_diagnose.py", ["--no-figures", "--only", "none"])],
)  # fmt: skip
@pytest.mark.parametrize("variable", ["EFAM_FESTO_DATA", "EFAM_SHARED_DIR"])
@pytest.mark.parametrize("exists", [True, False])
def test_a_data_folder_without_the_data_is_skipped_naming_what_is_missing(
    tmp_path, script, argv, variable, exists
):
    """$EFAM_FESTO_DATA (or $EFAM_SHARED_DIR) naming a folder without the data, or no folder:
    the data are absent, so the scripts skip cleanly (exit 0, one line), naming the file they
    looked for (the folder itself was called absent when it existed), and write nothing."""
    wrong = tmp_path / "not_the_data"
    if exists:
        (wrong / "recordings").mkdir(parents=True)
    done = _script(script, argv, tmp_path, **{variable: str(wrong)})
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Traceback" not in done.stderr and "skipped" in done.stdout
    looked = wrong if variable == "EFAM_FESTO_DATA" else wrong / "data" / "real" / "festo_dmsp"
    assert f"{looked / 'recordings.json'} is absent" in done.stdout, done.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == (["not_the_data"] if exists else [])


def test_the_default_shared_folder_absent_is_still_skipped_cleanly(tmp_path):
    import subprocess
    import sys

    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import shared_data; "
        "from pathlib import Path; shared_data.CHECKOUT = Path(sys.argv[2]) / 'checkout'; "
        "import festo_calibrate; sys.exit(festo_calibrate.main(['--quick', '--out', 'r.json']))"
    )
    env = {
        k: v for k, v in __import__("os").environ.items() if k not in ("EFAM_SHARED_DIR", "EFAM_FESTO_DATA")
    }
    done = subprocess.run([sys.executable, "-c", code, str(SCRIPTS), str(tmp_path)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("festo_calibrate: skipped, ") and "is absent" in done.stdout
    assert not (tmp_path / "r.json").exists()


def _constants_file(folder: Path, **changes) -> Path:
    """A contractile muscle given by its constants (a Festo DMSP-20-like McKibben), as a file."""
    doc = {
        "format": "efam_mujoco.muscle/1", "name": "dmsp20",
        "constants": {"rest_length_m": 0.274, "rest_diameter_m": 0.03, "theta_rest_deg": 65.0,
                      "bladder_volume_m3": 2e-5},
        "deadband_kPa": 20.0, "tension_only": True,
        "stress": {"default": "exponent", "laws": {"exponent": {"E1_Pa": 5e5, "E2": 1.0, "E3": 0.5, "E4": 1.5}}},
    }  # fmt: skip
    for key, value in changes.items():
        doc["stress"]["laws"]["exponent"][key] = value
    path = folder / "dmsp20.json"
    path.write_text(json.dumps(doc))
    return path


def test_an_exponent_law_stiffening_exponent_no_rubber_has_is_refused(tmp_path, capsys):
    """E4 = 700 loaded on a contractile muscle, whose strains keep |eps|^700 finite; the paper's
    are 1.35 and 1.52."""
    assert load_muscle(_constants_file(tmp_path, E4=10.0)).stress.name == "exponent"  # the bound itself
    run_bad(["muscle", _constants_file(tmp_path, E4=700.0).name, "--json", "out.json"], tmp_path, capsys,
            r"dmsp20\.json: stress law 'exponent': coefficient 'E4' = 700 cannot be physical",
            r"dimensionless.*lies in 1 \.\. 10")  # fmt: skip


def test_the_plausibility_bounds_take_every_real_muscle():
    """The presets, a Festo DMSP-40 (40 mm bore, lengths to 9 m) and a 1.8 mm thin McKibben load."""
    for name in ("FAM1", "FAM2"):
        load_muscle(name)
    doc = musclefile.muscle_document(load_muscle("FAM1"))
    for diameter, length in ((0.05, 9.0), (0.0018, 0.05)):
        constants = {"rest_length_m": length, "rest_diameter_m": diameter, "theta_rest_deg": 60.0}
        constants["bladder_volume_m3"] = 0.2 * np.pi * diameter**2 / 4 * length
        musclefile.muscle_from_document({**doc, "constants": constants, "tension_only": True}, "real")


@pytest.mark.parametrize("lag_s", [1e30, 61.0])
def test_a_pressure_lag_no_valve_has_is_refused_in_python_as_by_the_plugin(lag_s):
    from efam_mujoco.plugin import actuator_dynamics

    with pytest.raises(ValueError, match=r"RigOptions\.pressure_lag_s must be at most 60 s.*was it in ms"):
        rig.RigOptions(pressure_lag_s=lag_s)
    with pytest.raises(ValueError, match=r"pressure lag \(dynprm\) .* s must be in 0 \.\. 60 s"):
        actuator_dynamics(lag_s=lag_s)
    assert 'dynprm="60.0"' in actuator_dynamics(lag_s=60.0)


def test_a_fitted_dead_band_below_100_Pa_is_written_as_zero(tmp_path):
    """A fit on a muscle with no dead band can land a few Pa from 0 (calibrate's and diagnose's
    fits are bounded at 0 only); a muscle file refuses 1 .. 100 Pa (a kPa value written as Pa), so
    the writer says 0 (none a bench can tell from 0) and the file loads. The fit itself is left as
    it is: its value moves nothing a bench can see."""
    from dataclasses import replace

    from efam_mujoco.calibrate import fit_blocked

    P = np.linspace(50e3, 500e3, 10)
    assert fit_blocked(P, 2e-4 * (P - 30e3)).deadband_Pa == pytest.approx(30e3)
    for deadband, written in ((40.0, 0.0), (0.5, 0.0005), (150.0, 0.15)):
        path = musclefile.save_muscle(
            tmp_path / f"m{deadband:g}.json", replace(load_muscle("FAM1"), deadband_Pa=deadband)
        )
        assert json.loads(path.read_text())["deadband_kPa"] == pytest.approx(written)
        assert load_muscle(path).deadband_Pa == pytest.approx(written * 1e3)
