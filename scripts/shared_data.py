"""Where the project's shared data lives: ``../shared`` beside the checkout, or ``$EFAM_SHARED_DIR``.

The shared folder (the paper, the real Festo recordings) is not part of the package. Scripts,
benchmarks and tests that read it find it here and skip cleanly when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Environment variable that overrides the location of the shared folder.
SHARED_ENV = "EFAM_SHARED_DIR"
CHECKOUT = Path(__file__).resolve().parents[1]


def shared_dir() -> Path:
    """The shared folder: ``$EFAM_SHARED_DIR`` if set, else ``../shared`` from the repository root."""
    override = os.environ.get(SHARED_ENV)
    return Path(override) if override else CHECKOUT.parent / "shared"


def festo_dir() -> Path:
    """The real Festo DMSP recordings (``EFAM_FESTO_DATA`` overrides just this folder)."""
    override = os.environ.get("EFAM_FESTO_DATA")
    return Path(override) if override else shared_dir() / "data" / "real" / "festo_dmsp"
