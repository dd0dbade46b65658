"""Muscle files: the paper's presets and calibrated muscles, as JSON.

A muscle file holds what a user measured or identified, with units in its keys::

    {
      "format": "efam_mujoco.muscle/1",
      "name": "FAM1",
      "geometry":  {"rest_length_m": ..., "rest_diameter_m": ..., "sleeve_length_ref_m": ...},
      "constants": {"theta_rest_deg": ..., "bladder_volume_m3": ...},
      "deadband_kPa": 33.62,
      "tension_only": false,
      "stress": {"default": "exponential_decay", "laws": {"linear": {"E1_Pa": ..., "E2": ...}}}
    }

``geometry`` (paper Table 2) derives the constants through Eqs. 3-8; ``constants`` gives them
directly (rest_length, rest_diameter, theta_rest, bladder_volume) and overrides what geometry
derives, which is how a calibration that re-estimated the braid angle from blocked forces
(Sec. 4.4) is stored. Any key may use another unit of the same quantity (``rest_length_cm``).
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from .files import write_json_atomic
from .muscle import DEFAULT_LOCK_STIFFNESS, Geometry, Muscle, MuscleError
from .stress import StressLaw, StressLawError
from .units import UnitError, read_quantity

FORMAT = "efam_mujoco.muscle/1"
PRESETS = ("fam1", "fam2")

_GEOMETRY_LENGTHS = (
    "rest_length", "rest_diameter", "sleeve_length_ref", "sleeve_diameter_ref", "bladder_length",
    "bladder_inner_diameter", "bladder_outer_diameter", "clamp_length", "clamp_inner_diameter",
    "clamp_outer_diameter", "thread_thickness",
)  # fmt: skip


class MuscleFileError(ValueError):
    """A muscle file that cannot be read; the message names the file and the key."""


def preset_names() -> tuple[str, ...]:
    return PRESETS


def read_document(source: str | Path) -> tuple[dict, str]:
    """The parsed JSON of a preset name or a file path, and a label for messages."""
    key = str(source).lower()
    if key in PRESETS:
        text = resources.files("efam_mujoco.presets").joinpath(f"{key}.json").read_text()
        label = f"preset {key.upper()}"
    else:
        path = Path(source)
        if not path.exists():
            raise MuscleFileError(
                f"'{source}' is neither a preset ({', '.join(p.upper() for p in PRESETS)}) nor a file"
            )
        text = path.read_text()
        label = str(path)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise MuscleFileError(f"{label}: not valid JSON ({err})") from None
    if not isinstance(doc, dict):
        raise MuscleFileError(f"{label}: expected a JSON object at the top level")
    fmt = doc.get("format")
    if fmt != FORMAT:
        raise MuscleFileError(f"{label}: key 'format' must be '{FORMAT}', got {fmt!r}")
    return doc, label


def geometry_from_dict(g: dict, where: str) -> Geometry:
    values = {f"{k}_m": read_quantity(g, k, "length", where) for k in _GEOMETRY_LENGTHS}
    angle = read_quantity(g, "sleeve_angle_ref", "angle", where, default=None)
    if angle is not None:
        values["sleeve_angle_ref_deg"] = angle * 180.0 / 3.141592653589793
    values["fittings"] = int(g.get("fittings", 2))
    return Geometry(**values)


def muscle_from_document(doc: dict, label: str, law: str | None = None) -> Muscle:
    """Build a :class:`Muscle` from a parsed muscle file, with the named (or default) law."""
    try:
        constants: dict[str, float] = {}
        if "geometry" in doc:
            geometry = geometry_from_dict(doc["geometry"], f"{label}: geometry")
            constants = {
                "rest_length_m": geometry.rest_length_m,
                "rest_diameter_m": geometry.rest_diameter_m,
                "theta_rest_deg": geometry.theta_rest_deg,
                "bladder_volume_m3": geometry.bladder_volume_m3,
            }
        given = doc.get("constants", {})
        where = f"{label}: constants"
        for base, quantity, key in (
            ("rest_length", "length", "rest_length_m"),
            ("rest_diameter", "length", "rest_diameter_m"),
            ("bladder_volume", "volume", "bladder_volume_m3"),
        ):
            value = read_quantity(given, base, quantity, where, default=constants.get(key))
            if value is None:
                raise MuscleFileError(f"{where}: missing key '{key}' (or a 'geometry' block)")
            constants[key] = value
        theta = read_quantity(given, "theta_rest", "angle", where, default=None)
        if theta is not None:
            constants["theta_rest_deg"] = theta * 180.0 / 3.141592653589793
        if "theta_rest_deg" not in constants:
            raise MuscleFileError(f"{where}: missing key 'theta_rest_deg' (or a 'geometry' block)")
        deadband = read_quantity(doc, "deadband", "pressure", label)
        stress = stress_from_document(doc, label, law)
        lock = doc.get("lock_stiffness_N_per_m", DEFAULT_LOCK_STIFFNESS)
        if isinstance(lock, bool) or not isinstance(lock, (int, float)):
            raise MuscleFileError(f"{label}: 'lock_stiffness_N_per_m' must be a number, got {lock!r}")
        return Muscle(
            **constants,
            deadband_Pa=deadband,
            stress=stress,
            tension_only=bool(doc.get("tension_only", False)),
            lock_stiffness_N_per_m=float(lock),
            name=str(doc.get("name", label)),
        )
    except (MuscleError, StressLawError, UnitError) as err:
        msg = str(err)
        raise MuscleFileError(msg if msg.startswith(label) else f"{label}: {msg}") from None


def stress_from_document(doc: dict, label: str, law: str | None = None) -> StressLaw:
    block = doc.get("stress")
    if not isinstance(block, dict) or not isinstance(block.get("laws"), dict) or not block["laws"]:
        raise MuscleFileError(f"{label}: missing 'stress' block with a non-empty 'laws' object")
    name = law or block.get("default") or next(iter(block["laws"]))
    if name not in block["laws"]:
        raise MuscleFileError(
            f"{label}: no coefficients for stress law '{name}' (has: {', '.join(block['laws'])})"
        )
    return StressLaw.from_dict(name, block["laws"][name], where=f"{label}: stress law '{name}'")


def load_muscle(source: str | Path, law: str | None = None) -> Muscle:
    """A preset name (``FAM1``, ``fam2``) or a muscle file path -> :class:`Muscle`."""
    doc, label = read_document(source)
    return muscle_from_document(doc, label, law)


def available_laws(source: str | Path) -> tuple[str, ...]:
    doc, label = read_document(source)
    return tuple(doc.get("stress", {}).get("laws", {}))


def muscle_document(muscle: Muscle, laws: dict[str, StressLaw] | None = None, **extra) -> dict:
    """A muscle file (as a dict) holding ``muscle``'s constants and one or more stress laws."""
    laws = dict(laws or {muscle.stress.name: muscle.stress})
    laws.setdefault(muscle.stress.name, muscle.stress)
    doc = {
        "format": FORMAT,
        "name": muscle.name,
        "constants": {
            "rest_length_m": muscle.rest_length_m,
            "rest_diameter_m": muscle.rest_diameter_m,
            "theta_rest_deg": muscle.theta_rest_deg,
            "bladder_volume_m3": muscle.bladder_volume_m3,
        },
        "deadband_kPa": muscle.deadband_Pa / 1e3,
        "tension_only": muscle.tension_only,
        "lock_stiffness_N_per_m": muscle.lock_stiffness_N_per_m,
        "stress": {"default": muscle.stress.name, "laws": {k: v.to_dict() for k, v in laws.items()}},
    }
    doc.update(extra)
    return doc


def save_muscle(path: str | Path, muscle: Muscle, laws: dict[str, StressLaw] | None = None, **extra) -> Path:
    """Write a muscle file atomically (a failed write never leaves a half file)."""
    return write_json_atomic(path, muscle_document(muscle, laws, **extra))
