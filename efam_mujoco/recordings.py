"""Bench recordings of a muscle: time, length, pressure and force, SI inside.

A :class:`Recording` is what every consumer (calibration, diagnosis, the rig replay) takes. CSV
reading and writing with unit-suffixed headers lives here too (see ``read_csv``).

Force sign: ``force_N`` is positive when the muscle pushes its ends apart (the package's MuJoCo
convention); a ``tension_N`` column (positive = pulls, the paper's Eq. 2 sign) is negated on read.

CSV format (one file = one :class:`Recording`; a file may hold several pressures and both loading
and unloading)::

    # lines starting with '#' are comments
    time_s,length_m,pressure_kPa,force_N
    0.000,0.17018,103.4,40.1
    ...

Every header is ``<quantity>_<unit>`` (units from :mod:`efam_mujoco.units`, any unit of the right
quantity): exactly one of each role below, nothing else.

===========  =============================================================================
role         accepted headers
===========  =============================================================================
time         ``time_<unit>`` (s, ms, min); strictly increasing
length       ``length_<unit>`` (the muscle's length) or ``displacement_<unit>`` (the change
             from the RESTING length, positive = longer; ``read_csv`` then needs
             ``rest_length_m``, which ``efam calibrate`` takes from ``--muscle``)
pressure     ``pressure_<unit>`` (Pa, kPa, MPa, bar, psi), gauge pressure
force        ``force_<unit>`` (positive = pushes the ends apart) or ``tension_<unit>``
             (positive = pulls; stored negated)
===========  =============================================================================

Bad rows (a wrong number of fields, an empty or non-numeric value, NaN or infinity, a time equal
to or before the previous row's) are an error naming the file, the line and the column by default
(``on_bad_rows="error"``). With ``on_bad_rows="drop"`` they are dropped instead and listed in
``recording.meta["dropped_rows"]`` (line, column, reason); :func:`drop_report` words that list for
the user. Input files are only ever read.
"""

from __future__ import annotations

import csv
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .units import QUANTITIES, UnitError, factor, split_unit


@dataclass
class Recording:
    """One bench test. Arrays share one length; ``meta`` keeps provenance (file, rest length...)."""

    time_s: np.ndarray
    length_m: np.ndarray
    pressure_Pa: np.ndarray
    force_N: np.ndarray  # positive = pushes the ends apart
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("time_s", "length_m", "pressure_Pa", "force_N"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        n = {len(self.time_s), len(self.length_m), len(self.pressure_Pa), len(self.force_N)}
        if len(n) != 1:
            raise ValueError("recording arrays must all have the same length")

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def tension_N(self) -> np.ndarray:
        """Paper sign (Eq. 2): positive when the muscle pulls."""
        return -self.force_N

    def subset(self, mask, **meta) -> Recording:
        """The samples where ``mask`` holds (a boolean or index array), same meta plus ``meta``."""
        return Recording(
            self.time_s[mask], self.length_m[mask], self.pressure_Pa[mask], self.force_N[mask],
            {**self.meta, **meta},
        )  # fmt: skip


class RecordingError(ValueError):
    """A recording file that cannot be read; the message names the file, line and column."""


# role -> {header base: (quantity, sign)}
_ROLES = {
    "time": {"time": ("time", 1.0)},
    "length": {"length": ("length", 1.0), "displacement": ("length", 1.0)},
    "pressure": {"pressure": ("pressure", 1.0)},
    "force": {"force": ("force", 1.0), "tension": ("force", -1.0)},
}
_BASE_ROLE = {base: role for role, bases in _ROLES.items() for base in bases}
_ACCEPTED = "time_<unit>, length_<unit> | displacement_<unit>, pressure_<unit>, force_<unit> | tension_<unit>"
BAD_ROW_POLICIES = ("error", "drop")


def _columns(header: list[str], label: str, line: int) -> dict[str, tuple[int, str, str, float]]:
    """Map each role to (column index, header, base, factor to SI with sign)."""
    found: dict[str, tuple[int, str, str, float]] = {}
    for index, raw in enumerate(header):
        name = raw.strip()
        if not name:
            raise RecordingError(
                f"{label}: line {line}, column {index + 1}: empty header (expected {_ACCEPTED})"
            )
        base, unit = split_unit(name)
        if name in _BASE_ROLE:
            raise RecordingError(
                f"{label}: line {line}, column '{name}' has no unit; write e.g. "
                f"'{name}_{'kPa' if name == 'pressure' else next(iter(_unit_table(name)))}'"
            )
        if base not in _BASE_ROLE:
            raise RecordingError(f"{label}: line {line}, unknown column '{name}' (accepted: {_ACCEPTED})")
        role = _BASE_ROLE[base]
        quantity, sign = _ROLES[role][base]
        try:
            scale = factor(unit, quantity, f"{label}: line {line}, column '{name}'")
        except UnitError as err:
            raise RecordingError(str(err)) from None
        if role in found:
            raise RecordingError(
                f"{label}: line {line}, columns '{found[role][1]}' and '{name}' both give the {role}"
            )
        found[role] = (index, name, base, sign * scale)
    for role in _ROLES:
        if role not in found:
            options = " or ".join(f"'{b}_<unit>'" for b in _ROLES[role])
            raise RecordingError(f"{label}: line {line}, missing a {role} column ({options})")
    return found


def _unit_table(base: str) -> dict:
    return QUANTITIES[_ROLES[_BASE_ROLE[base]][base][0]]


def read_csv(
    path: str | os.PathLike,
    *,
    rest_length_m: float | None = None,
    on_bad_rows: str = "error",
) -> Recording:
    """Read one recording CSV (format in the module docstring) into a :class:`Recording` (SI).

    ``rest_length_m`` is required when the file gives ``displacement_<unit>`` instead of a length
    (the displacement is measured from the resting length); it is stored in ``meta`` either way.
    ``on_bad_rows``: ``"error"`` (default) raises on the first bad row; ``"drop"`` drops bad rows
    and lists them in ``meta["dropped_rows"]``.
    """
    if on_bad_rows not in BAD_ROW_POLICIES:
        raise ValueError(f"on_bad_rows must be one of {BAD_ROW_POLICIES}, got {on_bad_rows!r}")
    path = Path(path)
    label = str(path)
    try:
        handle = path.open(newline="")
    except OSError as err:
        raise RecordingError(f"{label}: cannot open ({err.strerror})") from None
    with handle:
        lines = [(n, row) for n, row in enumerate(csv.reader(handle), start=1) if not _skip(row)]
    if not lines:
        raise RecordingError(f"{label}: no header line (expected {_ACCEPTED})")
    header_line, header = lines[0]
    columns = _columns(header, label, header_line)
    order = ("time", "length", "pressure", "force")
    values: list[list[float]] = []
    dropped: list[dict] = []
    last_time = -math.inf
    for line, row in lines[1:]:
        parsed, problem = _parse_row(row, header, columns, order)
        if problem is None and parsed[0] <= last_time:
            what = "duplicate time" if parsed[0] == last_time else "time goes backwards (unsorted rows)"
            problem = (columns["time"][1], f"{what}: {parsed[0]:g} s after {last_time:g} s")
        if problem is not None:
            column, reason = problem
            if on_bad_rows == "error":
                where = f"line {line}" + (f", column '{column}'" if column else "")
                hint = " (read with on_bad_rows='drop' to drop such rows)"
                raise RecordingError(f"{label}: {where}: {reason}{hint}")
            dropped.append({"line": line, "column": column, "reason": reason})
            continue
        last_time = parsed[0]
        values.append(parsed)
    if len(values) < 2:
        raise RecordingError(f"{label}: fewer than 2 usable data rows ({len(dropped)} dropped)")
    data = np.array(values)
    length = data[:, 1]
    rest = None if rest_length_m is None else float(rest_length_m)
    if rest is not None and not (math.isfinite(rest) and rest > 0):
        raise RecordingError(f"{label}: rest_length_m must be a positive length, got {rest_length_m!r}")
    length_column = columns["length"][1]
    if columns["length"][2] == "displacement":
        if rest is None:
            raise RecordingError(
                f"{label}: column '{length_column}' is the change from the resting length; give the "
                f"resting length (rest_length_m=..., or --muscle / --rest-length-mm on the command line)"
            )
        length = rest + length
    if np.any(length <= 0):
        line = lines[1:][int(np.argmax(length <= 0))][0]
        raise RecordingError(f"{label}: column '{length_column}': a length <= 0 m (first near line {line})")
    meta = {
        "source": label,
        "columns": [c.strip() for c in header],
        "rest_length_m": rest,
        "dropped_rows": dropped,
    }
    return Recording(data[:, 0], length, data[:, 2], data[:, 3], meta)


def _skip(row: list[str]) -> bool:
    return not row or all(not cell.strip() for cell in row) or row[0].lstrip().startswith("#")


def _parse_row(row, header, columns, order):
    """The row's values in SI (role order) and None, or None and (column, problem)."""
    if len(row) != len(header):
        return None, ("", f"{len(row)} fields, the header has {len(header)}")
    out = []
    for role in order:
        index, name, _, scale = columns[role]
        text = row[index].strip()
        if not text:
            return None, (name, "empty value")
        try:
            value = float(text)
        except ValueError:
            return None, (name, f"not a number: {text!r}")
        if not math.isfinite(value):
            return None, (name, f"not a finite number: {text!r}")
        out.append(value * scale)
    return out, None


def drop_report(recording: Recording, limit: int = 5) -> str:
    """One line telling the user which rows ``on_bad_rows='drop'`` dropped ('' when none)."""
    dropped = recording.meta.get("dropped_rows") or []
    if not dropped:
        return ""
    shown = "; ".join(
        f"line {d['line']}" + (f" ({d['column']}: {d['reason']})" if d["column"] else f" ({d['reason']})")
        for d in dropped[:limit]
    )
    more = f"; and {len(dropped) - limit} more" if len(dropped) > limit else ""
    return f"{recording.meta.get('source', 'recording')}: dropped {len(dropped)} bad row(s): {shown}{more}"


def read_recordings(
    paths, *, rest_length_m: float | None = None, on_bad_rows: str = "error", warn=None
) -> list[Recording]:
    """Read several CSV files (see :func:`read_csv`); with ``on_bad_rows="drop"`` each file's
    dropped rows are told to ``warn`` (a callable taking one line; default: standard error)."""
    warn = warn or (lambda line: print(line, file=sys.stderr))
    recordings = []
    for path in paths:
        recording = read_csv(path, rest_length_m=rest_length_m, on_bad_rows=on_bad_rows)
        note = drop_report(recording)
        if note:
            warn(note)
        recordings.append(recording)
    return recordings


def write_csv(path: str | os.PathLike, recording: Recording, *, pressure_unit: str = "kPa") -> Path:
    """Write ``time_s,length_m,pressure_<unit>,force_N`` atomically (tmp file + rename).

    Refuses to overwrite the file the recording was read from (input files are never modified).
    """
    path = Path(path)
    source = recording.meta.get("source")
    if source and Path(source).exists() and path.exists() and path.resolve() == Path(source).resolve():
        raise RecordingError(f"{path}: refusing to overwrite the recording's own input file")
    scale = factor(pressure_unit, "pressure", "write_csv")
    tmp = path.with_name(path.name + ".tmp")
    rows = np.column_stack(
        [recording.time_s, recording.length_m, recording.pressure_Pa / scale, recording.force_N]
    )
    with tmp.open("w", newline="") as handle:
        handle.write(f"time_s,length_m,pressure_{pressure_unit},force_N\n")
        for t, length, p, f in rows:
            handle.write(f"{t:.9g},{length:.9g},{p:.9g},{f:.9g}\n")
    tmp.replace(path)
    return path
