"""The arm model a recording refers to: an ArmSpec as JSON (``efam_mujoco.arm_spec/1``) or an MJCF.

JSON layout (units in the keys, muscles as muscle-file documents so a calibrated muscle travels
with the arm)::

    {"format": "efam_mujoco.arm_spec/1", "name": "arm_1x3", "orientation": "upright",
     "pressure_tau_s": 0.05, "max_pressure_Pa": 517106.8, "payload_kg": 0.0, "gravity": true,
     "timestep_s": null, "axial_viscosity_N_s": 6.8, "bend_viscosity_N_m2_s": 0.05,
     "hold_tip": false, "mode": "segmented",
     "sections": [{"radius_m": 0.0182, "angles_deg": [0, 120, 240], "disks": 8,
                   "end_mass_kg": null, "body_mass_kg": null, "plate_mass_kg": 0.0,
                   "muscles": [<muscle document>, ...]}]}

The pressure key takes any pressure unit in its name, as a muscle file's keys do
(``max_pressure_kPa``, ``_psi``, ``_bar``, ``_MPa``; an unknown unit is an error naming the key).
``angles_deg`` are within -360 .. 360 deg. A muscle entry may also be a preset name (``"FAM1"``).
``"timestep_s": null`` (the default) lets the builder choose the step from the arm's physics
(``arm/timestep.py``: 1 ms for the default damped arm at D = 8); a number is used as given
(refused beyond the arm's stability limit, with a warning when within less than its margin).
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import fields
from pathlib import Path

import mujoco
import numpy as np

from .. import plugin
from ..arm import ArmSpec, SectionSpec, build_spec
from ..arm.spec import ARM_BOUNDS
from ..files import check_json_name, write_json_atomic
from ..musclefile import MuscleFileError, check_text, load_muscle, muscle_document, muscle_from_document
from ..units import PRESSURE, PressureUnitWarning, UnitError, read_quantity, split_unit

FORMAT = "efam_mujoco.arm_spec/1"
_SECTION_KEYS = ("radius_m", "angles_deg", "disks", "end_mass_kg", "body_mass_kg", "plate_mass_kg")


class ArmModelError(ValueError):
    """An arm model file that cannot be used; the message names the file and the key."""


def spec_to_dict(arm: ArmSpec) -> dict:
    """An :class:`ArmSpec` as a JSON-ready dict (inverse of :func:`spec_from_dict`)."""
    doc = {"format": FORMAT}
    for f in fields(ArmSpec):
        if f.name != "sections":
            doc[f.name] = getattr(arm, f.name)
    doc["sections"] = [
        {**{k: getattr(s, k) for k in _SECTION_KEYS}, "muscles": [muscle_document(m) for m in s.muscles]}
        for s in arm.sections
    ]
    doc["sections"] = json.loads(json.dumps(doc["sections"]))  # tuples -> lists
    return doc


def _json_types(values: dict, cls, where: str) -> None:
    """Each value of ``values`` has the JSON type its field of ``cls`` declares: booleans are
    JSON booleans only (``"false"`` is a true string), numbers are numbers (not booleans),
    angles a list of numbers, names strings; an error names the key."""
    declared = {f.name: str(f.type) for f in fields(cls)}
    for key, value in values.items():
        kind = declared.get(key, "")
        optional = kind.endswith("| None")
        if value is None and optional:
            continue
        base = kind.split("|")[0].strip()
        if base == "bool":
            ok = isinstance(value, bool)
        elif base in ("float", "int"):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            ok = ok and (base == "float" or float(value).is_integer())
        elif base == "str":
            ok = isinstance(value, str)
        elif base.startswith("tuple[float"):
            ok = isinstance(value, list) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
            )
        else:
            continue
        if not ok:
            want = {"bool": "a JSON boolean (true or false)", "int": "a whole number", "float": "a number",
                    "str": "a string"}.get(base, "a list of numbers")  # fmt: skip
            raise ArmModelError(f"{where}: key '{key}' must be {want}, got {json.dumps(value)}")


def _shown_value(value) -> str:
    """``value`` as JSON for a message, cut short (a long list would fill the screen)."""
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):  # a Python caller's object: not JSON at all
        text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


#: the arm's pressure key without its unit: ``max_pressure_<unit>``, any pressure unit (as a muscle
#: file's keys), read in Pa
_MAX_PRESSURE = "max_pressure"


def _max_pressure_in_Pa(doc: dict, label: str) -> tuple[dict, str | None]:
    """``doc`` with its ``max_pressure_<unit>`` (``_kPa``, ``_psi``, ``_bar``...) read as
    ``max_pressure_Pa`` (the field of :class:`ArmSpec`), and the key the file wrote (None when
    it has none). A unit :mod:`efam_mujoco.units` does not know, the key without a unit or given
    twice, or a value that is not a finite number is an :class:`ArmModelError` naming the key."""
    keys = [k for k in doc if k == _MAX_PRESSURE or split_unit(k)[0] == _MAX_PRESSURE]
    if not keys:
        return doc, None
    try:
        value = read_quantity(doc, _MAX_PRESSURE, "pressure", label)
    except UnitError as err:
        raise ArmModelError(str(err)) from None
    doc = {k: v for k, v in doc.items() if k not in keys}
    doc["max_pressure_Pa"] = value
    return doc, keys[0]


def _check_max_pressure(doc: dict, key: str, sections: list, label: str) -> None:
    """The checks :class:`ArmSpec` makes of ``max_pressure_Pa``, said in the unit and key the file
    used (``max_pressure_kPa = 20000 is outside 1e-12 .. 10000 kPa``), not in Pa."""
    unit = split_unit(key)[1]
    scale = PRESSURE[unit]
    value = doc["max_pressure_Pa"] / scale
    low, high, _ = ARM_BOUNDS["max_pressure_Pa"]
    if not low <= doc["max_pressure_Pa"] <= high:
        raise ArmModelError(
            f"{label}: key '{key}' = {value:.10g} is outside {low / scale:g} .. {high / scale:g} {unit}"
        )
    lowest = min((m for s in sections for m in s.muscles), key=lambda m: m.deadband_Pa)
    if doc["max_pressure_Pa"] <= lowest.deadband_Pa:
        raise ArmModelError(
            f"{label}: key '{key}' = {value:.10g} {unit} is within every muscle's dead band (the lowest, "
            f"{lowest.name or 'a muscle'}'s, ends at {lowest.deadband_Pa / scale:.4g} {unit}): no command could "
            "inflate a muscle"
        )


def spec_from_dict(doc: dict, label: str = "arm spec") -> ArmSpec:
    """The :class:`ArmSpec` of a dict written by :func:`spec_to_dict` (clear errors naming the key)."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ArmModelError(f"{label}: key 'format' must be {FORMAT!r}")
    known = {f.name for f in fields(ArmSpec)}
    doc, pressure_key = _max_pressure_in_Pa(doc, label)
    unknown = sorted(set(doc) - known - {"format"})
    if unknown:
        raise ArmModelError(f"{label}: unknown key(s) {', '.join(unknown)}")
    _json_types({k: doc[k] for k in known - {"sections"} if k in doc}, ArmSpec, label)
    if isinstance(doc.get("name"), str):
        # the name becomes the MJCF's model="..."; a control character or half a surrogate pair
        # there makes the XML ill-formed, so the muscle file's rule for its 'name' applies (one rule)
        try:
            check_text(doc["name"], "name", label)
        except MuscleFileError as err:
            raise ArmModelError(str(err)) from None
    sections = doc.get("sections")
    if not isinstance(sections, list) or not sections:
        raise ArmModelError(f"{label}: key 'sections' must be a non-empty list")
    built = []
    for j, s in enumerate(sections):
        where = f"{label}: sections[{j}]"
        if not isinstance(s, dict) or not isinstance(s.get("muscles"), list):
            raise ArmModelError(f"{where}: needs a 'muscles' list")
        bad = sorted(set(s) - set(_SECTION_KEYS) - {"muscles"})
        if bad:
            raise ArmModelError(f"{where}: unknown key(s) {', '.join(bad)}")
        muscles = []
        for i, m in enumerate(s["muscles"]):
            if not isinstance(m, (str, dict)):  # a list, null, a boolean or a number is none of the three
                raise ArmModelError(
                    f"{where}.muscles[{i}]: must be a preset name, a muscle-file path or a muscle document "
                    f"(a JSON object), got {_shown_value(m)}"
                )
            try:
                muscles.append(
                    load_muscle(m) if isinstance(m, str) else muscle_from_document(m, f"{where}.muscles[{i}]")
                )
            except (MuscleFileError, ValueError, TypeError) as err:
                text = str(err)
                # a muscle document's own error already names this place (said once, not twice)
                named = text if text.startswith(f"{where}.muscles[{i}]") else f"{where}.muscles[{i}]: {text}"
                raise ArmModelError(named) from None
        kw = {k: s[k] for k in _SECTION_KEYS if k in s}
        _json_types(kw, SectionSpec, where)
        if kw.get("angles_deg") is not None:
            kw["angles_deg"] = tuple(kw["angles_deg"])
        try:
            built.append(SectionSpec(muscles=tuple(muscles), **kw))
        except (ValueError, TypeError) as err:
            raise ArmModelError(f"{where}: {err}") from None
    kw = {k: doc[k] for k in known - {"sections"} if k in doc}
    if pressure_key not in (None, "max_pressure_Pa"):
        _check_max_pressure(doc, pressure_key, built, label)
    try:
        with warnings.catch_warnings():
            if pressure_key not in (None, "max_pressure_Pa"):  # its unit was written: not a Pa guess
                warnings.simplefilter("ignore", PressureUnitWarning)
            spec = ArmSpec(sections=tuple(built), **kw)
    except (ValueError, TypeError) as err:
        raise ArmModelError(f"{label}: {err}") from None
    from ..arm.cli import MAX_DEGREES_OF_FREEDOM, degrees_of_freedom

    if degrees_of_freedom(spec) > MAX_DEGREES_OF_FREEDOM:  # as efam arm: a build and replays of hours
        raise ArmModelError(
            f"{label}: {degrees_of_freedom(spec)} degrees of freedom (4 per spacer disk), beyond the "
            f"{MAX_DEGREES_OF_FREEDOM} a diagnosis replays in reasonable time; use fewer 'disks'"
        )
    return spec


def save_spec(path: str | Path, arm: ArmSpec) -> Path:
    """Write an arm spec file (JSON) atomically; a name with a recording's suffix (``.csv``) is
    refused."""
    doc = spec_to_dict(arm)
    check_json_name("save_spec", path)
    return write_json_atomic(path, doc)


def load_spec(path: str | Path) -> ArmSpec:
    """Read an arm spec file (JSON)."""
    from ..musclefile import MuscleFileError, parse_json_text, read_small_file

    try:  # strict JSON as the muscle files (no NaN, no key twice, a BOM allowed), bounded in size
        data, label = read_small_file(path, "an arm spec file")
        doc = parse_json_text(data, label)
    except MuscleFileError as err:
        raise ArmModelError(str(err)) from None
    if not isinstance(doc, dict):
        raise ArmModelError(f"{label}: expected a JSON object at the top level")
    return spec_from_dict(doc, label)


def load_arm_model(path: str | Path) -> mujoco.MjSpec:
    """The arm as an :class:`mujoco.MjSpec` from a spec file (``.json``) or an MJCF (``.xml``).

    The model must have a body ``base``, a sensor ``tip_pos`` and one actuator per muscle whose
    ctrl is the gauge pressure in Pa (what :func:`efam_mujoco.arm.build_spec` makes)."""
    plugin.load()
    path = Path(path)
    if path.suffix.lower() == ".json":
        arm = load_spec(path)
        try:
            spec = build_spec(arm)
        except ValueError as err:  # the builder's own refusal ("arm: timestep_s = 4 ms is unstable"):
            # said with the spec file it came from, which the builder never saw
            text = str(err)
            text = text[len("arm: ") :] if text.startswith("arm: ") else text
            raise ArmModelError(text if text.startswith(f"{path}:") else f"{path}: {text}") from None
    elif path.suffix.lower() not in (".xml", ".mjcf"):
        # MuJoCo's own words for a CSV or a YAML ('could not find decoder for resource') say nothing
        raise ArmModelError(
            f"{path}: an arm model is a spec file (.json, `armdiag.save_spec`) or an MJCF (.xml), "
            f"not a '{path.suffix or 'suffix-less'}' file"
        )
    else:
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except Exception as err:  # MuJoCo's parser names line and column itself
            raise ArmModelError(f"{path}: not a usable MJCF: {err}") from None
    check_arm_model(spec, str(path))
    return spec


def check_arm_model(spec: mujoco.MjSpec, label: str) -> None:
    """Refuse a model the arm diagnosis cannot replay, naming what is missing."""
    names = {b.name for b in spec.bodies}
    if "base" not in names:
        raise ArmModelError(f"{label}: no body named 'base' (the arm's mount)")
    if "tip_pos" not in {s.name for s in spec.sensors}:
        raise ArmModelError(f"{label}: no sensor named 'tip_pos' (framepos of the tip)")
    if not spec.actuators:
        raise ArmModelError(f"{label}: no actuators (one per muscle, ctrl = gauge pressure in Pa)")
    for eq in spec.equalities:
        # a body welded to the mount (the builder's hold_tip, a blocked-force fixture) holds the
        # tip still: its replay cannot follow a recorded tip, and every mismatch would be 'unexplained'
        if eq.type == mujoco.mjtEq.mjEQ_WELD and eq.active and {"base", "world"} & {eq.name1, eq.name2}:
            other = eq.name1 if eq.name2 in ("base", "world") else eq.name2
            raise ArmModelError(
                f"{label}: body '{other}' is welded to '{eq.name2 if other == eq.name1 else eq.name1}'"
                f"{f' (equality {eq.name!r})' if eq.name else ''}: a held tip cannot follow a recording "
                "(hold_tip is for blocked-force checks; set it to false)"
            )


def model_limits(spec: mujoco.MjSpec) -> dict:
    """What a recording is checked against (:func:`.recording.check_against_model`), SI:
    ``max_command_Pa`` per actuator (the top of its control range; inf when unlimited),
    ``base_m`` the base's world position and ``rest_reach_m`` the base-to-tip distance in the
    model's reference pose (the builder's: straight, every muscle at its rest length),
    ``timestep_s``."""
    plugin.load()
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    limited = np.asarray(model.actuator_ctrllimited, bool)
    top = np.where(limited, model.actuator_ctrlrange[:, 1], np.inf)
    base = data.xpos[model.body("base").id].copy()
    tip = np.asarray(data.sensor("tip_pos").data[:3], float)
    return {
        "max_command_Pa": top,
        "base_m": base,
        "rest_reach_m": float(np.linalg.norm(tip - base)),
        "timestep_s": float(model.opt.timestep),
    }
