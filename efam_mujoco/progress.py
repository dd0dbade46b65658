"""Progress bars for anything that can run longer than a few seconds.

One place decides how progress is shown: a ``tqdm`` bar on standard error when it is a terminal,
nothing otherwise (CI logs, pipes, tests), unless ``EFAM_PROGRESS=1`` forces it on or
``EFAM_PROGRESS=0`` forces it off.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from tqdm.auto import tqdm

T = TypeVar("T")


def progress_enabled() -> bool:
    """Whether bars are shown: ``$EFAM_PROGRESS`` if set (1/0), else whether stderr is a terminal."""
    forced = os.environ.get("EFAM_PROGRESS")
    if forced is not None:
        return forced.strip() not in ("", "0", "false", "no")
    return sys.stderr.isatty()


def progress(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate over ``items`` with a progress bar named ``description`` (quiet when not a terminal)."""
    return iter(
        tqdm(
            items, desc=description, total=total, disable=not progress_enabled(), leave=False, file=sys.stderr
        )
    )
