"""efam size: catalogue sizing against the paper's muscle, MuJoCo, and independent formulas."""

import json
import math
from dataclasses import replace
from importlib import resources

import pytest

from efam_mujoco import rig
from efam_mujoco.cli import main
from efam_mujoco.muscle import Geometry, Muscle
from efam_mujoco.size import CatalogueError, Material, Request, RequestError, load_catalogue, size
from efam_mujoco.size.design import fitting_for, length_lost

PSI = 6894.757293168361
P75 = 75 * PSI  # 517.1 kPa
INCH = 0.0254


def gaylord_push(P, deadband, d_rest, l_rest, d_ref, l_ref):
    """Eq. 9 with Eq. 5, written out here: push (MuJoCo sign) at the resting length."""
    theta = math.atan(d_ref * l_rest / (l_ref * d_rest))  # Eq. 5, reference angle 45 deg
    return -(P - deadband) * math.pi * d_rest**2 / (4 * math.cos(theta) ** 2) * (3 * math.sin(theta) ** 2 - 1)


def rebuilt(design_dict, material):
    """The muscle made from the printed manufacturing parameters (what a user would build)."""
    m = design_dict["manufacturing"]
    g = Geometry(
        rest_length_m=m["rest_length_m"], rest_diameter_m=m["rest_diameter_m"],
        sleeve_length_ref_m=m["sleeve_length_45deg_m"], sleeve_diameter_ref_m=m["sleeve_diameter_45deg_m"],
        bladder_length_m=m["bladder_length_m"], bladder_inner_diameter_m=m["bladder_inner_diameter_m"],
        bladder_outer_diameter_m=m["bladder_outer_diameter_m"], clamp_length_m=m["clamp_length_m"],
        clamp_inner_diameter_m=m["clamp_inner_diameter_m"], clamp_outer_diameter_m=m["clamp_outer_diameter_m"],
        thread_thickness_m=m["thread_thickness_m"],
    )  # fmt: skip
    return Muscle.from_geometry(g, material.deadband_Pa, material.stress)


# ------------------------------------------------------------------------------ the catalogue


def test_catalogue_rules_reproduce_table1_fittings_and_eq7():
    cat = load_catalogue()
    paper = next(t for t in cat.tubings if t.name.startswith("paper"))
    assert (paper.inner_diameter_m, paper.outer_diameter_m) == pytest.approx((0.019, 0.0222))
    f = fitting_for(paper, cat.rules)
    # Table 1: core 2.133 cm, swage-tube bore 0.884 in, 2.54 cm long, swage tube 1 in outside
    assert f.core_diameter_m == pytest.approx(0.02133, rel=1e-4)
    assert f.channel_outer_diameter_m == pytest.approx(0.884 * INCH, rel=1e-4)
    assert f.length_m == pytest.approx(0.0254, rel=1e-4)
    assert f.swage_outer_diameter_m == pytest.approx(INCH, rel=1e-3)
    assert length_lost(paper, cat.rules) == pytest.approx(0.01372, rel=2e-3)  # Sec. 4.2: 1.372 cm
    kevlar = next(s for s in cat.sleeves if s.name.startswith("paper"))
    assert kevlar.reference_diameter_m == pytest.approx(0.01905)  # README's convention
    assert cat.latex.strain_limit == pytest.approx(2.5)  # 750 % / 3


def test_bad_catalogue_names_the_entry_and_key(tmp_path):
    doc = json.loads(
        load_catalogue.__globals__["resources"]
        .files("efam_mujoco.size")
        .joinpath("catalogue.json")
        .read_text()
    )
    doc["tubings"][2].pop("wall_in")
    path = tmp_path / "cat.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(CatalogueError, match=r"tubings\[2\].*wall"):
        load_catalogue(path)
    doc["tubings"][2]["wall"] = 0.1  # no unit
    path.write_text(json.dumps(doc))
    with pytest.raises(CatalogueError, match="has no unit"):
        load_catalogue(path)


@pytest.mark.parametrize(
    "key, name",
    [("sleeves", "\x1b[31mred"), ("sleeves", ""), ("sleeves", "   "), ("sleeves", 7), ("tubings", "a\nb")],
)
def test_catalogue_names_must_be_visible_text(tmp_path, key, name):
    # a no-break space is visible text (tested below); an escape, a newline or nothing is not
    doc = json.loads(resources.files("efam_mujoco.size").joinpath("catalogue.json").read_text())
    doc[key][1]["name"] = name
    path = tmp_path / "cat.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(CatalogueError, match=rf"{key}\[1\]: key 'name' must be non-blank text") as err:
        load_catalogue(path)
    assert "\x1b" not in str(err.value) and "\n" not in str(err.value)  # shown escaped, never raw


# -------------------------------------------------------------------------------- FAM1 back


def test_fam1_measured_performance_gives_fam1_dimensions():
    """Asked for FAM1's measured performance (280 N blocked, 98 % free stroke at 517.1 kPa) at its
    length with its material, the best design is FAM1's parts and cuts."""
    material = Material.from_muscle("FAM1")
    request = Request(stroke=0.98, force_N=0.0, pressure_Pa=P75, length_m=0.17018, blocked_force_N=280.0)
    result = size(request, material, verify=1)
    best = result.best
    # the parts: FAM1's 3/4 in x 1/16 in tube (Table 1: 1.9 / 2.22 cm) in a 1.905 cm sleeve
    assert best.tubing.inner_diameter_m == pytest.approx(0.019, abs=0.06e-3)
    assert best.tubing.outer_diameter_m == pytest.approx(0.0222, abs=0.03e-3)
    assert best.sleeve.reference_diameter_m == pytest.approx(0.01905)
    g = best.geometry
    # the cuts: bladder 17.78 cm within one cut step plus the growth rule's FAM1-FAM2 spread
    spread = load_catalogue().rules.length_growth_spread * 0.164
    assert abs(g.bladder_length_m - 0.1778) <= 1e-3 + spread
    # sleeve 50.8 cm: Eq. 9 is flat near 12.5 deg (1 N moves the angle 0.2 deg), so the 280 N
    # request pins the sleeve length to about 2 %
    assert g.sleeve_length_ref_m == pytest.approx(0.508, rel=0.02)
    assert best.muscle.theta_rest_deg == pytest.approx(12.54, abs=0.3)
    assert g.rest_diameter_m == pytest.approx(0.0287, abs=0.1e-3)
    assert g.clamp_outer_diameter_m == pytest.approx(0.884 * INCH, abs=0.1e-3)
    # the printed parameters make a muscle that does it (Eq. 9 written independently)
    push = gaylord_push(P75, material.deadband_Pa, g.rest_diameter_m, g.rest_length_m,
                        g.sleeve_diameter_ref_m, g.sleeve_length_ref_m)  # fmt: skip
    assert push >= 280.0 and push == pytest.approx(280.0, rel=0.005)
    assert best.verification.free_stroke.mujoco >= 0.98
    assert best.binding.name == "blocked_force"


# ---------------------------------------------------------------------- MuJoCo: every design


@pytest.mark.parametrize(
    "request_",
    [
        Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15),
        Request(stroke=0.8, force_N=0.0, pressure_Pa=250e3),
        Request(stroke=0.3, force_N=120.0, pressure_Pa=P75, max_diameter_m=0.035),
    ],
    ids=["force-at-stroke", "free-stroke", "strong-short"],
)
def test_every_proposed_design_meets_the_request_in_mujoco(request_):
    material = Material.from_muscle("FAM1")
    result = size(request_, material, verify=0)
    assert result.feasible and len(result.designs) >= 2
    P, S, F = request_.pressure_Pa, request_.stroke, request_.force_N
    for design in result.designs:
        muscle = rebuilt(design.to_dict(), material)
        L = muscle.rest_length_m
        if F > 0:
            # displacement control at the stroke: the load cell still reads the force
            assert rig.stroke_forces(muscle, P, [L * (1 + S)])[0] >= F * 0.98, design.tubing.name
            # force control: pushing F, the plate settles beyond the stroke
            assert rig.equilibrium_length(muscle, P, load_N=F) / L - 1 >= S * 0.98, design.tubing.name
        else:
            assert rig.free_extension(muscle, P) >= S * 0.98, design.tubing.name
        if request_.max_diameter_m:
            assert muscle.rest_diameter_m <= request_.max_diameter_m
        assert design.feasible and all(c.status != "fail" for c in design.checks)


def test_ranking_prefers_lighter_among_equal_fit():
    result = size(Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15), verify=0)
    excess = [d.excess for d in result.designs]
    assert excess == sorted(excess)
    tied = [d.mass_kg for d in result.designs if d.excess == result.designs[0].excess]
    assert tied == sorted(tied)


# -------------------------------------------------------------------------- infeasible requests


def test_infeasible_request_gets_closest_point_and_confirmed_relaxations():
    request = Request(stroke=1.0, force_N=300.0, pressure_Pa=300e3, length_m=0.2)
    result = size(request, verify=0)
    assert not result.feasible
    assert 0 < result.closest.fraction < 1
    relax = {x.requirement: x for x in result.relax}
    assert {"--force", "--stroke", "--pressure"} <= set(relax)
    assert relax["--force"].achievable < 300 and relax["--stroke"].achievable < 1.0
    assert relax["--pressure"].achievable > 300
    assert all(x.confirmed for x in result.relax)
    # independently: the relaxed requests are feasible, and a little beyond them is not
    assert size(replace(request, force_N=relax["--force"].achievable), verify=0, relax=False).feasible
    assert not size(
        replace(request, force_N=relax["--force"].achievable * 1.03), verify=0, relax=False
    ).feasible
    assert size(
        replace(request, pressure_Pa=relax["--pressure"].achievable * 1e3), verify=0, relax=False
    ).feasible


def test_too_narrow_is_relaxed_by_diameter():
    request = Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, max_diameter_m=0.015)
    result = size(request, verify=0)
    relax = {x.requirement: x for x in result.relax}
    assert not result.feasible and relax["--max-diameter"].confirmed
    assert relax["--max-diameter"].achievable > 15


def test_unguided_muscle_is_limited_by_euler_buckling():
    guided = size(Request(stroke=0.3, force_N=50.0, pressure_Pa=400e3, length_m=0.15), verify=0, relax=False)
    unguided = size(
        Request(stroke=0.3, force_N=50.0, pressure_Pa=400e3, length_m=0.15, unguided=True),
        verify=0,
        relax=False,
    )
    assert guided.feasible and not unguided.feasible
    easy = size(
        Request(stroke=0.3, force_N=2.0, pressure_Pa=100e3, length_m=0.05, unguided=True),
        verify=0,
        relax=False,
    )
    for d in easy.designs:
        m, P = d.muscle, 100e3
        # Euler, pinned ends, written out: the wall's modulus at zero strain and P
        r_o, t = m.rest_outer_radius_m, m.rest_wall_thickness_m
        EI = float(m.stress.slope(0.0, P)) * math.pi / 4 * (r_o**4 - (r_o - t) ** 4)
        assert d.performance.blocked_force_N <= math.pi**2 * EI / m.rest_length_m**2


def test_strain_limit_caps_the_stroke():
    result = size(Request(stroke=3.0, force_N=10.0, pressure_Pa=400e3), verify=0)
    assert not result.feasible
    (stroke,) = [x for x in result.relax if x.requirement == "--stroke"]
    assert stroke.achievable <= load_catalogue().latex.strain_limit and stroke.confirmed


# --------------------------------------------------------------------------------------- bundle


def test_bundle_section_reference_beside_mujoco():
    request = Request(stroke=0.5, force_N=300.0, pressure_Pa=400e3, length_m=0.17, bundle=3, payload_kg=0.1)
    result = size(request, verify=1)
    b, m = result.bundle, result.best.muscle
    assert result.best.performance.force_at_stroke_N >= 100.0  # each muscle carries a third
    g = result.best.geometry
    three = 3 * gaylord_push(400e3, m.deadband_Pa, g.rest_diameter_m, g.rest_length_m,
                             g.sleeve_diameter_ref_m, g.sleeve_length_ref_m)  # fmt: skip
    assert b.tip_force_N.analytic == pytest.approx(three, rel=1e-9)
    assert b.tip_force_N.mujoco == pytest.approx(three, rel=0.005)
    assert b.stroke.mujoco == pytest.approx(b.stroke.analytic, rel=0.01)
    assert b.stroke.analytic >= 0.5
    assert b.bend_range_deg > 90 and b.bend_deg.analytic == pytest.approx(90, abs=0.1)
    assert b.bend_deg.mujoco == pytest.approx(b.bend_deg.analytic, abs=1.0)
    assert b.settled
    # payload sag of the horizontal section: the constant-curvature reference cuts at mid-arc, an
    # approximation under distributed weight (measured 3.8 % of the section's length)
    length = m.rest_length_m * (1 + b.stroke.analytic)
    assert b.tip_deflection_m.analytic > 0
    assert abs(b.tip_deflection_m.mujoco - b.tip_deflection_m.analytic) < 0.05 * length


# ----------------------------------------------------------------------------------------- CLI


def test_cli_json_and_figure(tmp_path, capsys):
    out, fig = tmp_path / "size.json", tmp_path / "size.png"
    argv = ["size", "--stroke", "0.5", "--force", "40", "--pressure", "400", "--length", "0.15", "--top", "1"]
    assert main([*argv, "--json", str(out), "--figure", str(fig)]) == 0
    doc = json.loads(out.read_text())
    assert doc["feasible"] and doc["designs"][0]["verification"]["meets_request_in_mujoco"]
    assert set(doc["designs"][0]["constraints"]) >= {
        "force_at_stroke", "blocked_force", "length_range", "bladder_strain", "pressure_rating",
        "drucker", "buckling", "sleeve_fit", "max_diameter",
    }  # fmt: skip
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "MuJoCo" in capsys.readouterr().out


def test_cli_infeasible_exits_1_with_relaxation(capsys):
    argv = ["size", "--stroke", "0.5", "--force", "40", "--pressure", "400", "--max-diameter", "15"]
    assert main(argv) == 1
    out = capsys.readouterr().out
    assert "closest achievable point" in out and "--max-diameter" in out


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--stroke", "98", "--force", "10", "--pressure", "400"], "--stroke must be in (0, 5]"),
        (
            ["--stroke", "0.5", "--force", "ten", "--pressure", "400"],
            "--force takes a plain decimal number in N",
        ),
        # float() and int() read these; no other command's number flag does
        (["--stroke", "0.5", "--force", "10", "--pressure", "5_00"], "got '5_00'"),
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "\uff15\uff10\uff10"],
            "--pressure takes a plain decimal",
        ),
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "400", "--bundle", "\uff13"],
            "--bundle takes a whole",
        ),
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "400", "--top", "1_0"],
            "--top: takes a whole number",
        ),
        # the arm's own payload limit, named by the flag (was "arm: payload_kg = 1000.0 is outside")
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "400", "--bundle", "3", "--payload", "60"],
            "--payload must be in [0, 50] kg",
        ),
        (["--stroke", "0.5", "--force", "10", "--pressure", "-5"], "--pressure must be in (0, 1000] kPa"),
        (["--stroke", "0.5", "--force", "10", "--pressure", "nan"], "--pressure"),
        (["--stroke", "0.5", "--force", "10", "--pressure", "400", "--max-diameter", "0"], "mm"),
        # metres typed into the mm flag (was accepted: 'raise --max-diameter from 0.0287 to 12.3 mm')
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "300", "--max-diameter", "0.0287"],
            "--max-diameter must be in [1, 1000] mm, got 0.0287 (the flag is in mm",
        ),
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "400", "--bundle", "2"],
            "--bundle needs at least 3",
        ),
        # a thousand muscles in a section searched for minutes (the arm builder stops at 24)
        (
            ["--stroke", "0.5", "--force", "10", "--pressure", "400", "--bundle", "1000"],
            "--bundle takes at most 24 muscles",
        ),
        (["--stroke", "0.5", "--force", "10", "--pressure", "400", "--length", "17"], "--length must be in"),
        (["--str", "0.5", "--force", "10", "--pressure", "400"], "--stroke"),  # no abbreviations
        (["--force", "10", "--pressure", "400"], "--stroke"),
    ],
)
def test_cli_bad_flags_name_flag_and_unit(extra, message, capsys):
    assert main(["size", *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--payload", "1"], "--payload (kg) applies to a bundle"),
        (["--top", "0"], "--top must be >= 1"),
        (["--stress-from", "no_such_muscle.json"], "--stress-from"),
        (["--catalogue", "no_such_catalogue.json"], "catalogue file"),
    ],
)
def test_cli_bad_inputs_are_one_line(extra, message, capsys):
    assert main(["size", "--stroke", "0.5", "--force", "10", "--pressure", "400", *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize(
    "kw, message",
    [
        (dict(stroke=98.0), "stroke"),
        (dict(force_N=-1.0), "force_N"),
        (dict(pressure_Pa=0.0), "pressure_Pa"),
        (dict(bundle=2), "bundle"),
        (dict(payload_kg=1.0), "payload_kg"),
        (dict(length_m=17.0), "length_m"),
        (dict(unguided="no"), r"unguided: must be True or False, got 'no'"),
        (dict(unguided=1), "unguided: must be True or False"),
    ],
)
def test_request_errors_name_the_parameter(kw, message):
    base = dict(stroke=0.5, force_N=10.0, pressure_Pa=400e3)
    with pytest.raises(RequestError, match=message):
        Request(**{**base, **kw})


def test_material_from_a_calibrated_muscle_file(tmp_path):
    from efam_mujoco.musclefile import load_muscle, save_muscle

    path = save_muscle(tmp_path / "my.json", load_muscle("FAM2", "polynomial"))
    material = Material.from_muscle(str(path))
    assert material.stress.name == "polynomial" and material.deadband_Pa == pytest.approx(34.47e3)
    request = Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15)
    mine, default = size(request, material, verify=0), size(request, verify=0)
    assert mine.feasible and mine.material.source.endswith("(polynomial law)")
    assert mine.best.performance.force_at_stroke_N >= 40.0
    # another material, another braid angle for the same tube
    tube = mine.best.tubing.name
    other = next(d for d in default.designs if d.tubing.name == tube)
    assert abs(other.muscle.theta_rest_deg - mine.best.muscle.theta_rest_deg) > 0.01


def test_unstable_law_is_named(tmp_path):
    from efam_mujoco.musclefile import FORMAT

    doc = {
        "format": FORMAT, "name": "soft", "deadband_kPa": 30.0,
        "constants": {"rest_length_m": 0.17, "rest_diameter_m": 0.0287, "theta_rest_deg": 12.5,
                      "bladder_volume_m3": 1.7e-5},
        # stable on this muscle's strains, softening to instability at larger ones
        "stress": {"laws": {"polynomial": {"E1_Pa": 1.5e6, "E2": 1.0, "E3_Pa": 0.0, "E4_Pa": -3.5e4}}},
    }  # fmt: skip
    path = tmp_path / "soft.json"
    path.write_text(json.dumps(doc))
    material = Material.from_muscle(str(path))
    easy = size(
        Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15), material, verify=0, relax=False
    )
    drucker = [c for d in easy.designs for c in d.checks if c.name == "drucker"]
    assert easy.feasible and drucker and all(c.passed and c.value > 0 for c in drucker)
    # a long stroke needs small braid angles, whose strains reach where the law softens
    hard = size(
        Request(stroke=1.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15), material, verify=0, relax=False
    )
    assert not hard.feasible
    assert any(note.startswith("drucker:") and "not Drucker-stable" in note for note in hard.notes)


def test_unguided_request_is_told_to_guide_or_shorten():
    request = Request(stroke=0.3, force_N=20.0, pressure_Pa=300e3, length_m=0.25, unguided=True)
    result = size(request, verify=0)
    relax = {x.requirement: x for x in result.relax}
    assert not result.feasible and relax["--unguided"].confirmed
    if "--length" in relax:
        assert relax["--length"].achievable < 0.25 and relax["--length"].confirmed


def test_very_long_muscle_is_reported_not_crashed(capsys):
    # a 5 m muscle rings slowly on the free rig: it may not come to rest, and then it says so
    assert (
        main(["size", "--stroke", "0.5", "--force", "10", "--pressure", "400", "--length", "5", "--top", "1"])
        == 0
    )
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert (
        "-> not checked: the free or loaded rig did not come to rest" in captured.out
        or "meets the request" in captured.out
    )


def test_a_catalogue_name_with_a_no_break_space_is_read():
    doc = json.loads(resources.files("efam_mujoco.size").joinpath("catalogue.json").read_text())
    doc["sleeves"][1]["name"] = "PET\u00a01/8 in"
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "cat.json"
        path.write_text(json.dumps(doc))
        assert any(s.name == "PET\u00a01/8 in" for s in load_catalogue(path).sleeves)


def test_a_thousandfold_relaxation_is_said_as_a_factor():
    # '--pressure 1e-300' was told to rise "(+113999999999999977482...%)", 300 digits long
    from efam_mujoco.size.relax import Relaxation

    huge = Relaxation("--pressure", 1e-300, 114.0, "kPa", (114.0 / 1e-300 - 1) * 100, True)
    assert "(x 1.14e+302)" in huge.message and len(huge.message) < 120
    usual = Relaxation("--pressure", 300.0, 360.0, "kPa", 20.0)
    assert "(+20.0 %)" in usual.message


def test_arm_overlapping_muscles_name_the_flag(capsys):
    # the spec's own words said "raise radius_m", a key the command line does not have
    assert main(["arm", "--radius-mm", "1"]) == 2
    err = capsys.readouterr().err
    assert "overlap at rest" in err and "raise --radius-mm" in err and "radius_m " not in err


def test_a_force_within_the_rounding_of_zero_gives_the_free_stroke():
    # --force 5e-324 leaked scipy's "f(a) and f(b) must have different signs" (no flag named)
    from efam_mujoco.musclefile import load_muscle
    from efam_mujoco.size.constraints import stroke_at_force

    muscle = load_muscle("FAM1")
    free = float(muscle.free_length(400e3))
    for tiny in (5e-324, 1e-300):
        assert stroke_at_force(muscle, 400e3, tiny, free) == pytest.approx(free / muscle.rest_length_m - 1.0)
    assert main(["size", "--stroke", "0.5", "--force", "5e-324", "--pressure", "400"]) == 0
