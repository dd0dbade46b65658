"""Arm recordings: commanded pressures in, tip positions out (CSV with unit-suffixed headers).

One file = one :class:`ArmRecording`::

    # lines starting with '#' are comments
    time_s,p_s1m1_kPa,p_s1m2_kPa,p_s1m3_kPa,tip_x_m,tip_y_m,tip_z_m
    0.00,100,100,100,0.0012,-0.0004,0.2051
    ...

====================  ======================================================================
column                meaning
====================  ======================================================================
``time_<unit>``       sample time (s, ms, min), strictly increasing
``p_<muscle>_<u>``    commanded gauge pressure of muscle ``<muscle>`` (names from the arm
                      model's actuators), any pressure unit (Pa, kPa, MPa, bar, psi); one per
                      muscle, all required
``pm_<muscle>_<u>``   measured pressure at the muscle (optional)
``tip_x_<u>`` ...     tip marker position in the model's world frame (m, cm, mm, in); an
                      empty cell is a marker dropout (kept as NaN, not fitted)
``tip_q{w,x,y,z}``    tip orientation quaternion (optional, unitless)
``marker<k>_x_<u>``   intermediate markers (optional, read and kept)
====================  ======================================================================

The arm is taken to be at rest under the first row's commands at the first time. Bad input
(unknown column, unknown unit, a missing muscle, a non-numeric or non-finite value, a
negative pressure, time not increasing) is an error naming the file, the line and the column.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..files import write_text_atomic
from ..units import UnitError, factor


class ArmRecordingError(ValueError):
    """An arm recording that cannot be read; the message names the file, line and column."""


@dataclass
class ArmRecording:
    """Commands and tip of one arm test, SI. ``tip_m`` rows with a dropout are NaN."""

    time_s: np.ndarray
    muscles: list[str]
    command_Pa: np.ndarray  # (n, muscles)
    tip_m: np.ndarray  # (n, 3), world frame
    measured_Pa: np.ndarray | None = None  # (n, muscles) or None
    extra: dict = field(default_factory=dict)  # orientation / markers, SI, by column name
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.time_s = np.asarray(self.time_s, float)
        self.command_Pa = np.asarray(self.command_Pa, float).reshape(len(self.time_s), -1)
        self.tip_m = np.asarray(self.tip_m, float).reshape(len(self.time_s), 3)
        if self.command_Pa.shape[1] != len(self.muscles):
            raise ValueError("command_Pa needs one column per muscle")

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def duration_s(self) -> float:
        """Duration of the recording (s), first to last sample."""
        return float(self.time_s[-1] - self.time_s[0])

    @property
    def valid(self) -> np.ndarray:
        """Rows where the tip marker was seen."""
        return np.all(np.isfinite(self.tip_m), axis=1)


_TIP_AXES = ("x", "y", "z")


def _classify(name: str, muscles: list[str], label: str, line: int, column: int):
    """(role, key, factor to SI) of one header cell."""
    where = f"{label}: line {line}, column {column} ('{name}')"

    def unit_of(base, quantity):
        unit = name[len(base) + 1 :]
        if not unit:
            raise ArmRecordingError(
                f"{where}: no unit; write e.g. '{base}_{ {'pressure': 'kPa'}.get(quantity, 'm') }'"
            )
        try:
            return factor(unit, quantity, where)
        except UnitError as err:
            raise ArmRecordingError(str(err)) from None

    if name.startswith("time"):
        return "time", None, unit_of("time", "time")
    for prefix, role in (("pm_", "measured"), ("p_", "command")):
        if name.startswith(prefix):
            for m in sorted(muscles, key=len, reverse=True):
                if name.startswith(f"{prefix}{m}_"):
                    return role, m, unit_of(f"{prefix}{m}", "pressure")
            raise ArmRecordingError(
                f"{where}: no muscle of that name in the arm model (muscles: {', '.join(muscles)})"
            )
    for axis in _TIP_AXES:
        if name.startswith(f"tip_{axis}_") or name == f"tip_{axis}":
            return "tip", axis, unit_of(f"tip_{axis}", "length")
    if name in ("tip_qw", "tip_qx", "tip_qy", "tip_qz"):
        return "extra", name, 1.0
    if name.startswith("marker"):
        base, _, unit = name.rpartition("_")
        try:
            return "extra", base + "_m", factor(unit, "length", where)
        except UnitError as err:
            raise ArmRecordingError(str(err)) from None
    raise ArmRecordingError(
        f"{where}: unknown column (accepted: time_<unit>, p_<muscle>_<unit>, pm_<muscle>_<unit>, "
        "tip_x_<unit>, tip_y_<unit>, tip_z_<unit>, tip_q{w,x,y,z}, marker<k>_{x,y,z}_<unit>)"
    )


def read_csv(path: str | os.PathLike, muscles: list[str]) -> ArmRecording:
    """Read an arm recording (format in the module docstring) for an arm with ``muscles``."""
    path = Path(path)
    label = str(path)
    try:
        with path.open(newline="") as handle:
            rows = [(n, r) for n, r in enumerate(csv.reader(handle), 1) if r and any(c.strip() for c in r)]
    except OSError as err:
        raise ArmRecordingError(f"{label}: cannot open ({err.strerror})") from None
    except (UnicodeDecodeError, csv.Error) as err:
        raise ArmRecordingError(f"{label}: not a text CSV file ({err})") from None
    rows = [(n, r) for n, r in rows if not r[0].lstrip().startswith("#")]
    if not rows:
        raise ArmRecordingError(f"{label}: no header line")
    head_line, header = rows[0]
    roles = []
    seen = {}
    for c, raw in enumerate(header, 1):
        name = raw.strip()
        if not name:
            raise ArmRecordingError(f"{label}: line {head_line}, column {c}: empty header")
        role = _classify(name, muscles, label, head_line, c)
        key = role[:2]
        if key in seen:
            raise ArmRecordingError(
                f"{label}: line {head_line}, columns {seen[key]} and {c} ('{name}') give the same quantity"
            )
        seen[key] = c
        roles.append(role)
    missing = [f"p_{m}_kPa" for m in muscles if ("command", m) not in seen]
    missing += [f"tip_{a}_m" for a in _TIP_AXES if ("tip", a) not in seen]
    if ("time", None) not in seen:
        missing.insert(0, "time_s")
    if missing:
        raise ArmRecordingError(f"{label}: line {head_line}: missing column(s) {', '.join(missing)}")
    n = len(rows) - 1
    if n < 2:
        raise ArmRecordingError(f"{label}: fewer than 2 data rows")
    values = np.full((n, len(header)), np.nan)
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ArmRecordingError(f"{label}: line {line}: {len(row)} fields, the header has {len(header)}")
        for c, (cell, (role, _key, _)) in enumerate(zip(row, roles)):
            cell = cell.strip()
            where = f"{label}: line {line}, column {c + 1} ('{header[c].strip()}')"
            if not cell:
                if role in ("tip", "extra"):
                    continue  # a marker dropout
                raise ArmRecordingError(f"{where}: empty value")
            try:
                v = float(cell)
            except ValueError:
                raise ArmRecordingError(f"{where}: not a number: {cell!r}") from None
            if not math.isfinite(v):
                raise ArmRecordingError(f"{where}: not finite: {cell!r}")
            if role in ("command", "measured") and v < 0:
                raise ArmRecordingError(f"{where}: negative gauge pressure {v:g} (vacuum is not supported)")
            values[r, c] = v
    col = {role[:2]: i for i, role in enumerate(roles)}
    scale = np.array([role[2] for role in roles])
    values = values * scale
    t = values[:, col["time", None]]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        line = rows[1 + bad[0] + 1][0]
        raise ArmRecordingError(
            f"{label}: line {line}, column {col['time', None] + 1} ('{header[col['time', None]].strip()}'): "
            "time not increasing"
        )
    commands = np.column_stack([values[:, col["command", m]] for m in muscles])
    measured = None
    if all(("measured", m) in col for m in muscles):
        measured = np.column_stack([values[:, col["measured", m]] for m in muscles])
    tip = np.column_stack([values[:, col["tip", a]] for a in _TIP_AXES])
    tip[~np.all(np.isfinite(tip), axis=1)] = np.nan  # a partial marker row is a dropout
    if np.all(np.isnan(tip[:, 0])):
        raise ArmRecordingError(f"{label}: no row has a tip position")
    extra = {key: values[:, i] for (role, key), i in col.items() if role == "extra"}
    meta = {
        "source": label,
        "columns": [h.strip() for h in header],
        "dropouts": int(np.isnan(tip[:, 0]).sum()),
    }
    return ArmRecording(t, list(muscles), commands, tip, measured, extra, meta)


def write_csv(path: str | os.PathLike, rec: ArmRecording, digits: int = 6) -> Path:
    """Write ``rec`` in the CSV format of :func:`read_csv` (kPa, m; dropouts as empty cells)."""
    head = ["time_s"] + [f"p_{m}_kPa" for m in rec.muscles]
    cols = [rec.time_s] + [rec.command_Pa[:, i] / 1e3 for i in range(len(rec.muscles))]
    if rec.measured_Pa is not None:
        head += [f"pm_{m}_kPa" for m in rec.muscles]
        cols += [rec.measured_Pa[:, i] / 1e3 for i in range(len(rec.muscles))]
    head += ["tip_x_m", "tip_y_m", "tip_z_m"]
    cols += [rec.tip_m[:, 0], rec.tip_m[:, 1], rec.tip_m[:, 2]]
    lines = [",".join(head)]
    for row in np.column_stack(cols):
        lines.append(",".join("" if not np.isfinite(v) else f"{v:.{digits}g}" for v in row))
    return write_text_atomic(path, "\n".join(lines) + "\n")
