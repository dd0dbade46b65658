"""Machine set-up shared by the benchmark scripts (imported from the script's own folder)."""

from __future__ import annotations

import os


def pin_one_core() -> str:
    """Pin this process to one CPU (the lowest it may use) so a 'one core' timing means one core;
    returns what was done, for the results JSON."""
    if hasattr(os, "sched_setaffinity"):
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        return f"cpu {cpu}"
    return "not pinned (no sched_setaffinity)"
