"""Calibration: identify a muscle's model from bench recordings (issue 4).

Public API (see docs/calibration.md):

* :func:`fit_law` (muscle, recordings, law, fit_deadband=True, ...) -> :class:`LawFit`
* :func:`calibrate` (recordings, muscle, laws="all", ...) -> :class:`Calibration`
* :func:`paper_baseline` / :func:`fit_law_nelder_mead`: the paper's fminsearch procedure
* :func:`synthesize`, :func:`recovery_error`: recordings from a known model (the paper's protocol)
* :func:`fit_blocked`, :func:`blocked_points`: Sec. 4.3-4.4 on their own
* :func:`register_cli`: the ``efam calibrate`` subcommand
"""

from .baseline import fit_law_nelder_mead, paper_baseline
from .blocked import BlockedForceFit, blocked_points, braid_angle_from_slope, fit_blocked
from .cli import register_cli
from .core import Calibration, calibrate, folds, geometry_from_blocked
from .data import comparison_points, pool
from .fit import LawFit, Problem, eq14_table, fit_law
from .synth import PAPER_PRESSURES_PA, recovery_error, synthesize

__all__ = [
    "LawFit", "fit_law", "Calibration", "calibrate", "paper_baseline", "fit_law_nelder_mead",
    "BlockedForceFit", "fit_blocked", "blocked_points", "braid_angle_from_slope", "geometry_from_blocked",
    "folds", "pool", "comparison_points", "Problem", "eq14_table", "synthesize", "recovery_error",
    "PAPER_PRESSURES_PA", "register_cli",
]  # fmt: skip
