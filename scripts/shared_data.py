"""Where the project's shared data lives: ``../shared`` beside the checkout, or ``$EFAM_SHARED_DIR``.

The shared folder (the paper, the real Festo recordings) is not part of the package. Scripts,
benchmarks and tests that read it find it here and skip cleanly when it is absent. A variable
that is set names the folder on purpose: a script then refuses (:func:`festo_override_problem`)
a folder without the data instead of skipping as if no data were meant.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Environment variable that overrides the location of the shared folder.
SHARED_ENV = "EFAM_SHARED_DIR"
#: Environment variable that overrides the location of the Festo recordings alone.
FESTO_ENV = "EFAM_FESTO_DATA"
#: What the Festo data folder holds (the scripts read these).
FESTO_FILES = ("recordings.json", "recordings/")
CHECKOUT = Path(__file__).resolve().parents[1]


def shared_dir() -> Path:
    """The shared folder: ``$EFAM_SHARED_DIR`` if set, else ``../shared`` from the repository root."""
    override = os.environ.get(SHARED_ENV)
    return Path(override) if override else CHECKOUT.parent / "shared"


def festo_dir() -> Path:
    """The real Festo DMSP recordings (``EFAM_FESTO_DATA`` overrides just this folder)."""
    override = os.environ.get(FESTO_ENV)
    return Path(override) if override else shared_dir() / "data" / "real" / "festo_dmsp"


def festo_override_problem(required=FESTO_FILES) -> str:
    """What is wrong with the Festo data folder an environment variable names ('' when no
    variable is set, or the folder holds every one of ``required``; a name ending in '/' is a
    folder). Without a variable an absent ``../shared`` is skipped by the caller; with one, a
    folder that is not the data folder is the user's mistake, not "no data"."""
    for name in (FESTO_ENV, SHARED_ENV):
        value = os.environ.get(name)
        if value:
            break
    else:
        return ""
    folder = festo_dir()
    where = f"${name} = {value}" + ("" if name == FESTO_ENV else f": its Festo data folder {folder}")
    if not folder.is_dir():
        return f"{where} {'is not a folder' if folder.exists() else 'does not exist'}"
    missing = [
        f for f in required if not ((folder / f).is_dir() if f.endswith("/") else (folder / f).is_file())
    ]
    if not missing:
        return ""
    fix = (
        f"point {FESTO_ENV} at the folder that holds them (shared/data/real/festo_dmsp)"
        if name == FESTO_ENV
        else f"point {SHARED_ENV} at the shared folder (the one holding data/real/festo_dmsp)"
    )
    return f"{where} is not the Festo DMSP data folder: it has no {', '.join(missing)}; {fix}, or unset it"
