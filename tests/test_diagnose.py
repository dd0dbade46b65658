"""``diagnose`` blind on synthetic recordings with a concealed effect (a small version of
bench/bench_diagnose.py), the test-protocol segmentation, the JSON and the command line."""

import json

import numpy as np
import pytest

from efam_mujoco import load_muscle
from efam_mujoco.cli import main
from efam_mujoco.diagnose import diagnose
from efam_mujoco.diagnose.effects import EFFECT_NAMES, EffectModel
from efam_mujoco.diagnose.segment import label
from efam_mujoco.diagnose.synth import Protocol, synthesize
from efam_mujoco.recordings import write_csv


@pytest.fixture(scope="module")
def runs():
    """Diagnoses of a few concealed truths (seeds outside the tuning and benchmark ranges)."""
    out = {}
    for effect, seed in (("none", 901), ("friction", 902), ("viscoelasticity", 903), ("pressure_lag", 904),
                         ("drift", 905)):  # fmt: skip
        recording, truth = synthesize(seed, effect)
        out[effect] = (recording, truth, diagnose([recording], load_muscle(truth.base_name)))
    return out


def test_protocol_is_segmented_into_the_experimenters_cycles():
    recording, truth = synthesize(11, "none")
    x = recording.length_m / truth.muscle.rest_length_m - 1
    lab = label(recording.time_s, x, recording.pressure_Pa, [0])
    # strokes: a passive stroke, slow-fast-slow at five pressures, one repeat of the first
    # pressure: 17 out-and-back cycles driven by the length; each pressure step is its own
    # (pressure-driven) half-cycle
    stroke_cycles = [
        c
        for c in np.unique(lab.cycle)
        if np.any(lab.moving[lab.cycle == c] & (lab.driver[lab.cycle == c] == 0))
    ]
    assert len(stroke_cycles) == 1 + 5 * 3 + 1
    np.testing.assert_allclose(lab.levels_Pa / 1e3, [0, 103.4, 206.8, 310.3, 413.7, 517.1], atol=2.0)
    fast = np.unique(lab.cycle[(lab.rate_class == 1) & (lab.driver == 0)])
    assert len(fast) == 5  # the one fast stroke at each pressure
    assert lab.n_folds == 5
    # every fold holds out whole half-cycles at more than one pressure level, in both directions
    for k in range(lab.n_folds):
        assert len(np.unique(lab.level[lab.fold == k])) >= 2
        halves = np.unique(lab.half_cycle[lab.fold == k])
        assert all(np.all(lab.fold[lab.half_cycle == h] == k) for h in halves)
        d = lab.direction[(lab.fold == k) & (lab.driver == 0)]
        assert (d > 0).any() and (d < 0).any()


@pytest.mark.parametrize("effect", ["friction", "viscoelasticity", "pressure_lag", "drift"])
def test_concealed_effect_is_named_and_held_out_error_halves(runs, effect):
    _, truth, d = runs[effect]
    assert d.names[0] == effect
    assert d.heldout_rms_after_N < 0.5 * d.heldout_rms_before_N
    assert d.rms_after_N < d.rms_before_N
    # what is left is close to the noise floor
    assert d.heldout_rms_after_N < 2.0 * d.noise_N


def test_clean_recording_names_nothing(runs):
    recording, truth, d = runs["none"]
    assert d.effects == []
    assert d.rms_after_N == pytest.approx(d.rms_before_N)
    # the re-fit model replays the recording to within its noise
    assert d.rms_before_N < 1.2 * truth.noise_N + 0.3
    assert d.noise_N == pytest.approx(truth.noise_N, rel=0.25)


def test_noise_floor_sees_the_sensor_noise_not_the_effect(runs):
    _, truth, d = runs["friction"]
    assert d.noise_N == pytest.approx(truth.noise_N, rel=0.25)
    assert d.located["residual_rms_N"] > 3 * d.noise_N
    assert "direction" in d.located["above_noise"]


def test_located_viscoelasticity_relaxes_in_holds_and_grows_with_rate(runs):
    _, _, d = runs["viscoelasticity"]
    factors = d.located["factors"]
    assert factors["dwell"]["above_noise"]
    # after lengthening the pull relaxes: the push residual rises during the hold
    after_rising = next(b for b in factors["dwell"]["bins"] if b["bin"] == "after rising")
    assert after_rising["mean_N"] > 0


def test_identified_effect_switches_on_in_simulation(runs):
    recording, _, d = runs["friction"]
    model = d.model  # the re-fitted muscle with the identified effect on
    replay = model.push_recording(recording)
    np.testing.assert_allclose(replay, d.predicted_after, rtol=1e-12)
    before = np.sqrt(
        np.mean((recording.force_N - d.muscle_after.push(recording.pressure_Pa, recording.length_m)) ** 2)
    )
    after = np.sqrt(np.mean((recording.force_N - replay) ** 2))
    assert after < 0.5 * before


def test_the_physics_map_reads_the_reported_correction_on_top_of_the_named_terms(runs):
    # the data-driven gain that doubts a name is the one the report shows beside it (with the
    # input-error features, where a transducer's error that a static term half absorbs shows)
    for effect in ("friction", "viscoelasticity", "drift"):
        _, _, d = runs[effect]
        assert d.effects and d.correction.to_json()["heldout_rms_before_N"] > 0
        assert d.verdict.dd_gain == pytest.approx(d.correction.gain, abs=1e-12)


def test_json_has_the_issue_fields(runs):
    _, _, d = runs["pressure_lag"]
    doc = json.loads(json.dumps(d.to_json()))
    for key in ("effects", "rms_before_N", "rms_after_N", "noise_N", "located"):
        assert key in doc
    e = doc["effects"][0]
    assert e["name"] == "pressure_lag"
    assert set(e) >= {"name", "parameters", "heldout_rms_before_N", "heldout_rms_after_N"}
    assert 0.01 < e["parameters"]["tau_s"] < 1.0
    assert (
        doc["effects"] == []
        or doc["effects"][0]["heldout_rms_after_N"] < doc["effects"][0]["heldout_rms_before_N"]
    )


def test_isometric_pressure_ramps_friction_found():
    # length held, pressure ramped up and down (like the Festo recordings): the rate is the
    # pressure rate and the hysteresis between pressurising and venting is friction's
    recording, truth = synthesize(907, "friction", protocol=Protocol(isometric=True, sample_hz=50.0))
    assert np.ptp(recording.length_m) < 1e-4
    d = diagnose([recording], load_muscle(truth.base_name))
    assert d.names[0] == "friction"
    assert d.located["factors"]["direction"]["above_noise"]
    assert d.heldout_rms_after_N < 0.5 * d.heldout_rms_before_N


def test_cli_writes_json_and_report(tmp_path, runs, capsys):
    recording, truth, _ = runs["pressure_lag"]
    csv = write_csv(tmp_path / "rec.csv", recording)
    out_json = tmp_path / "d.json"
    code = main(["diagnose", str(csv), "--muscle", truth.base_name, "--json", str(out_json),
                 "--report", str(tmp_path / "report")])  # fmt: skip
    assert code == 0
    doc = json.loads(out_json.read_text())
    assert doc["effects"][0]["name"] == "pressure_lag"
    assert (tmp_path / "report" / "report.txt").read_text().count("pressure_lag") >= 1
    assert (tmp_path / "report" / "diagnose_residual_map.png").stat().st_size > 10_000
    assert "Located mismatch" in capsys.readouterr().out


def test_cli_a_json_that_cannot_be_written_leaves_no_report_behind(tmp_path, runs, capsys, monkeypatch):
    # the --json fails at its write (a full disk, a folder that refuses files): the report
    # folder must not be swapped in first, and no temporary is left (a failed run writes nothing)
    from efam_mujoco import files

    recording, truth, _ = runs["pressure_lag"]
    csv = write_csv(tmp_path / "rec.csv", recording)
    real = files._temporary_beside

    def refuse(path, suffix=""):
        if path.name == "d.json":
            raise files.OutputError(f"cannot write {path} (No space left on device)")
        return real(path, suffix)

    monkeypatch.setattr(files, "_temporary_beside", refuse)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["diagnose", str(csv), "--muscle", truth.base_name, "--json", str(tmp_path / "d.json"),
                 "--report", str(tmp_path / "report")])  # fmt: skip
    assert code == 2
    assert "cannot write" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_cli_bad_input_is_one_clear_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,length_m,pressure_kPa,force_N\n0,0.17,100,1\n0,0.17,100,1\n")
    assert main(["diagnose", str(bad), "--muscle", "FAM1"]) == 2
    assert "duplicate time" in capsys.readouterr().err
    assert main(["diagnose", str(bad), "--muscle", "NOPE"]) == 2


def test_effect_model_rejects_unknown_effects():
    with pytest.raises(ValueError, match="unknown effect"):
        EffectModel(load_muscle("FAM1"), [("temperature", {})])
    assert "none" not in EFFECT_NAMES
