"""Arm recordings: commanded pressures in, tip positions out (CSV with unit-suffixed headers).

One file = one :class:`ArmRecording`::

    # lines starting with '#' are comments (those among the data rows are reported)
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

The quantity (``time``, ``p``, ``pm``, ``tip``, ``marker``) is read in any case, as loggers write
it (``Time_s``, ``TIP_X_m``); the muscle's name and the unit exactly as written.

The arm is taken to be at rest under the first row's commands at the first time. The file is
read by the muscle recordings' rules (:mod:`efam_mujoco.recordings`: UTF-8 with or without a
byte-order mark, commas, plain ASCII decimals). Bad input (unknown column, unknown unit, a
missing muscle, a non-numeric, non-finite or unphysically large value, a negative pressure,
time not increasing, a time base no recorder makes, commands that are 0 everywhere) is an error
naming the file, the line and the column. Against the arm model (:func:`check_against_model`):
commands far above the model's highest pressure, tip positions farther from the base than the
arm can reach and tips that never leave the base are errors too (a unit mix-up, with the unit
that fits); commands a little above that pressure are replayed at it, with a warning that
counts them.
"""

from __future__ import annotations

import math
import os
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..files import write_text_atomic
from ..recordings import (
    CELL_SPACE,
    MAX_INTERVAL_S,
    MIN_INTERVAL_S,
    RecordingError,
    comment_meta,
    csv_rows,
    decimal_cell,
    open_recording,
    refuse_other_separators,
    shown_path,
)
from ..units import LENGTH, PRESSURE, TIME, UnitError, factor, split_unit, unit_that_fits

#: The columns an arm recording takes, for messages.
_ACCEPTED = "time_<unit>, p_<muscle>_<unit> per muscle, tip_x_<unit>, tip_y_<unit>, tip_z_<unit> (optional pm_, tip_q, marker<k>_)"


class ArmRecordingError(ValueError):
    """An arm recording that cannot be read; the message names the file, line and column."""


class ArmRecordingWarning(UserWarning):
    """Something in an arm recording that the replay changes (commands above the model's
    highest pressure, replayed at it); the message names the column and counts the samples."""


#: Longest recording read (s): one arm test is seconds to minutes (the benchmark's are 15 s, the
#: diagnosis searches the first 10 s of training time), and four hours is more than a lab session
#: of one arm with one tip marker. A test of 15 s or more written in ms under a 's' header reads
#: as more than 4 h; shorter mix-ups are caught by the replay bound of the diagnosis
#: (:data:`efam_mujoco.armdiag.diagnosis.MAX_REPLAY_STEPS`).
MAX_DURATION_S = 4 * 3600.0
#: ... and at least this long: an arm's tip takes tenths of a second to follow a command (its
#: regulators' lag, its first bending mode), so a shorter test shows nothing of the arm, and
#: seconds written under 'time_ms' make a 6 s test read 6 ms
MIN_DURATION_S = 0.5
#: Commands up to this multiple of the model's highest pressure (the actuators' control range, the
#: arm's rated pressure) are replayed at that pressure with a warning (a regulator overshooting
#: the rating); beyond it a value cannot be a command for this arm (Pa under a kPa header, psi
#: under kPa) and the recording is refused.
COMMAND_REFUSE_FACTOR = 2.0
#: A tip farther from the base than this multiple of the arm's rest length (straight, at zero
#: pressure) cannot be physical: an EFAM extends to at most about 4.5 x its resting length
#: (FAM1: 0.771 m / 0.170 m, braid-limited), so 10 x leaves a wide margin and still catches a
#: tip in mm (1000 x) or cm (100 x) under an 'm' header.
REACH_FACTOR = 10.0
#: A tip whose median distance from the base is under this share of the arm's rest length never
#: left the base: an EFAM arm only lengthens, and bent into a half circle its tip is still 2/pi of
#: its length away, so a recording whose tip stays within 0.3 of it holds another unit (metres
#: under a 'mm' or 'cm' header, centimetres under 'mm': 0.1 x) or another marker.
MIN_REACH_SHARE = 0.3
#: Commands that never reach this share of the model's highest pressure drive nothing (below
#: any EFAM's dead band): MPa or bar written under a 'kPa' header (0.1-1 % of it).
MIN_COMMAND_SHARE = 0.05
#: One command column under :data:`MIN_COMMAND_SHARE` while others reach it is refused as written
#: in another unit when that unit puts its largest command within this factor of the others':
#: bar and MPa under 'kPa' are 100 x and 1000 x off, a muscle merely driven less than the others
#: rarely within 3 x of them once scaled by such a factor.
COLUMN_UNIT_FACTOR = 3.0
#: A command column whose sample-to-sample changes are at least this share of what white noise of
#: its spread makes (RMS of the differences over sqrt(2) x its standard deviation: 1 for white
#: noise, near 0 for ramps, steps and sines sampled at 30-200 Hz) is a regulator's jitter about
#: an idle muscle's zero, not commands written in another unit
JITTER_SHARE = 0.5
#: A tip whose every coordinate spans less than this (m) while the commands change never moved:
#: a motion tracker's noise alone spans tens of micrometres
FROZEN_TIP_M = 1e-6
#: The sample interval a unit hint aims for: arm tip trackers sample at 30-200 Hz.
TYPICAL_INTERVAL_S = 0.01


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
                f"{where}: no unit; write e.g. '{base}_{ {'pressure': 'kPa', 'time': 's'}.get(quantity, 'm') }'"
            )
        try:
            return factor(unit, quantity, where)
        except UnitError as err:
            raise ArmRecordingError(str(err)) from None

    # the quantity is read in any case, as loggers write it (Time_s, P_s1m1_kPa, TIP_X_m); the
    # muscle's name and the unit exactly as written (a muscle 'A' is not 'a', mPa is not MPa)
    low = name.lower()
    if low == "time" or low.startswith("time_"):  # 'timestamp_s' is no time unit 'tamp_s'
        return "time", None, unit_of("time", "time")
    for prefix, role in (("pm_", "measured"), ("p_", "command")):
        if low.startswith(prefix):
            for m in sorted(muscles, key=len, reverse=True):
                # 'p_s1m1' (no unit) is the muscle s1m1 without its unit, not an unknown muscle
                if name[len(prefix) :] == m or name[len(prefix) :].startswith(f"{m}_"):
                    return role, m, unit_of(f"{prefix}{m}", "pressure")
            raise ArmRecordingError(
                f"{where}: no muscle of that name in the arm model (muscles: {', '.join(muscles)})"
            )
    for axis in _TIP_AXES:
        if low.startswith(f"tip_{axis}_") or low == f"tip_{axis}":
            return "tip", axis, unit_of(f"tip_{axis}", "length")
    if low in ("tip_qw", "tip_qx", "tip_qy", "tip_qz"):
        return "extra", low, 1.0
    if low.startswith("marker"):
        base, _, unit = name.rpartition("_")
        try:
            return "extra", base + "_m", factor(unit, "length", where)
        except UnitError as err:
            raise ArmRecordingError(str(err)) from None
    raise ArmRecordingError(
        f"{where}: unknown column (accepted: time_<unit>, p_<muscle>_<unit>, pm_<muscle>_<unit>, "
        "tip_x_<unit>, tip_y_<unit>, tip_z_<unit>, tip_q{w,x,y,z}, marker<k>_{x,y,z}_<unit>)"
    )


def _header_roles(header: list[str], muscles: list[str], label: str, head_line: int) -> list:
    """(role, key, factor to SI) of each header cell; an error names the line and the column of an
    empty, unknown or repeated column, or the columns that are missing."""
    roles = []
    seen = {}
    for c, raw in enumerate(header, 1):
        name = raw.strip()
        if not name:
            raise ArmRecordingError(f"{label}: line {head_line}, column {c}: empty header")
        role = _classify(name, muscles, label, head_line, c)
        key = role[:2]
        if key in seen:
            first = seen[key]
            raise ArmRecordingError(
                f"{label}: line {head_line}, columns {first} ('{header[first - 1].strip()}') and {c} ('{name}') "
                "give the same quantity; keep one"
            )
        seen[key] = c
        roles.append(role)
    missing = [f"p_{m}_kPa" for m in muscles if ("command", m) not in seen]
    missing += [f"tip_{a}_m" for a in _TIP_AXES if ("tip", a) not in seen]
    if ("time", None) not in seen:
        missing.insert(0, "time_s")
    if missing:
        raise ArmRecordingError(f"{label}: line {head_line}: missing column(s) {', '.join(missing)}")
    return roles


def _parse_arm_row(row: list[str], line: int, last: int, header: list[str], roles: list, label: str) -> list:
    """One data row's values in SI, column by column (NaN for an empty tip or extra cell: a marker
    dropout); an error names the file, the line and the column."""
    # an unclosed quote swallows the lines after it: said with the row it spoiled
    runs_on = f" (a quote on line {line} runs on to line {last})" if last > line else ""
    if len(row) != len(header):
        raise ArmRecordingError(
            f"{label}: line {line}: {len(row)} fields, the header has {len(header)}{runs_on}"
        )
    out = []
    for c, (cell, (role, _key, scale)) in enumerate(zip(row, roles)):
        cell = cell.strip(CELL_SPACE)  # ASCII only: a no-break space is refused, never stripped
        where = f"{label}: line {line}, column {c + 1} ('{header[c].strip()}')"
        if not cell:
            if role in ("tip", "extra"):
                out.append(math.nan)  # a marker dropout
                continue
            raise ArmRecordingError(f"{where}: empty value{runs_on}")
        v, problem = decimal_cell(cell, scale)  # in SI
        if v is None:
            raise ArmRecordingError(f"{where}: {problem}{runs_on}")
        if role in ("command", "measured") and v < 0:
            raise ArmRecordingError(
                f"{where}: negative gauge pressure {float(cell):g} (vacuum is not supported)"
            )
        out.append(v)
    return out


def read_csv(path: str | os.PathLike, muscles: list[str]) -> ArmRecording:
    """Read an arm recording (format in the module docstring) for an arm with ``muscles``.

    The file is read by the muscle recordings' rules (``efam_mujoco.recordings``): UTF-8 with or
    without a byte-order mark, no bare-CR line endings, '#' comment rows, commas only, plain
    ASCII decimals (no ``1_000``, no decimal comma), magnitudes up to 1e9 in SI."""
    path = Path(path)
    label = shown_path(path)  # for messages; meta keeps the real name
    header: list[str] | None = None
    head_line = 0
    roles: list = []
    # streamed into one array('d') per column and the file line of each sample (about 8 bytes a
    # column a row): a list of rows of strings took ~800 bytes a row, and a multi-GB log ran the
    # machine out of memory before its duration was ever checked
    columns: list[array] = []
    lines = array("q")
    n = 0
    pending = None  # the first data row's problem: said once a second row shows there is a recording
    comments = array("q")  # the line of every '#' row, before the header and among the data
    try:
        with open_recording(path, label) as handle:
            for line, last, row in csv_rows(handle, label, comments):
                if header is None:
                    refuse_other_separators(row, label, line, _ACCEPTED)
                    header, head_line = row, line
                    roles = _header_roles(header, muscles, label, head_line)
                    columns = [array("d") for _ in header]
                    continue
                if pending is not None:
                    raise pending
                n += 1
                try:
                    parsed = _parse_arm_row(row, line, last, header, roles, label)
                except ArmRecordingError as err:
                    if n > 1:
                        raise
                    pending = err  # one data row only is "fewer than 2 data rows", as before
                    continue
                for store, v in zip(columns, parsed):
                    store.append(v)
                lines.append(line)
    except RecordingError as err:
        raise ArmRecordingError(str(err)) from None
    if header is None:
        raise ArmRecordingError(f"{label}: no header line")
    if n < 2:
        raise ArmRecordingError(f"{label}: fewer than 2 data rows")
    # views of the arrays, not copies: the recording's columns are only read from here on
    values = [np.frombuffer(c, dtype=float) for c in columns]
    line_of = np.frombuffer(lines, dtype=np.int64)
    col = {role[:2]: i for i, role in enumerate(roles)}
    t = values[col["time", None]]
    time_name = header[col["time", None]].strip()
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        line = int(line_of[bad[0] + 1])
        raise ArmRecordingError(
            f"{label}: line {line}, column {col['time', None] + 1} ('{time_name}'): time not increasing"
        )
    _check_time_base(t, f"{label}: column {col['time', None] + 1} ('{time_name}')", time_name)
    commands = np.column_stack([values[col["command", m]] for m in muscles])
    if not np.any(commands):  # an unplugged logger channel or a wrong file: the arm only sags
        names = ", ".join(header[col["command", m]].strip() for m in muscles)
        raise ArmRecordingError(
            f"{label}: every command column ({names}) is 0 in every row: nothing drives the arm, so "
            "there is nothing to diagnose"
        )
    measured = None
    if all(("measured", m) in col for m in muscles):
        measured = np.column_stack([values[col["measured", m]] for m in muscles])
    tip = np.column_stack([values[col["tip", a]] for a in _TIP_AXES])
    tip[~np.all(np.isfinite(tip), axis=1)] = np.nan  # a partial marker row is a dropout
    if np.all(np.isnan(tip[:, 0])):
        raise ArmRecordingError(f"{label}: no row has a tip position")
    extra = {key: values[i] for (role, key), i in col.items() if role == "extra"}
    meta = {
        "source": str(path),
        "columns": [h.strip() for h in header],
        "dropouts": int(np.isnan(tip[:, 0]).sum()),
        "lines": line_of,  # the file line of each sample
        "time_column": time_name,
        "command_columns": [header[col["command", m]].strip() for m in muscles],
        "tip_columns": [header[col["tip", a]].strip() for a in _TIP_AXES],
        **comment_meta(comments, head_line),  # the diagnosis tells the user of those among the data
    }
    return ArmRecording(t, list(muscles), commands, tip, measured, extra, meta)


def unit_hint(column: str, value_si: float, target_si: float, table: dict) -> str:
    """``"; the numbers fit 'time_ms'"`` (:func:`efam_mujoco.units.unit_that_fits`), or empty."""
    fits = unit_that_fits(value_si, target_si, column, table)
    return f"; the numbers fit '{fits}'" if fits else ""


def _check_time_base(t: np.ndarray, where: str, column: str) -> None:
    """Refuse a time column no recorder writes in that unit (:data:`MIN_INTERVAL_S` ..
    :data:`MAX_INTERVAL_S` between samples, at most :data:`MAX_DURATION_S` long)."""
    interval = float(np.median(np.diff(t)))
    if not MIN_INTERVAL_S <= interval <= MAX_INTERVAL_S:
        raise ArmRecordingError(
            f"{where}: the median sample interval is {interval:.4g} s; a recorder samples every "
            f"{MIN_INTERVAL_S:g} .. {MAX_INTERVAL_S:g} s (a time unit mix-up?)"
            + unit_hint(column, interval, TYPICAL_INTERVAL_S, TIME)
        )
    duration = float(t[-1] - t[0])
    if duration > MAX_DURATION_S:
        raise ArmRecordingError(
            f"{where}: the recording spans {duration:.4g} s ({duration / 3600:.3g} h), longer than the "
            f"{MAX_DURATION_S / 3600:g} h an arm recording can be (a time unit mix-up?)"
            + unit_hint(column, interval, TYPICAL_INTERVAL_S, TIME)
        )


def _line(rec: ArmRecording, row: int) -> str:
    lines = rec.meta.get("lines")
    return f"line {lines[row]}" if lines is not None and len(lines) == len(rec) else f"sample {row + 1}"


def units_putting(number: float, low_Pa: float, high_Pa: float) -> list[str]:
    """The pressure units under which a command column's ``number`` (as written) would lie in
    ``low_Pa`` .. ``high_Pa``: the units a unit hint or a re-read may offer."""
    return [u for u in PRESSURE if low_Pa <= number * PRESSURE[u] <= high_Pa]


def _jitter_share(p: np.ndarray) -> float:
    """How much of a column's variation changes from one sample to the next: the RMS of its
    first differences over what white noise of the same standard deviation gives (sqrt(2) x
    it). About 1 for noise, near 0 for a commanded signal (ramps, steps, sines); NaN ignored."""
    p = np.asarray(p, float)
    p = p[np.isfinite(p)]
    spread = float(np.std(p)) if len(p) > 2 else 0.0
    if spread == 0.0:
        return 0.0
    return float(np.sqrt(np.mean(np.diff(p) ** 2)) / (math.sqrt(2.0) * spread))


def _check_small_columns(rec: ArmRecording, max_Pa: np.ndarray, columns: list[str], src: str) -> None:
    """Refuse one muscle's command column written in a larger unit than its header's (bar or MPa
    under 'kPa') while the other columns are right: the whole-recording test of
    :data:`MIN_COMMAND_SHARE` only sees the largest command of all muscles.

    A column is refused only when it looks like a unit mix-up, not a muscle little used: its
    commands change (a column of 0 is an idle muscle, a constant one a held bias pressure), as a
    signal does, not from sample to sample as noise does (:data:`JITTER_SHARE`: an idle muscle's
    regulator jitters by a few kPa about zero, which 'bar' would put among the others), never
    reach :data:`MIN_COMMAND_SHARE` of its model's highest pressure, and another pressure unit puts
    its largest value within :data:`COLUMN_UNIT_FACTOR` of what the columns that do reach it
    command (their median largest command)."""
    tops = np.asarray(max_Pa, float)
    highest = np.nanmax(rec.command_Pa, axis=0) if len(rec) else np.zeros(len(rec.muscles))
    reaching = [
        float(highest[j]) for j in range(len(rec.muscles)) if highest[j] >= MIN_COMMAND_SHARE * tops[j]
    ]  # an unlimited actuator (top inf) never counts as reaching: nothing to compare it with
    if not reaching:  # the whole-recording test's case (or no finite range): said there
        return
    usual = float(np.median(reaching))
    for i, (m, name) in enumerate(zip(rec.muscles, columns)):
        p, top = rec.command_Pa[:, i], float(tops[i])
        if not math.isfinite(top) or not 0 < highest[i] < MIN_COMMAND_SHARE * top or np.ptp(p) == 0:
            continue
        if _jitter_share(p) >= JITTER_SHARE:  # an idle muscle's regulator noise, not a signal
            continue
        base, unit = split_unit(name)
        if unit not in PRESSURE:  # a column whose unit cannot be read back: no unit to offer
            continue
        shown = PRESSURE[unit]
        # a decade or more off only (bar or MPa under 'kPa', kPa under 'Pa'): psi under 'kPa' is
        # 6.9 x, as near as a muscle merely driven less than the others, and is left to the replay
        # (diagnosis._check_command_unit)
        fits = [
            u
            for u in units_putting(highest[i] / shown, MIN_COMMAND_SHARE * top, top)
            if PRESSURE[u] >= 10 * shown
        ]
        if not fits:
            continue
        # the unit that puts the column's largest command nearest the other muscles' (in ratio)
        best = min(fits, key=lambda u: abs(math.log(highest[i] / shown * PRESSURE[u] / usual)))
        if not 1 / COLUMN_UNIT_FACTOR <= highest[i] / shown * PRESSURE[best] / usual <= COLUMN_UNIT_FACTOR:
            continue
        raise ArmRecordingError(
            f"{src}: column '{name}': muscle {m}'s largest command is {highest[i] / shown:g} {unit}, under "
            f"{MIN_COMMAND_SHARE:.0%} of the model's highest pressure {top / shown:g} {unit}, while the other "
            f"muscles' commands reach {usual / shown:g} {unit}: below any EFAM's dead band, this muscle never "
            f"moves; was it {best}? the numbers fit '{base}_{best}'"
        )


def check_against_model(rec: ArmRecording, max_command_Pa, base_m, rest_reach_m: float) -> list[str]:
    """Check a recording against its arm model before any replay.

    ``max_command_Pa``: per muscle, the highest pressure the model takes (the actuators' control
    range: MuJoCo clamps beyond it); ``base_m``: the base's world position and ``rest_reach_m``
    the base-to-tip distance of the straight arm at zero pressure. Refuses (:class:`ArmRecordingError`,
    naming the column, the first line and the unit that fits) commands above
    :data:`COMMAND_REFUSE_FACTOR` x the highest pressure and tips farther from the base than
    :data:`REACH_FACTOR` x the rest reach (a value that overflows counts as far), and tips that
    stay within :data:`MIN_REACH_SHARE` x the rest reach of the base (median); commands that never
    reach :data:`MIN_COMMAND_SHARE` of the highest pressure, of all muscles together or of one
    muscle whose column reads as another unit (:func:`_check_small_columns`). Returns one message
    per column with commands a little above the highest pressure (replayed at it: the caller
    warns, never silent)."""
    src = shown_path(rec.meta.get("source", "recording"))
    max_Pa = np.broadcast_to(np.asarray(max_command_Pa, float), (len(rec.muscles),))
    columns = rec.meta.get("command_columns") or [f"p_{m}_Pa" for m in rec.muscles]
    notes = []
    for i, (m, name) in enumerate(zip(rec.muscles, columns)):
        p, top = rec.command_Pa[:, i], float(max_Pa[i])
        if not math.isfinite(top):
            continue
        unit = split_unit(name)[1]
        shown = PRESSURE.get(unit, 1.0)
        unit = unit if unit in PRESSURE else "Pa"
        far = np.flatnonzero(p > COMMAND_REFUSE_FACTOR * top)
        if far.size:
            r = int(far[0])
            fits = units_putting(np.max(p) / shown, 0.0, top)
            hint = ""
            if fits:  # the unit that puts the column's largest value nearest the top pressure
                best = max(fits, key=lambda u: PRESSURE[u])
                hint = f"; was it {best}? the numbers fit '{split_unit(name)[0]}_{best}'"
            raise ArmRecordingError(
                f"{src}: {_line(rec, r)}, column '{name}': command {p[r] / shown:g} {unit} is "
                f"{p[r] / top:.3g} x the model's highest pressure {top / shown:g} {unit} (muscle {m}'s "
                f"control range); {far.size} of {len(p)} samples are above {COMMAND_REFUSE_FACTOR:g} x it"
                + hint
            )
        over = np.flatnonzero(p > top * (1 + 1e-9))
        if over.size:
            notes.append(
                f"{src}: column '{name}': {over.size} of {len(p)} commands are above the model's highest "
                f"pressure {top / shown:g} {unit} (up to {np.max(p) / shown:g} {unit}, first at "
                f"{_line(rec, int(over[0]))}); they are replayed at {top / shown:g} {unit}"
            )
    finite = np.isfinite(max_Pa)
    if finite.any() and rec.command_Pa.size:
        highest = float(np.nanmax(rec.command_Pa))
        top = float(np.max(max_Pa[finite]))
        if highest < MIN_COMMAND_SHARE * top:
            name = columns[int(np.nanargmax(np.nanmax(rec.command_Pa, axis=0)))]
            unit = split_unit(name)[1]
            shown = PRESSURE.get(unit, 1.0)
            unit = unit if unit in PRESSURE else "Pa"
            fits = units_putting(highest / shown, MIN_COMMAND_SHARE * top, top)
            hint = ""
            if fits:  # the unit that puts the largest command nearest the top pressure
                best = max(fits, key=lambda u: PRESSURE[u])
                hint = f"; was it {best}? the numbers fit '{split_unit(name)[0]}_{best}'"
            raise ArmRecordingError(
                f"{src}: column '{name}': the largest command of any muscle is {highest / shown:g} {unit}, under "
                f"{MIN_COMMAND_SHARE:.0%} of the model's highest pressure {top / shown:g} {unit}: below any "
                f"EFAM's dead band, the arm never moves" + hint
            )
    _check_small_columns(rec, max_Pa, columns, src)
    # a test the arm cannot follow (checked here, not by the reader: a few rows are a file)
    duration = float(rec.time_s[-1] - rec.time_s[0]) if len(rec) else 0.0
    if duration < MIN_DURATION_S:
        column = rec.meta.get("time_column") or "time_s"
        interval = float(np.median(np.diff(rec.time_s))) if len(rec) > 1 else 0.0
        raise ArmRecordingError(
            f"{src}: column '{column}': the recording spans {duration:.4g} s, shorter than the "
            f"{MIN_DURATION_S:g} s an arm's tip needs to follow a command (a time unit mix-up?)"
            + unit_hint(column, interval, TYPICAL_INTERVAL_S, TIME)
        )
    # a marker that never moves while the commands do: frozen, or another body's
    spans = (
        np.nanmax(rec.tip_m, axis=0) - np.nanmin(rec.tip_m, axis=0) if np.isfinite(rec.tip_m).any() else None
    )
    if (
        spans is not None
        and float(np.max(spans)) < FROZEN_TIP_M
        and float(np.nanmax(np.ptp(rec.command_Pa, axis=0))) > 0
    ):
        tip_columns = rec.meta.get("tip_columns") or ["tip_x_m", "tip_y_m", "tip_z_m"]
        raise ArmRecordingError(
            f"{src}: columns {', '.join(repr(c) for c in tip_columns)}: the tip never moves (by at most "
            f"{float(np.max(spans)) * 1e6:.3g} um) while the commands change: a frozen or lost marker?"
        )
    if not rest_reach_m > 0:  # a model without a length (tip on the base): nothing to compare with
        return notes
    limit = REACH_FACTOR * float(rest_reach_m)
    with np.errstate(over="ignore"):  # a value near the float limit overflows to inf: far, as it is
        distance = np.linalg.norm(rec.tip_m - np.asarray(base_m, float), axis=1)
    far = np.flatnonzero(~np.isnan(distance) & (distance > limit))  # NaN: a marker dropout
    tip_columns = rec.meta.get("tip_columns") or ["tip_x_m", "tip_y_m", "tip_z_m"]
    if far.size:
        r = int(far[0])
        axis = int(np.argmax(np.abs(rec.tip_m[r] - np.asarray(base_m, float))))
        name = tip_columns[axis]
        unit = split_unit(name)[1]
        shown = LENGTH.get(unit, 1.0)
        reach = float(np.nanmedian(distance))
        raise ArmRecordingError(
            f"{src}: {_line(rec, r)}, column '{name}': the tip is {distance[r]:.4g} m from the arm's base, "
            f"{distance[r] / rest_reach_m:.3g} x the arm's rest length {rest_reach_m:.4g} m; no EFAM arm reaches "
            f"beyond {REACH_FACTOR:g} x its rest length ({far.size} of {len(distance)} samples do; the value "
            f"there: {rec.tip_m[r, axis] / shown:g} {unit if unit in LENGTH else 'm'})"
            + unit_hint(name, reach, rest_reach_m, LENGTH)
        )
    seen = distance[~np.isnan(distance)]
    if seen.size and float(np.median(seen)) < MIN_REACH_SHARE * rest_reach_m:
        reach = float(np.median(seen))
        units = sorted({split_unit(c)[1] for c in tip_columns})
        raise ArmRecordingError(
            f"{src}: columns {', '.join(repr(c) for c in tip_columns)}: the tip stays within {reach:.4g} m of the "
            f"arm's base (median), {reach / rest_reach_m:.3g} x the arm's rest length {rest_reach_m:.4g} m; an EFAM "
            f"arm's tip is at least {MIN_REACH_SHARE:g} x its rest length from its base (a tip in another unit "
            f"than {'/'.join(units)}, or another marker?)"
            + unit_hint(tip_columns[0], reach, rest_reach_m, LENGTH)
        )
    return notes


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
