"""Shared harness of the bad-input corpus (tests/test_robust_*.py).

``run_bad(argv, folder, capsys, *expect)`` runs ``efam argv`` in-process (``efam_mujoco.cli.main``)
inside ``folder`` and asserts what every bad input must give: a non-zero exit, a message on
standard error naming the problem (each regular expression in ``expect``), no traceback, every
file in the folder byte-identical afterwards and no new file (no stray temporaries, no half
outputs), and no MUJOCO_LOG.TXT.
"""

from __future__ import annotations

import json
import os
import re
from contextlib import contextmanager
from pathlib import Path

from efam_mujoco.cli import main


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative path -> bytes), hidden ones included."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not path.is_symlink():
            out[str(path.relative_to(folder))] = path.read_bytes()
        elif path.is_symlink():
            out[str(path.relative_to(folder))] = b"->" + os.readlink(path).encode()
        elif path.is_dir():
            out[str(path.relative_to(folder)) + "/"] = b""
    return out


@contextmanager
def inside(folder: Path):
    previous = Path.cwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(previous)


def run_cli(argv, folder: Path, capsys) -> tuple[int, str, str]:
    """``efam argv`` run in ``folder``: (exit status, stdout, stderr)."""
    capsys.readouterr()
    with inside(folder):
        code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def run_bad(argv, folder: Path, capsys, *expect: str) -> str:
    """Run a bad input; assert the corpus's promises; return standard error."""
    before = snapshot(folder)
    code, out, err = run_cli(argv, folder, capsys)
    assert code != 0, f"exit 0 for a bad input {argv}: {out[-300:]} {err[-300:]}"
    assert "Traceback" not in err and "Traceback" not in out, err
    assert "internal error" not in err, err
    assert err.strip(), "no message"
    for pattern in expect:
        assert re.search(pattern, err, re.IGNORECASE | re.DOTALL), f"{pattern!r} not in: {err}"
    after = snapshot(folder)
    assert after == before, f"files changed: {sorted(set(after) ^ set(before)) or 'contents'}"
    assert not (folder / "MUJOCO_LOG.TXT").exists()
    return err


def strict_load(path: Path):
    """Parse JSON refusing NaN and Infinity tokens (what a standard parser accepts)."""

    def refuse(token):
        raise ValueError(f"non-standard JSON token {token}")

    return json.loads(Path(path).read_text(), parse_constant=refuse)


def csv_text(rows, header="time_s,length_m,pressure_kPa,force_N") -> str:
    return header + "\n" + "\n".join(",".join(f"{v:.9g}" for v in row) for row in rows) + "\n"
