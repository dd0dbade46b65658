"""Bench recordings of a muscle: time, length, pressure and force, SI inside.

A :class:`Recording` is what every consumer (calibration, diagnosis, the rig replay) takes. CSV
reading and writing with unit-suffixed headers lives here too (see ``read_csv``).

Force sign: ``force_N`` is positive when the muscle pushes its ends apart (the package's MuJoCo
convention); a ``tension_N`` column (positive = pulls, the paper's Eq. 2 sign) is negated on read.

CSV format (one file = one :class:`Recording`; a file may hold several pressures and both loading
and unloading)::

    # lines starting with '#' are comments (those among the data rows are reported)
    time_s,length_m,pressure_kPa,force_N
    0.000,0.17018,103.4,40.1
    ...

Every header is ``<quantity>_<unit>`` (units from :mod:`efam_mujoco.units`, any unit of the right
quantity): exactly one of each role below, nothing else. The quantity is read in any case
(``Time_s``, ``FORCE_N``); the unit as written (``mN`` is not ``MN``).

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
the user. Input files are only ever read. The separator is the comma and the decimal mark the
point: a semicolon- or tab-separated file and a decimal comma are refused with a message that
says so (a decimal comma is not guessed at: it could be a thousands separator). A cell may have
ASCII spaces or tabs round its value; a no-break or thin space (U+00A0, U+202F) anywhere in it is
a bad value naming the character. Comment rows ('#') are skipped: ``meta["comment_rows"]`` counts
them and ``meta["comment_lines_in_data"]`` lists those after the header (commented-out samples),
which :func:`read_recordings` reports (:func:`comment_report`).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import math
import os
import re
import sys
import unicodedata
import warnings
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .files import write_text_atomic
from .muscle import SIZE_RANGE_M
from .units import (
    LENGTH,
    PRESSURE,
    QUANTITIES,
    TIME,
    UnitError,
    factor,
    is_odd_space,
    split_unit,
    unit_that_fits,
    visible,
)


@dataclass
class Recording:
    """One bench test. Arrays share one length; ``meta`` keeps provenance (file, rest length...)."""

    time_s: np.ndarray
    length_m: np.ndarray
    pressure_Pa: np.ndarray
    force_N: np.ndarray  # positive = pushes the ends apart
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        """Arrays of one length, each one-dimensional and finite, time strictly increasing: what
        the CSV reader guarantees, checked for recordings built in Python too (a NaN there ended
        in 'SVD did not converge' deep inside a fit)."""
        for name in ("time_s", "length_m", "pressure_Pa", "force_N"):
            try:
                value = np.asarray(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"Recording: {name} must be an array of numbers") from None
            if value.ndim != 1:
                raise ValueError(f"Recording: {name} must be one-dimensional, got shape {value.shape}")
            if not np.all(np.isfinite(value)):
                k = int(np.argmin(np.isfinite(value)))
                raise ValueError(f"Recording: {name}[{k}] = {value[k]} is not a finite number")
            setattr(self, name, value)
        n = {len(self.time_s), len(self.length_m), len(self.pressure_Pa), len(self.force_N)}
        if len(n) != 1:
            raise ValueError("recording arrays must all have the same length")
        steps = np.diff(self.time_s)
        if steps.size and not np.all(steps > 0):
            k = int(np.argmin(steps > 0)) + 1
            raise ValueError(
                f"Recording: time_s must increase from sample to sample ({self.time_s[k]:g} s at sample {k} "
                f"after {self.time_s[k - 1]:g} s)"
            )

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def tension_N(self) -> np.ndarray:
        """Paper sign (Eq. 2): positive when the muscle pulls."""
        return -self.force_N

    def subset(self, mask, **meta) -> Recording:
        """The samples where ``mask`` holds (a boolean or index array), same meta plus ``meta``."""
        kept = {**self.meta, **meta}
        lines = self.meta.get("lines")
        if lines is not None and len(lines) == len(self) and "lines" not in meta:
            kept["lines"] = np.asarray(lines)[mask]
        return Recording(
            self.time_s[mask], self.length_m[mask], self.pressure_Pa[mask], self.force_N[mask], kept
        )


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


def _shown(text: str, limit: int | None = 40) -> str:
    """A header or cell as an error message quotes it: at most ``limit`` characters (None: all),
    and control characters escaped (a binary file's bytes or a terminal escape sequence never
    reach the screen as they are)."""
    clipped = text if limit is None or len(text) <= limit else text[:limit] + "..."
    return clipped if clipped.isprintable() else clipped.encode("unicode_escape").decode("ascii")


def shown_path(path: str | os.PathLike) -> str:
    """A file name as an error message shows it: as it is, or escaped like a header cell when it
    holds control characters (a name can carry a terminal escape sequence too); never cut."""
    return _shown(str(path), None)


def _columns(header: list[str], label: str, line: int) -> dict[str, tuple[int, str, str, float]]:
    """Map each role to (column index, header, base, factor to SI with sign)."""
    found: dict[str, tuple[int, str, str, float]] = {}
    for index, raw in enumerate(header):
        name = raw.strip(CELL_SPACE)
        if not name:
            raise RecordingError(
                f"{label}: line {line}, column {index + 1}: empty header (expected {_ACCEPTED})"
            )
        base, unit = split_unit(name)
        # the quantity's name in any case ('Time_s', 'FORCE_N'); the unit's case is meaning (mN, MN)
        base = base.lower()
        if name.lower() in _BASE_ROLE:
            plain = name.lower()
            raise RecordingError(
                f"{label}: line {line}, column '{_shown(name)}' has no unit; write e.g. "
                f"'{plain}_{'kPa' if plain == 'pressure' else next(iter(_unit_table(plain)))}'"
            )
        if base not in _BASE_ROLE:
            refuse_other_separators(header, label, line, _ACCEPTED)
            raise RecordingError(
                f"{label}: line {line}, unknown column '{_shown(name)}' (accepted: {_ACCEPTED})"
            )
        role = _BASE_ROLE[base]
        quantity, sign = _ROLES[role][base]
        try:
            scale = factor(unit, quantity, f"{label}: line {line}, column '{_shown(name)}'")
        except UnitError as err:
            raise RecordingError(str(err)) from None
        if role in found:
            raise RecordingError(
                f"{label}: line {line}, columns '{_shown(found[role][1])}' and '{_shown(name)}' both give the {role}"
            )
        found[role] = (index, name, base, sign * scale)
    for role in _ROLES:
        if role not in found:
            options = " or ".join(f"'{b}_<unit>'" for b in _ROLES[role])
            raise RecordingError(f"{label}: line {line}, missing a {role} column ({options})")
    return found


def _unit_table(base: str) -> dict:
    return QUANTITIES[_ROLES[_BASE_ROLE[base]][base][0]]


#: A data row is a few dozen bytes; a line longer than this is not one (and is not read whole).
MAX_LINE_BYTES = 65536
#: No physical recording of a muscle holds a value this large in SI (1e9 m, Pa, N, s): such a
#: value is a corrupt field (``1e300``), refused like a non-number.
MAX_MAGNITUDE_SI = 1e9
#: A gauge pressure cannot be below minus one atmosphere.
P_ATM_PA = 101325.0


#: leading bytes of compressed archives a recording may be mistaken for (gzip, zip, bzip2, xz, zstd)
COMPRESSED_MAGIC = {
    b"\x1f\x8b": "gzip", b"PK\x03\x04": "zip", b"BZh": "bzip2", b"\xfd7zXZ\x00": "xz",
    b"\x28\xb5\x2f\xfd": "zstd",
}  # fmt: skip


def _refuse_compressed(first_line: bytes, label: str) -> None:
    """Refuse a file that starts like a compressed archive, naming the format (its bytes would
    otherwise be judged as text: a stray CR read as old Mac line endings)."""
    for magic, kind in COMPRESSED_MAGIC.items():
        if first_line.startswith(magic):
            raise RecordingError(
                f"{label}: a {kind}-compressed file, not a CSV text recording: decompress it first"
            )


def _decoded_lines(handle, label: str):
    """The file's lines as text: UTF-8 (a BOM at the start is dropped), each line bounded;
    an error names the line and the column of a bad byte."""
    number = 0
    while True:
        raw = handle.readline(MAX_LINE_BYTES + 1)
        if not raw:
            return
        number += 1
        if number == 1:
            _refuse_compressed(raw, label)
        nul = raw.find(b"\x00")
        if nul >= 0:
            raise RecordingError(
                f"{label}: line {number}, column {nul + 1}: a NUL byte: not UTF-8 text (a binary file, or "
                "UTF-16); save it as CSV text in UTF-8 or ASCII"
            )
        if b"\r" in raw.rstrip(b"\r\n"):
            _utf8(raw, number, label)  # a bare CR in bytes that are not text is no line ending
            raise RecordingError(
                f"{label}: line {number}: lines end in a bare carriage return (CR, old Mac line "
                "endings); save the file with LF or CRLF line endings"
            )
        if len(raw) > MAX_LINE_BYTES and not raw.endswith(b"\n"):
            raise RecordingError(
                f"{label}: line {number}: longer than {MAX_LINE_BYTES} bytes (not a recording row)"
            )
        if number == 1 and raw.startswith(b"\xef\xbb\xbf"):
            raw = raw[3:]
        yield _utf8(raw, number, label)


def _utf8(raw: bytes, number: int, label: str) -> str:
    """Line ``number`` decoded as UTF-8, or the error naming its column and the byte."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise RecordingError(
            f"{label}: line {number}, column {err.start + 1}: byte 0x{raw[err.start]:02x} is not "
            "UTF-8 (save the file as UTF-8 or ASCII)"
        ) from None


def open_recording(path: Path, label: str):
    """``path`` opened for reading as bytes, refused (:class:`RecordingError` naming ``label``) when
    it is a folder, a pipe or a device (which would block or never end), or cannot be opened."""
    if path.is_dir():
        raise RecordingError(f"{label}: is a folder, not a recording file")
    if path.exists() and not path.is_file():
        raise RecordingError(f"{label}: not a regular file (a pipe or a device?)")
    try:
        return path.open("rb")
    except OSError as err:
        raise RecordingError(f"{label}: cannot open ({err.strerror})") from None


def csv_rows(handle, label: str, comments: array | None = None):
    """(first line, last line, row) of each CSV row of an open recording that is not blank and
    not a '#' comment, decoded by the rules of :func:`_decoded_lines`; last > first when a
    quoted field ran over lines (an unclosed quote), which the caller names with a bad row.
    ``comments`` (an ``array("q")``), when given, receives the line number of every comment row."""
    reader = csv.reader(_decoded_lines(handle, label))
    while True:
        first = reader.line_num + 1
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as err:
            raise RecordingError(f"{label}: line {first}: not a CSV row ({err})") from None
        if _is_comment(row):
            if comments is not None:
                comments.append(first)
        elif not _skip(row):
            yield first, reader.line_num, row


def refuse_other_separators(header: list[str], label: str, line: int, accepted: str) -> None:
    """Refuse a header that is one field holding ';'- or tab-separated names (naming the separator)."""
    for sep, word in ((";", "semicolon"), ("\t", "tab")):
        if len(header) == 1 and sep in header[0]:
            raise RecordingError(
                f"{label}: line {line}, unknown column '{_shown(header[0].strip())}': the header is one field "
                f"holding '{word}'-separated names; save the file comma-separated, with decimal points "
                f"(accepted: {accepted})"
            )


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

    The file is streamed (memory ~ 40 bytes a row); a row's line number is kept in
    ``meta["lines"]`` for messages. A value that cannot be physical (a magnitude above 1e9 in SI,
    a gauge pressure below -1 atm) is a bad row like a non-number.
    """
    if on_bad_rows not in BAD_ROW_POLICIES:
        raise ValueError(f"on_bad_rows must be one of {BAD_ROW_POLICIES}, got {on_bad_rows!r}")
    path = Path(path)
    label = shown_path(path)  # for messages; meta keeps the real name (write_csv compares it)
    handle = open_recording(path, label)
    columns = None
    header: list[str] = []
    order = ("time", "length", "pressure", "force")
    values = [array("d") for _ in order]
    lines = array("q")
    comments = array("q")  # the line of every '#' row, before the header and among the data
    header_line = 0
    dropped: list[dict] = []
    last_time = -math.inf
    with handle:
        for first, last, row in csv_rows(handle, label, comments):
            line = first  # a quoted field can carry a row over several lines
            if columns is None:
                header, columns, header_line = row, _columns(row, label, line), line
                continue
            parsed, problem = _parse_row(row, header, columns, order)
            if problem is None and parsed[0] <= last_time:
                what = "duplicate time" if parsed[0] == last_time else "time goes backwards (unsorted rows)"
                problem = (columns["time"][1], f"{what}: {parsed[0]:g} s after {last_time:g} s")
            if problem is not None:
                column, reason = problem
                if last > first:  # an unclosed quote swallowed the lines after it
                    reason += f" (a quote on line {first} runs on to line {last})"
                if on_bad_rows == "error" or last > first:
                    # dropping a row an unclosed quote spans would drop every line it swallowed
                    # (half a recording, reported as one bad row): refused in either mode
                    where = f"line {line}" + (f", column '{column}'" if column else "")
                    hint = (
                        f"; close the quote: dropping the row would lose lines {first}-{last}"
                        if last > first
                        else " (--on-bad-rows drop, or on_bad_rows='drop' in Python, drops such rows)"
                    )
                    raise RecordingError(f"{label}: {where}: {reason}{hint}")
                if len(dropped) < 10000:
                    dropped.append({"line": line, "column": column, "reason": reason})
                else:
                    dropped[-1] = {**dropped[-1], "more": dropped[-1].get("more", 0) + 1}
                continue
            last_time = parsed[0]
            for store, value in zip(values, parsed):
                store.append(value)
            lines.append(line)
    if columns is None:
        raise RecordingError(f"{label}: no header line (expected {_ACCEPTED})")
    if len(lines) < 2:
        raise RecordingError(f"{label}: fewer than 2 usable data rows ({len(dropped)} dropped)")
    time_s, length, pressure, force = (np.frombuffer(v, dtype=float).copy() for v in values)
    rest = None if rest_length_m is None else float(rest_length_m)
    if rest is not None and not (math.isfinite(rest) and rest > 0):
        raise RecordingError(f"{label}: rest_length_m must be a positive length, got {rest_length_m!r}")
    length_column = columns["length"][1]
    if columns["length"][2] == "displacement":
        if rest is None:
            raise RecordingError(
                f"{label}: column '{length_column}' is the change from the resting length; give the "
                "resting length (on the command line --muscle gives it; in Python rest_length_m=...)"
            )
        length = rest + length
    if np.any(length <= 0):
        line = lines[int(np.argmax(length <= 0))]
        raise RecordingError(
            f"{label}: line {line}, column '{length_column}': a length <= 0 m "
            f"({length[int(np.argmax(length <= 0))]:g} m)"
        )
    meta = {
        "source": str(path),
        "columns": [c.strip() for c in header],
        "rest_length_m": rest,
        "dropped_rows": dropped,
        "lines": np.frombuffer(lines, dtype=np.int64).copy(),
        **comment_meta(comments, header_line),
    }
    return Recording(time_s, length, pressure, force, meta)


_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")


#: the whitespace a cell may have around its value: ASCII only (a no-break space, U+00A0, is
#: refused with the cell, never stripped: it is no space a CSV writer puts there)
CELL_SPACE = " \t"


def _is_comment(row: list[str]) -> bool:
    return bool(row) and row[0].lstrip(CELL_SPACE).startswith("#")


def _skip(row: list[str]) -> bool:
    return not row or all(not cell.strip(CELL_SPACE) for cell in row) or _is_comment(row)


def decimal_cell(text: str, scale: float = 1.0) -> tuple[float | None, str]:
    """A stripped, non-empty CSV cell as a value in SI (times ``scale``) and "", or None and
    why not: a plain ASCII decimal only (``float`` alone also takes ``1_000``, a thousands
    separator?, and other scripts' digits; a decimal comma is refused, not guessed), finite,
    and at most :data:`MAX_MAGNITUDE_SI` in SI (``1e300`` is a corrupt field)."""
    try:
        if "_" in text or not text.isascii():
            raise ValueError(text)
        value = float(text)
    except ValueError:
        hint = " (a decimal comma? write decimal points)" if _DECIMAL_COMMA.match(text) else ""
        odd = next((c for c in text if not c.isascii()), "")
        if odd:  # float() strips a no-break space round a number: name it instead
            hint = (
                f" (it holds U+{ord(odd):04X}, {unicodedata.name(odd, 'unnamed').lower()}: a number is plain "
                f"ASCII digits{', with no spaces inside' if is_odd_space(odd) else ''})"
            )
        return None, f"not a number: {_shown(text)!r}{hint}"
    if not math.isfinite(value):
        return None, f"not a finite number: {_shown(text)!r}"
    value *= scale
    if not abs(value) <= MAX_MAGNITUDE_SI:
        return None, f"{_shown(text)} cannot be physical (magnitude above {MAX_MAGNITUDE_SI:g} in SI)"
    return value, ""


def _looks_like_epoch(text: str, scale: float) -> bool:
    """Whether a time cell reads as Unix clock time (seconds, or ms, since 1970, dated 2001 ..
    2100) rather than the time since the test's start."""
    try:
        seconds = float(text) * scale
    except ValueError:
        return False
    return 9.8e8 <= seconds <= 4.2e9


def _parse_row(row, header, columns, order):
    """The row's values in SI (role order) and None, or None and (column, problem)."""
    if len(row) != len(header):
        return None, ("", f"{len(row)} fields, the header has {len(header)}")
    out = []
    for role in order:
        index, name, _, scale = columns[role]
        text = row[index].strip(CELL_SPACE)
        if not text:
            return None, (name, "empty value")
        value, problem = decimal_cell(text, scale)
        if value is None:
            if role == "time" and "cannot be physical" in problem and _looks_like_epoch(text, scale):
                problem += (
                    ": it reads as an absolute clock time (Unix seconds since 1970); write the time since "
                    "the test's start (the first time subtracted)"
                )
            return None, (name, problem)
        if role == "pressure" and value < -P_ATM_PA:
            return None, (name, f"gauge pressure {value / 1e3:g} kPa is below -1 atm (-101.325 kPa)")
        out.append(value)
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
    total = len(dropped) + sum(d.get("more", 0) for d in dropped)  # the list keeps 10 000 at most
    more = f"; and {total - limit} more" if total > limit else ""
    return (
        f"{shown_path(recording.meta.get('source', 'recording'))}: dropped {total} bad row(s): {shown}{more}"
    )


def comment_meta(comments, header_line: int) -> dict:
    """The ``meta`` entries of the '#' rows a reader skipped (``comments``: their file lines;
    ``header_line``: the header's): how many in all, and the lines of those after the header (a
    commented-out sample, not a preamble), which :func:`comment_report` tells the user."""
    return {"comment_rows": len(comments), "comment_lines_in_data": [c for c in comments if c > header_line]}


def comment_report(recording, limit: int = 5) -> str:
    """One line telling the user how many '#' rows among the data rows (after the header) were
    skipped, and where ('' when none): a commented-out sample is not read. Comment lines before
    the header (a preamble, the format's documented use) are only counted in ``meta``.
    ``recording``: a muscle :class:`Recording` or an arm recording (both keep the lines in ``meta``)."""
    inside = recording.meta.get("comment_lines_in_data") or []
    if not len(inside):
        return ""
    shown = ", ".join(str(int(line)) for line in inside[:limit])
    more = f"; and {len(inside) - limit} more" if len(inside) > limit else ""
    return (
        f"{shown_path(recording.meta.get('source', 'recording'))}: skipped {len(inside)} comment row(s) "
        f"('#') among the data rows, not read as samples: line(s) {shown}{more}"
    )


def read_recordings(
    paths, *, rest_length_m: float | None = None, on_bad_rows: str = "error", warn=None
) -> list[Recording]:
    """Read several CSV files (see :func:`read_csv`); each file's '#' rows among its data
    (:func:`comment_report`) and, with ``on_bad_rows="drop"``, its dropped rows are told to
    ``warn`` (a callable taking one line; default: standard error)."""
    warn = warn or (lambda line: print(line, file=sys.stderr))
    recordings = []
    for path in paths:
        recording = read_csv(path, rest_length_m=rest_length_m, on_bad_rows=on_bad_rows)
        for note in (comment_report(recording), drop_report(recording)):
            if note:
                warn(note)
        recordings.append(recording)
    return recordings


def write_csv(path: str | os.PathLike, recording: Recording, *, pressure_unit: str = "kPa") -> Path:
    """Write ``time_s,length_m,pressure_<unit>,force_N`` atomically (files.write_text_atomic).

    Refuses to overwrite the file the recording was read from (input files are never modified).
    """
    path = Path(path)
    source = recording.meta.get("source")
    if source and Path(source).exists() and path.exists() and path.resolve() == Path(source).resolve():
        raise RecordingError(f"{path}: refusing to overwrite the recording's own input file")
    scale = factor(pressure_unit, "pressure", "write_csv")
    rows = np.column_stack(
        [recording.time_s, recording.length_m, recording.pressure_Pa / scale, recording.force_N]
    )
    if not np.isfinite(rows).all():
        raise RecordingError(f"{path}: the recording holds non-finite values; nothing written")
    lines = [f"time_s,length_m,pressure_{pressure_unit},force_N\n"]
    lines += [f"{t:.9g},{length:.9g},{p:.9g},{f:.9g}\n" for t, length, p, f in rows]
    return write_text_atomic(path, "".join(lines))  # a unique temporary, then a rename


# ------------------------------------------------------------------ physical plausibility
#: Names of the plausibility checks (``efam calibrate/diagnose --allow NAME`` turns one into a
#: named warning).
CHECKS = {
    "time-unit": "sample intervals no bench recorder makes (a time unit mix-up)",
    "length-unit": "lengths in another unit than the header says (a factor of ten off the resting length, or forces that fit the model far better re-read)",
    "length-range": "lengths outside the muscle's admissible range",
    "rest-length": "a recording that never comes near the muscle's resting length",
    "pressure-range": "pressures above the rated pressure",
    "pressure-deadband": "pressures that never exceed the muscle's dead band",
    "pressure-negative": "gauge pressures well below zero",
    "pressure-absolute": "absolute pressures in a gauge column (every value an atmosphere too high)",
    "pressure-unit": "pressures whose forces fit the model far better read in another unit (psi under 'kPa')",
    "force-range": "forces beyond what the muscle can produce",
    "force-unit": "forces a unit factor off the muscle's model (lbf or kgf under 'N')",
    "force-dead": "a constant or dead force channel (load cell)",
    "force-sign": "a force channel whose sign is the other way round (push vs pull)",
    "force-model": "a force channel that does not follow length and pressure at all (noise, another test's column)",
    "nothing-varies": "length and pressure both constant",
    "tension-only": "a tension-only muscle recorded pushing",
}
#: Default rated (largest allowed) gauge pressure: above the paper's 517 kPa and a Festo
#: DMSP's 600 kPa with margin. ``--rated-pressure-kPa`` changes it.
DEFAULT_RATED_PRESSURE_PA = 1.0e6
#: Lengths this far beyond the admissible range (fraction of the resting length) are flagged.
LENGTH_TOLERANCE = 0.02
#: A recording must come this close (fraction of the resting length) to the resting length.
REST_LENGTH_REACH = 0.5
#: Median sample intervals a bench recorder makes (1 MHz .. one sample a minute).
MIN_INTERVAL_S, MAX_INTERVAL_S = 1e-6, 60.0
TIME_UNITS = TIME
#: A recording whose length sweeps at least this share of the resting length (it was stroked)
#: must somewhere move faster than MIN_STROKE_SPEED_M_PER_S between two samples. Bench strokes
#: run at mm/s (the paper 5.1 mm/s, Sec. 3; standard rubber tests 500 mm/min); 10 um/s is a
#: 100 mm stroke taking almost three hours. A time column in ms headed ``time_s`` makes every
#: speed 1000 times slower (5.1 mm/s reads as 5.1 um/s) while its sample intervals (10 ms read
#: as 10 s) still look like a slow recorder's; held-length (isometric) recordings are not judged.
STROKE_SWEEP = 0.05
MIN_STROKE_SPEED_M_PER_S = 10e-6
#: ... and nowhere faster than this (over at least ``SPEED_WINDOW_S``, so that encoder noise
#: between two samples a millisecond apart does not count): fast servo-hydraulic testers stroke
#: at up to about 1 m/s; seconds written under ``time_ms`` make a 5 mm/s stroke read 5 m/s
MAX_STROKE_SPEED_M_PER_S = 3.0
SPEED_WINDOW_S = 0.02
#: The least-squares scale from the model's force to the recorded one (where the model is
#: trustworthy, ``FORCE_SCALE_REGION``): outside this range the force column is in another unit than its header says (lbf
#: under 'N' reads 0.22, kgf 0.10, mN 1000) or the muscle is not the one tested; a muscle that
#: differs from its file by tens of percent, with its friction and zero, stays well inside
FORCE_SCALE_RANGE = (0.4, 2.5)
#: A recorded force whose correlation with the model's (same lengths and pressures) is below
#: minus this has its sign the other way round (effects and zeros keep it well above zero).
SIGN_CORRELATION = 0.5
#: ... and one whose correlation with it lies within plus or minus this does not follow the
#: muscle at all: a muscle's force rises and falls with its pressure and length whatever its
#: friction, drift or zero (a channel of noise, a column from another test, shuffled rows)
FOLLOW_CORRELATION = 0.3
#: A recording with more than this share of its lengths outside the admissible range has lengths
#: in another unit or column (the force checks against the model are then skipped: they would
#: read the model at the wrong lengths)
LENGTHS_WRONG_SHARE = 0.05
#: Gauge pressures below this are flagged (noise around zero passes).
NEGATIVE_PRESSURE_PA = -10e3
#: One standard atmosphere (Pa): what an absolute pressure reads above the gauge pressure.
ATMOSPHERE_PA = 101325.0
#: A recording never below an atmosphere less this whose forces the model reproduces with less
#: than this share of the error once an atmosphere is taken off is flagged as absolute pressure.
ABSOLUTE_SLACK_PA, ABSOLUTE_ERROR_SHARE = 5e3, 0.5
#: A recording whose forces the model reproduces with less than this share of the error (and at
#: least ``UNIT_ERROR_MATERIAL_N`` better) once its pressures are read in another unit is flagged:
#: one file of a set in psi under a 'kPa' header was calibrated and diagnosed as physics.
UNIT_ERROR_SHARE, UNIT_ERROR_MATERIAL_N = 0.3, 5.0


@dataclass(frozen=True)
class Finding:
    """One failed plausibility check: its name (a key of :data:`CHECKS`) and what was seen."""

    check: str
    message: str
    #: beyond any fluidic muscle (not only this one's rating or range): refused even when its
    #: check is allowed, since no ``--allow`` makes such a recording a muscle's
    impossible: bool = False


class PlausibilityError(RecordingError):
    """Recordings that cannot be physical for the muscle; the message names each check."""


def _line(recording: Recording, index: int) -> str:
    lines = recording.meta.get("lines")
    if lines is not None and len(lines) == len(recording):
        return f"line {int(lines[index])}"
    return f"sample {index + 1}"


def _column(recording: Recording, base: str) -> str:
    for name in recording.meta.get("columns", []):
        if split_unit(name)[0].lower() in base.split("|"):
            return name
    return base.split("|")[0]


def _time_unit_hint(tcol: str, speed: float, bench_speed) -> str:
    """``"; the numbers fit 'time_ms'"``: the time unit nearest the header's under which the
    length would move at ``speed`` re-read so that ``bench_speed(speed)`` holds, or ''."""
    base, unit = split_unit(tcol)
    if unit not in TIME_UNITS:
        return ""
    # nearest first: a unit the other way round only makes the speed worse, and fails the test
    for other in sorted(TIME_UNITS, key=lambda u: abs(math.log(TIME_UNITS[u] / TIME_UNITS[unit]))):
        if other != unit and bench_speed(speed * TIME_UNITS[unit] / TIME_UNITS[other]):
            return f"; the numbers fit '{base}_{other}'"
    return ""


def _slow_strokes(rec: Recording, rest: float, tcol: str) -> str:
    """A message when the recording was stroked (its length sweeps ``STROKE_SWEEP`` of the
    resting length) but never faster than ``MIN_STROKE_SPEED_M_PER_S``, the fastest
    sample-to-sample speed: a time column in a smaller unit than its header says; else ''."""
    L, t = rec.length_m, rec.time_s
    if len(rec) < 2 or not float(np.ptp(L)) >= STROKE_SWEEP * rest:
        return ""
    fastest = float(np.max(np.abs(np.diff(L)) / np.diff(t)))
    if fastest >= MIN_STROKE_SPEED_M_PER_S:
        return ""
    hint = _time_unit_hint(tcol, fastest, lambda speed: speed >= MIN_STROKE_SPEED_M_PER_S)
    duration = float(t[-1] - t[0])
    return (
        f"column '{tcol}': the muscle is stroked over {np.ptp(L) * 1e3:.4g} mm but never faster than "
        f"{fastest * 1e6:.3g} um/s (over {duration / 3600:.3g} h); bench strokes run at mm/s, and "
        f"{MIN_STROKE_SPEED_M_PER_S * 1e6:g} um/s is a 100 mm stroke taking "
        f"{0.1 / MIN_STROKE_SPEED_M_PER_S / 3600:.3g} h{hint}"
    )


def _fast_strokes(rec: Recording, rest: float, tcol: str) -> str:
    """A message when the length moves faster than ``MAX_STROKE_SPEED_M_PER_S`` over any span of
    ``SPEED_WINDOW_S`` (or more, at a slow sampling rate): a time column in a larger unit than its
    header says (seconds under ``time_ms``); else ''."""
    L, t = rec.length_m, rec.time_s
    if len(rec) < 3 or not float(np.ptp(L)) >= STROKE_SWEEP * rest:
        return ""
    interval = float(np.median(np.diff(t)))
    lag = max(1, int(math.ceil(SPEED_WINDOW_S / interval))) if interval > 0 else 1
    if lag >= len(rec):
        return ""
    with np.errstate(all="ignore"):
        speed = np.abs(L[lag:] - L[:-lag]) / (t[lag:] - t[:-lag])
    speed = speed[np.isfinite(speed)]
    # the 99th percentile: one glitch of the encoder is not a stroke
    fastest = float(np.percentile(speed, 99)) if speed.size else 0.0
    if fastest <= MAX_STROKE_SPEED_M_PER_S:
        return ""
    hint = _time_unit_hint(tcol, fastest, lambda speed: speed <= MAX_STROKE_SPEED_M_PER_S)
    return (
        f"column '{tcol}': the muscle is stroked at {fastest:.3g} m/s, faster than a bench strokes a "
        f"muscle (fast testers reach about 1 m/s; the limit here is {MAX_STROKE_SPEED_M_PER_S:g} m/s){hint}"
    )


def _far_better(F, as_read: float, best):
    """``(as_read, best)`` when the re-read unit's fit ``best`` ((unit, RMS error) or None) is far
    better than the fit as read (:data:`UNIT_ERROR_SHARE`, :data:`UNIT_ERROR_MATERIAL_N`) and the
    model so read explains the force's own variation (R^2 >= 0.5: a dead load cell's zeros also
    sit nearer a muscle whose pressures are read a thousand times smaller); else
    ``(as_read, None)``. The rule of the pressure-unit and length-unit checks."""
    explains = best is not None and best[1] ** 2 <= 0.5 * float(np.var(F))
    if explains and best[1] < UNIT_ERROR_SHARE * as_read and as_read - best[1] > UNIT_ERROR_MATERIAL_N:
        return as_read, best
    return as_read, None


def _pressure_unit_fit(muscle, F, P, L, aligned, column: str, rated_pressure_Pa: float):
    """(model RMS error as read, (unit, its RMS error) or None): the pressure unit other than
    ``column``'s under which ``muscle``'s force fits the recorded ``F`` best, when that is far
    better (:data:`UNIT_ERROR_SHARE`, :data:`UNIT_ERROR_MATERIAL_N`) and keeps the pressures
    within the rated pressure."""
    written = split_unit(column)[1]
    if written not in PRESSURE or not np.all(np.isfinite(aligned)) or not np.any(P > 0):
        return 0.0, None
    as_read = float(np.sqrt(np.mean((F - aligned) ** 2)))
    best = None
    for unit, size in PRESSURE.items():
        scale = size / PRESSURE[written]
        if unit == written or float(np.max(P)) * scale > rated_pressure_Pa:
            continue
        with np.errstate(all="ignore"):
            error = float(np.sqrt(np.mean((F - np.asarray(muscle.push(P * scale, L), dtype=float)) ** 2)))
        if np.isfinite(error) and (best is None or error < best[1]):
            best = (unit, error)
    return _far_better(F, as_read, best)


def _length_unit_fit(muscle, F, P, L, column: str, admissible: tuple[float, float]):
    """(model RMS error as read, (unit, its RMS error) or None): the length unit other than
    ``column``'s under which ``muscle``'s force fits the recorded ``F`` best, when that is far
    better (:data:`UNIT_ERROR_SHARE`, :data:`UNIT_ERROR_MATERIAL_N`, and explaining the force's
    own variation) with every length re-read inside the muscle's ``admissible`` range. A
    displacement is re-read from the resting length, a length from zero. Centimetres under a
    displacement_in header put a FAM at 2.5 times the strain it reached, still within the
    threads' geometric reach: only the forces tell."""
    base, written = split_unit(column)
    if written not in LENGTH or not np.any(P > muscle.deadband_Pa):
        return 0.0, None
    rest = muscle.rest_length_m
    origin = rest if base == "displacement" else 0.0
    lo, hi = admissible

    def error(lengths):
        with np.errstate(all="ignore"):
            e = float(np.sqrt(np.mean((F - np.asarray(muscle.push(P, lengths), dtype=float)) ** 2)))
        return e if np.isfinite(e) else math.inf

    as_read = error(L)
    best = None
    for unit, size in LENGTH.items():
        if unit == written:
            continue
        lengths = origin + (L - origin) * (size / LENGTH[written])
        if float(np.min(lengths)) < lo or float(np.max(lengths)) > hi:
            continue
        e = error(lengths)
        if best is None or e < best[1]:
            best = (unit, e)
    return _far_better(F, as_read, best)


def check_plausibility(
    recordings,
    muscle,
    *,
    rated_pressure_Pa: float = DEFAULT_RATED_PRESSURE_PA,
    tension_only: bool | None = None,
) -> list[Finding]:
    """Physical plausibility of recordings for ``muscle``, before any fit (see :data:`CHECKS`).

    Returns the findings (empty when everything is plausible); :func:`enforce_plausibility`
    turns them into an error or named warnings. Each message names the file, the column, the
    first offending line and, for a likely unit mix-up, the unit that would fit.
    """
    tension_only = muscle.tension_only if tension_only is None else tension_only
    rest = muscle.rest_length_m
    lo, hi = muscle.min_length_m, muscle.max_length_m
    findings: list[Finding] = []
    for rec in recordings:
        src = shown_path(rec.meta.get("source", "recording"))
        L, P, F = rec.length_m, rec.pressure_Pa, rec.force_N
        start = len(findings)
        lcol, pcol, fcol = (
            _column(rec, "length|displacement"),
            _column(rec, "pressure"),
            _column(rec, "force|tension"),
        )
        median_L = float(np.median(L))
        # lengths a unit or a column away from the muscle's: the forces' checks against the
        # model would compare with a model read at the wrong lengths, and only add noise
        lengths_wrong = False
        # lengths: a unit mix-up first (then the other length checks would only repeat it)
        if not 0.1 < median_L / rest < 10:
            if split_unit(lcol)[0] == "displacement":
                d = float(np.median(np.abs(L - rest))) or float(np.max(np.abs(L - rest)))
                fits = unit_that_fits(d, 0.2 * rest, lcol, LENGTH)
            else:
                fits = unit_that_fits(median_L, rest, lcol, LENGTH)
            hint = f"; the numbers fit '{fits}'" if fits else ""
            findings.append(Finding("length-unit", (
                f"{src}: column '{lcol}': median length {median_L:.4g} m is {median_L / rest:.3g} x the "
                f"muscle's resting length {rest:.4g} m{hint}"
            )))  # fmt: skip
            lengths_wrong = True
        else:
            out = (L < lo - LENGTH_TOLERANCE * rest) | (L > hi + LENGTH_TOLERANCE * rest)
            if out.any():
                i = int(np.argmax(out))
                base, unit = split_unit(lcol)
                hint = ""
                # a displacement written under a length header: read from the resting length,
                # every value would be admissible
                shifted = L + rest
                if base == "length" and np.all((shifted >= lo) & (shifted <= hi + LENGTH_TOLERANCE * rest)):
                    hint = (
                        f"; read as a displacement from the resting length every value is admissible: is the "
                        f"column 'displacement_{unit}'?"
                    )
                findings.append(Finding("length-range", (
                    f"{src}: {_line(rec, i)}, column '{lcol}': length {L[i]:.4g} m is outside the muscle's "
                    f"admissible range {lo:.4g} .. {hi:.4g} m ({np.count_nonzero(out)} samples){hint}"
                )))  # fmt: skip
                lengths_wrong = lengths_wrong or np.mean(out) > LENGTHS_WRONG_SHARE
            nearest = float(np.min(np.abs(L - rest)))
            if nearest > REST_LENGTH_REACH * rest:
                base, unit = split_unit(lcol)
                question = "is --muscle the muscle that was tested?"
                # a muscle's length written under a displacement header: read from the resting
                # length, every value lands one resting length too far, and as lengths they fit
                if base == "displacement" and np.min(np.abs(L - 2 * rest)) <= REST_LENGTH_REACH * rest:
                    question = (
                        f"'{lcol}' is read from the resting length (length = {rest:.4g} m + displacement), and "
                        f"the numbers fit the muscle's own length: is the column 'length_{unit}'?"
                    )
                findings.append(Finding("rest-length", (
                    f"{src}: column '{lcol}': the recording never comes within {REST_LENGTH_REACH:.0%} of the "
                    f"muscle's resting length {rest:.4g} m (nearest {nearest:.4g} m away): {question}"
                )))  # fmt: skip
                lengths_wrong = True
        tcol = _column(rec, "time")
        interval = float(np.median(np.diff(rec.time_s))) if len(rec) > 1 else 0.0
        if not MIN_INTERVAL_S <= interval <= MAX_INTERVAL_S:
            # a unit is offered only when under it the interval is one a recorder makes
            fits = unit_that_fits(interval, 0.01, tcol, TIME_UNITS, within=(MIN_INTERVAL_S, MAX_INTERVAL_S))
            hint = f"; the numbers fit '{fits}'" if fits else ""
            findings.append(Finding("time-unit", (
                f"{src}: column '{tcol}': the median sample interval is {interval:.4g} s; a bench recorder "
                f"samples every {MIN_INTERVAL_S:g} .. {MAX_INTERVAL_S:g} s{hint}"
            )))  # fmt: skip
        elif not lengths_wrong:  # strokes measured in lengths of another unit say nothing of the clock
            odd = _slow_strokes(rec, rest, tcol) or _fast_strokes(rec, rest, tcol)
            if odd:
                findings.append(Finding("time-unit", f"{src}: {odd}"))
        # pressures
        top = float(np.max(P))
        # pressures above the rating (another unit, or a spike): the forces' checks against the
        # model would read the model at those pressures and blame a good load cell
        pressures_wrong = top > rated_pressure_Pa
        if pressures_wrong:
            above = P > rated_pressure_Pa
            i, n_above = int(np.argmax(above)), int(np.count_nonzero(above))
            # a unit mix-up lifts most of the actuated samples; a few spikes in good data are not
            # a unit, and a unit hint there would have the user corrupt a right column
            actuated = max(np.count_nonzero(P > muscle.deadband_Pa), 1)
            if n_above >= 0.5 * actuated:
                fits = unit_that_fits(top, 0.5 * rated_pressure_Pa, pcol, PRESSURE)
                hint = f"; the numbers fit '{fits}'" if fits else ""
            else:
                hint = f" ({n_above} of {len(P)} samples, the rest within it: spikes or corrupt rows?)"
            findings.append(Finding("pressure-range", (
                f"{src}: {_line(rec, i)}, column '{pcol}': pressure {P[i] / 1e3:.4g} kPa is above the rated "
                f"pressure {rated_pressure_Pa / 1e3:g} kPa{hint}"
            )))  # fmt: skip
        elif top <= muscle.deadband_Pa:
            # a unit is offered only for a pressure that was driven (its swing far above its
            # sample-to-sample noise): on a never-pressurised file the noise around zero "fit"
            # bar or MPa, inviting a relabel that would corrupt a right column
            jitter = float(np.median(np.abs(np.diff(P)))) if len(P) > 1 else 0.0
            driven = top > 0 and float(np.ptp(P)) > 50.0 * jitter
            fits = unit_that_fits(top, 0.5 * rated_pressure_Pa, pcol, PRESSURE) if driven else ""
            hint = (
                f"; the numbers fit '{fits}'"
                if fits
                else ""
                if driven
                else "; it stays within its own noise: was the muscle pressurised?"
            )
            findings.append(Finding("pressure-deadband", (
                f"{src}: column '{pcol}': the pressure never exceeds the muscle's dead band "
                f"({top / 1e3:.4g} kPa <= {muscle.deadband_Pa / 1e3:.4g} kPa), so the muscle is never "
                f"actuated{hint}"
            )))  # fmt: skip
        lowest = float(np.min(P))
        if lowest < NEGATIVE_PRESSURE_PA:
            i = int(np.argmin(P))
            findings.append(Finding("pressure-negative", (
                f"{src}: {_line(rec, i)}, column '{pcol}': gauge pressure {P[i] / 1e3:.4g} kPa is well below "
                "zero; the model has no vacuum physics"
            )))  # fmt: skip
        # forces: what the muscle can produce over the recorded lengths and pressures
        step = max(1, len(rec) // 4000)
        Lc = np.clip(L[::step], lo, hi)
        Pc = np.clip(P[::step], 0.0, None)
        Fc = F[::step]
        free = dataclasses.replace(muscle, tension_only=False) if muscle.tension_only else muscle
        with np.errstate(all="ignore"):  # what the muscle could push or pull, before any clamp
            aligned = np.asarray(free.push(Pc, Lc), dtype=float)
            span = np.linspace(float(np.min(Lc)), float(np.max(Lc)), 200)  # the recorded lengths only
            reach = np.asarray(free.push(float(np.max(Pc)), span), dtype=float)
        # a length in another unit than its header's, within the admissible range (else the
        # length checks above said it): the forces fit the model far better re-read, and a
        # pressure re-read does not fit better still. Before the force checks, which would
        # otherwise blame the load cell for forces the model was asked at the wrong lengths
        if not (lengths_wrong or pressures_wrong):
            length_as_read, length_unit = _length_unit_fit(
                free, Fc, Pc, L[::step], lcol, (lo - LENGTH_TOLERANCE * rest, hi + LENGTH_TOLERANCE * rest)
            )
            if length_unit:
                _, pressure_unit = _pressure_unit_fit(free, Fc, Pc, Lc, aligned, pcol, rated_pressure_Pa)
                if pressure_unit is None or length_unit[1] < pressure_unit[1]:
                    base, written = split_unit(lcol)
                    findings.append(Finding("length-unit", (
                        f"{src}: column '{lcol}': the forces fit the muscle's model with {length_unit[1]:.3g} N "
                        f"RMS if the lengths were in {length_unit[0]} against "
                        f"{length_as_read:.3g} N as read in "
                        f"{written}: is the column's unit right? the numbers fit '{base}_{length_unit[0]}'"
                    )))  # fmt: skip
                    lengths_wrong = True
        model = aligned[np.isfinite(aligned)]
        capacity = float(np.max(np.abs(reach[np.isfinite(reach)]), initial=0.0))
        limit = 3.0 * capacity + 50.0
        big = np.abs(F) > limit
        if big.any():
            i = int(np.argmax(big))
            fits = unit_that_fits(float(np.max(np.abs(F))), max(capacity, 1.0), fcol, FORCE_UNITS)
            hint = f"; the numbers fit '{fits}'" if fits else ""
            findings.append(Finding("force-range", (
                f"{src}: {_line(rec, i)}, column '{fcol}': force {F[i]:.4g} N is beyond what the muscle can "
                f"produce at the recorded pressures (at most about {capacity:.4g} N){hint}"
            )))  # fmt: skip
        expected = float(np.ptp(model)) if model.size else 0.0
        spread = float(np.ptp(F))
        model_ok = not (lengths_wrong or pressures_wrong)  # the model read where the muscle was
        dead = (
            spread == 0.0
            # two or three distinct values say 'dead' only over a real recording: any two rows hold two
            or (len(F) >= MIN_SAMPLES and len(np.unique(F[: min(len(F), 100000)])) <= 2)
            or (expected > 5.0 and spread < 0.02 * expected and model_ok)
        )
        # a force beyond the muscle's reach is 'force-range' already; a dead channel has no scale:
        # no unit puts a constant on the model (it was offered 'force_lbf')
        if not big.any() and model_ok and not dead:
            with np.errstate(all="ignore"):  # the same pressures at the resting length
                blocked = np.asarray(free.push(Pc, np.full_like(Pc, rest)), dtype=float)
            scale = _force_scale(Fc, aligned, blocked)
            low, high = FORCE_SCALE_RANGE
            if scale is not None and scale > 0 and expected > 5.0 and not low <= scale <= high:
                fits = unit_that_fits(scale, 1.0, fcol, FORCE_UNITS, within=(0.7, 1.4))
                hint = f"; the numbers fit '{fits}'" if fits else ""
                findings.append(Finding("force-unit", (
                    f"{src}: column '{fcol}': the recorded forces are {scale:.3g} x the muscle's model at the "
                    f"recorded lengths and pressures (least squares where the model pulls or pushes at least "
                    f"{FORCE_SCALE_REGION:.0%} of its blocked force): is the column's "
                    f"unit right, or is --muscle not the muscle that was tested?{hint}"
                )))  # fmt: skip
        # ... and where the model expects no change either (one row repeated, every pressure in the
        # dead band) nothing says the load cell is dead: 'nothing-varies' or the model's range speak
        if dead and expected > 0.0:
            fits = unit_that_fits(spread, expected, fcol, FORCE_UNITS) if spread > 0 else ""
            hint = f" (or the numbers fit '{fits}')" if fits and len(np.unique(F[:1000])) > 2 else ""
            findings.append(Finding("force-dead", (
                f"{src}: column '{fcol}': the force hardly changes (range {spread:.4g} N over {len(F)} samples) "
                f"while the model expects a range of {expected:.4g} N: a dead or disconnected load cell?{hint}"
            )))  # fmt: skip
        # absolute pressure under a gauge header: never below an atmosphere, and the forces fit the
        # model far better an atmosphere lower (a test held above 100 kPa gauge fits as recorded)
        if (
            lowest >= ATMOSPHERE_PA - ABSOLUTE_SLACK_PA
            and expected > 5.0
            and model.size == len(Pc)
            and model_ok
        ):
            with np.errstate(all="ignore"):
                lowered = np.asarray(free.push(np.clip(Pc - ATMOSPHERE_PA, 0.0, None), Lc), dtype=float)
            error_as_read = float(np.sqrt(np.mean((Fc - aligned) ** 2)))
            error_lowered = float(np.sqrt(np.mean((Fc - lowered) ** 2)))
            if error_lowered < ABSOLUTE_ERROR_SHARE * error_as_read:
                findings.append(Finding("pressure-absolute", (
                    f"{src}: column '{pcol}': the pressure never falls below {lowest / 1e3:.4g} kPa, and "
                    f"the forces fit the muscle's model with {error_lowered:.3g} N RMS an atmosphere "
                    f"({ATMOSPHERE_PA / 1e3:.4g} kPa) lower against {error_as_read:.3g} N as recorded: is it an "
                    "absolute pressure? The column must hold gauge pressure (subtract the atmosphere)"
                )))  # fmt: skip
        # a pressure in another unit than its header's: within the rated pressure (else
        # 'pressure-range' says it) the forces fit the model far better read in another unit
        as_read, unit = (
            (0.0, None)
            if not model_ok
            else _pressure_unit_fit(free, Fc, Pc, Lc, aligned, pcol, rated_pressure_Pa)
        )
        if unit:
            findings.append(Finding("pressure-unit", (
                f"{src}: column '{pcol}': the forces fit the muscle's model with {unit[1]:.3g} N RMS if the "
                f"pressures were in {unit[0]} against {as_read:.3g} N as read in {split_unit(pcol)[1]}: "
                f"is the column's unit right? the numbers fit '{split_unit(pcol)[0]}_{unit[0]}'"
            )))  # fmt: skip
        # the sign: where the model's push force rises, the recorded one must not fall
        both = np.isfinite(aligned)
        if model_ok and expected > 5.0 and spread > 0.0 and np.count_nonzero(both) > 10:
            with np.errstate(all="ignore"):
                r = float(np.corrcoef(Fc[both], aligned[both])[0, 1])
            if r < -SIGN_CORRELATION:
                findings.append(Finding("force-sign", (
                    f"{src}: column '{fcol}': the recorded force falls where the model's rises (correlation "
                    f"{r:.2f} over the recorded lengths and pressures): is its sign the other way round "
                    "('force_<unit>' is positive when the muscle pushes its ends apart, 'tension_<unit>' when it "
                    "pulls), or is --muscle not the muscle that was tested?"
                )))  # fmt: skip
            elif abs(r) < FOLLOW_CORRELATION:
                findings.append(Finding("force-model", (
                    f"{src}: column '{fcol}': the recorded force does not follow the muscle's length and "
                    f"pressure (correlation {r:.2f} with the model's force over the recorded lengths and "
                    "pressures, where any muscle's force rises and falls with them): is it the load cell of "
                    "this test, are the rows in order, or is --muscle not the muscle that was tested?"
                )))  # fmt: skip
        if np.ptp(L) == 0.0 and np.ptp(P) == 0.0:
            findings.append(Finding("nothing-varies", (
                f"{src}: columns '{lcol}' and '{pcol}' are both constant: nothing was tested"
            )))  # fmt: skip
        if tension_only:
            threshold = max(5.0, 0.25 * capacity)  # a load-cell zero error passes; real pushing does not
            pushing = F > threshold
            if np.mean(pushing) > 0.05:
                i = int(np.argmax(pushing))
                findings.append(Finding("tension-only", (
                    f"{src}: {_line(rec, i)}, column '{fcol}': the muscle is declared tension-only "
                    f"(--tension-only or the muscle file) but pushes in {np.mean(pushing):.0%} of the samples "
                    f"(e.g. {F[i]:.4g} N, push positive)"
                )))  # fmt: skip
        findings[start:] = _mark_impossible(rec, src, findings[start:])
    return findings


#: the force units a hint may offer: exactly those a header may carry (``force_mN`` was offered for
#: a load cell in mN, and then refused as an unknown unit)
FORCE_UNITS = QUANTITIES["force"]


#: ... judged only where the model force is at least this share of the blocked force at the
#: same pressure: towards its free length a muscle's force falls to zero and the model's relative
#: error grows without bound (a Festo DMSP held at 75 % of its contraction pulls 0.02-0.23 x what
#: the nominal model says)
FORCE_SCALE_REGION = 0.6


def _force_scale(F, model, blocked) -> float | None:
    """The least-squares scale s of ``F ~ s model`` over the samples where the model is
    trustworthy: its force at least ``FORCE_SCALE_REGION`` of the blocked force at the same
    pressure (``blocked``: the model at the resting length), and the muscle actuated. None with
    fewer than 20 such samples (or under 5 % of the recording)."""
    with np.errstate(all="ignore"):
        use = (
            np.isfinite(model) & np.isfinite(F) & np.isfinite(blocked) & (np.abs(blocked) > 0)
            & (model * np.sign(blocked) >= FORCE_SCALE_REGION * np.abs(blocked))
        )  # fmt: skip
    if np.count_nonzero(use) < max(20, 0.05 * len(F)):
        return None
    m, f = model[use], F[use]
    norm = float(np.dot(m, m))
    return float(np.dot(f, m) / norm) if norm > 0 else None


#: No fluidic muscle is pressurised above this (pneumatic ones run under 1 MPa, hydraulic ones
#: under 35 MPa), nor longer than this (the muscle model's own size bound): a recording beyond
#: either is refused even with ``--allow pressure-range`` / ``length-range``, which are for a
#: rating or a range exceeded, not for a gigapascal or a hundred metres.
MAX_PRESSURE_PA = 100e6
MAX_LENGTH_M = SIZE_RANGE_M[1]


def _mark_impossible(rec: Recording, src: str, found: list[Finding]) -> list[Finding]:
    """One recording's findings with the ones no fluidic muscle explains marked ``impossible``: a
    pressure or a length beyond :data:`MAX_PRESSURE_PA` / :data:`MAX_LENGTH_M` (its range or
    unit finding says so, once; one is added if none did)."""
    out = list(found)
    for checks, values, limit, what, unit, scale, key in (
        (("pressure-range",), rec.pressure_Pa, MAX_PRESSURE_PA, "pressure", "MPa", 1e-6, "pressure"),
        (
            ("length-range", "length-unit"),
            rec.length_m,
            MAX_LENGTH_M,
            "length",
            "m",
            1.0,
            "length|displacement",
        ),
    ):
        if not len(values) or float(np.max(values)) <= limit:
            continue
        i = int(np.argmax(values))
        note = (
            f"{what} {values[i] * scale:.4g} {unit} at {_line(rec, i)} cannot be physical for any fluidic "
            f"muscle (above {limit * scale:g} {unit}): not allowable"
        )
        k = next((k for k, f in enumerate(out) if f.check in checks), None)
        if k is None:
            out.append(Finding(checks[0], f"{src}: column '{_column(rec, key)}': {note}", impossible=True))
        else:
            out[k] = Finding(out[k].check, f"{out[k].message}; {note}", impossible=True)
    return out


def _check_name(text: str) -> str:
    """``--allow``'s argparse type: a check's name. A recording's name after ``--allow`` (which
    takes every word that follows it) is told as such, not as an invalid choice."""
    if text in CHECKS:
        return text
    known = ", ".join(CHECKS)
    if Path(text).suffix or Path(text).exists():
        raise argparse.ArgumentTypeError(
            f"'{visible(text)}' is not a check but looks like a file: --allow takes every word after it, so "
            "give the recordings before --allow (or end its checks with --) (checks: " + known + ")"
        )
    raise argparse.ArgumentTypeError(f"unknown check '{visible(text)}' (checks: {known})")


def enforce_plausibility(findings: list[Finding], allow=(), warn=None, flag: str = "--allow") -> None:
    """Raise :class:`PlausibilityError` listing every finding whose check is not in ``allow``;
    tell ``warn`` (default: standard error) each allowed one as ``warning [check]: ...``."""
    warn = warn or (lambda line: print(line, file=sys.stderr))
    allow = set(allow)
    unknown = allow - set(CHECKS)
    if unknown:
        raise ValueError(f"{flag}: unknown check '{sorted(unknown)[0]}' (known: {', '.join(CHECKS)})")
    refused = [f for f in findings if f.check not in allow or f.impossible]
    for f in findings:
        if f.check in allow and not f.impossible:
            warn(f"warning [{f.check}]: {f.message}")
    if refused:
        lines = [f"[{f.check}] {f.message}" for f in refused]
        names = " ".join(sorted({f.check for f in refused if f.check not in allow}))
        raise PlausibilityError(
            "implausible recording(s): " + "; ".join(lines)
            + (f" (if the data are right, pass {flag} {names} to continue with a warning)" if names else "")
        )  # fmt: skip


class PlausibilityWarning(UserWarning):
    """A failed plausibility check the caller allowed (``allow=``): the work goes on, said once."""


def check_for_fit(recordings, muscle, allow=(), where: str = "fit") -> None:
    """The plausibility checks of the ``efam`` commands for the Python entry points
    (``diagnose``, ``calibrate``): raise :class:`PlausibilityError` naming every failed check
    not in ``allow`` (check names, or ``"all"`` to skip them: the commands have run them and
    said what they allowed); an allowed one is a :class:`PlausibilityWarning`. Before, a force
    logged in lbf, a length in mm or a dead load cell went into a Python fit without a word."""
    if isinstance(allow, str) and allow == "all":
        return
    allow = (allow,) if isinstance(allow, str) else tuple(allow)
    findings = check_plausibility(recordings, muscle)
    enforce_plausibility(
        findings, allow=allow, flag=f"{where}: the allow argument with",
        warn=lambda line: warnings.warn(line, PlausibilityWarning, stacklevel=4),
    )  # fmt: skip


# ------------------------------------------------------------------------------- decimation
#: Samples that go into a fit or a diagnosis at most (``--max-samples``): above it the
#: recordings are decimated, so memory and time stay bounded whatever the file's length.
DEFAULT_MAX_SAMPLES = 100_000
#: The fewest samples a fit is made from: a diagnosis from each recording, a calibration from
#: all of them together (a law of four coefficients, the dead band and the braid angle fit
#: anything from fewer).
MIN_SAMPLES = 50


def decimate(recordings, max_samples: int = DEFAULT_MAX_SAMPLES) -> tuple[list[Recording], str]:
    """Keep every k-th sample of every recording, with the smallest k that brings the total to
    at most ``max_samples`` (k = ceil(total / max_samples); each recording keeps its first
    sample). The rule is a stride, not an average: kept samples are real, time stamps and
    hysteresis loops are kept, noise is not filtered. Returns the recordings and a note for the
    user ('' when nothing was dropped)."""
    if max_samples < 1000:
        raise ValueError(f"--max-samples must be at least 1000, got {max_samples}")
    total = sum(len(r) for r in recordings)
    if total <= max_samples:
        return list(recordings), ""
    k = -(-total // max_samples)
    out = [r.subset(slice(None, None, k), decimated_every=k) for r in recordings]
    kept = sum(len(r) for r in out)
    note = (
        f"note: {total} samples decimated to {kept} (every {k}th sample kept; at most {max_samples} "
        "go into the fit, --max-samples changes it)"
    )
    return out, note


# ------------------------------------------------------------------- the commands' input side
def add_recording_arguments(parser) -> None:
    """The flags every command that fits recordings shares (``efam calibrate``, ``diagnose``)."""
    parser.add_argument(
        "--on-bad-rows", choices=BAD_ROW_POLICIES, default="error",
        help="bad CSV rows: stop with an error, or drop them and report which",
    )  # fmt: skip
    parser.add_argument(
        # extend: '--allow a --allow b' allows both (a plain list kept only the last, silently)
        "--allow", nargs="+", action="extend", default=[], metavar="CHECK", type=_check_name,
        help="continue past these failed plausibility checks with a named warning (the flag may be "
        "repeated): "
        + "; ".join(f"{k}: {v}" for k, v in CHECKS.items()) + " (default: none, every check is an error)",
    )  # fmt: skip
    parser.add_argument(
        "--rated-pressure-kPa", type=float, default=DEFAULT_RATED_PRESSURE_PA / 1e3,
        help="the muscle's rated gauge pressure: recorded pressures above it are refused",
    )  # fmt: skip
    parser.add_argument(
        "--max-samples", type=int, default=DEFAULT_MAX_SAMPLES,
        help="samples that go into the fit at most; longer recordings keep every k-th sample",
    )  # fmt: skip


def refuse_copies(recordings: list[Recording], names: list[str] | None = None, prefix: str = "") -> None:
    """Refuse two recordings with the same samples (a copy of a file under another name): a
    second recording of the same test differs at least by its noise, and a copy would count the
    same data twice, halving every error bar it enters. ``names`` (default: each recording's
    source, else its index) name them in the message, after ``prefix``."""
    if names is None:
        names = [r.meta.get("source", f"recordings[{i}]") for i, r in enumerate(recordings)]
    seen: dict[bytes, str] = {}
    for rec, name in zip(recordings, names):
        digest = hashlib.sha256()
        for column in (rec.time_s, rec.length_m, rec.pressure_Pa, rec.force_N):
            digest.update(np.ascontiguousarray(column, dtype=float).tobytes())
        key = digest.digest()
        if key in seen:
            raise RecordingError(
                f"{prefix}{shown_path(name)}: the same samples as {shown_path(seen[key])} (a copy: given "
                "twice, it would count twice)"
            )
        seen[key] = name
    # a copy saved again is not the same floats: fewer digits, another unit (a displacement in
    # mm), its clock shifted. Two recordings of one test still differ by their noise, far more
    # than a re-export's rounding
    for j in range(len(recordings)):
        for i in range(j):
            if _same_test(recordings[i], recordings[j]):
                raise RecordingError(
                    f"{prefix}{shown_path(names[j])}: the same samples as {shown_path(names[i])} to within "
                    f"{COPY_TOLERANCE:.0e} of each column's range (a copy saved again, in other units or with "
                    "its clock shifted: given twice, it would count twice)"
                )


#: two recordings whose every column agrees to this share of its range (the time from each
#: one's start) are one test saved twice: six significant digits round to 5e-7 of a value
COPY_TOLERANCE = 1e-4


def _same_test(a: Recording, b: Recording) -> bool:
    """Whether ``a`` and ``b`` hold the same samples up to a re-export (see :func:`refuse_copies`)."""
    if len(a) != len(b) or len(a) < 2:
        return False
    pairs = (
        (a.time_s - a.time_s[0], b.time_s - b.time_s[0]), (a.length_m, b.length_m),
        (a.pressure_Pa, b.pressure_Pa), (a.force_N, b.force_N),
    )  # fmt: skip
    for x, y in pairs:
        scale = max(float(np.ptp(x)), float(np.ptp(y)), 1e-12)
        if float(np.max(np.abs(x - y))) > COPY_TOLERANCE * scale:
            return False
    return True


def read_for_fit(args, muscle, warn=None) -> list[Recording]:
    """Read ``args.files``, check their physical plausibility against ``muscle`` (errors unless
    ``--allow``), and decimate them to ``--max-samples``: what ``calibrate`` and ``diagnose`` fit.
    Messages use the command line's flag names."""
    warn = warn or (lambda line: print(line, file=sys.stderr))
    rated = args.rated_pressure_kPa
    if not (math.isfinite(rated) and 0 < rated <= 100e3):
        raise ValueError(f"--rated-pressure-kPa must be in (0, 100000] kPa, got {rated:g}")
    if rated * 1e3 <= muscle.deadband_Pa:  # every recorded pressure was then blamed on the data
        raise ValueError(
            f"--rated-pressure-kPa {rated:g} is at or below the muscle's dead band "
            f"{muscle.deadband_Pa / 1e3:.4g} kPa: at its rated pressure it would never be actuated (MPa or bar "
            "written as kPa?)"
        )
    if args.max_samples < 1000:
        raise ValueError(f"--max-samples must be at least 1000, got {args.max_samples}")
    seen: dict = {}
    for name in args.files:
        path = Path(name)
        key = (path.stat().st_dev, path.stat().st_ino) if path.exists() else str(path)
        if key in seen:
            raise RecordingError(
                f"FILE {name}: the same recording as {seen[key]} (given twice, it would count twice)"
            )
        seen[key] = name
    recordings = read_recordings(
        args.files, rest_length_m=muscle.rest_length_m, on_bad_rows=args.on_bad_rows, warn=warn
    )
    refuse_copies(recordings, args.files, prefix="FILE ")
    findings = check_plausibility(recordings, muscle, rated_pressure_Pa=rated * 1e3)
    enforce_plausibility(findings, allow=args.allow, warn=warn)
    recordings, note = decimate(recordings, args.max_samples)
    if note:
        warn(note)
    return recordings
