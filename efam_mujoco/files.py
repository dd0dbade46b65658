"""Writing user-visible files safely: a failed or interrupted write never leaves a half file."""

from __future__ import annotations

import json
from pathlib import Path


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write to ``path.tmp`` then rename over ``path`` (atomic on one file system)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(text)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def write_json_atomic(path: str | Path, doc) -> Path:
    return write_text_atomic(path, json.dumps(doc, indent=1) + "\n")
