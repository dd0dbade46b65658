"""The diagnosis on degenerate but possible inputs: an answer, or an error that names the problem;
never a numerical library's message (a matrix's leading minor, a math domain error)."""

from __future__ import annotations

import numpy as np
import pytest

from efam_mujoco.diagnose import diagnose
from efam_mujoco.diagnose import virtual_bench as V
from efam_mujoco.diagnose.select import MIN_NOISE_N, Engine, noise_floor
from efam_mujoco.musclefile import load_muscle
from efam_mujoco.recordings import PlausibilityError, Recording


def test_a_training_matrix_rounding_left_indefinite_is_solved():
    # a training fold's normal matrix is the total less the held-out fold's; a column whose size
    # sits nearly all in one fold loses its digits there and the difference can come out
    # indefinite (here an eigenvalue of -0.001 on a unit diagonal): the bounded solve still
    # answers, inside its bounds, and on a positive definite matrix it is the exact solution
    G = np.array([[1.0, 1.001], [1.001, 1.0]])
    b = np.array([1.0, 0.5])
    lo, hi = np.array([-10.0, -10.0]), np.array([10.0, 10.0])
    theta = Engine._solve(G, b, lo, hi)
    assert np.all(np.isfinite(theta)) and np.all(theta >= lo) and np.all(theta <= hi)
    good = np.array([[2.0, 0.3], [0.3, 1.0]])
    assert Engine._solve(good, b, lo, hi) == pytest.approx(np.linalg.solve(good, b), rel=1e-6)


def test_normal_equations_that_overflowed_are_refused_by_what_they_mean():
    G = np.array([[1.0, np.inf], [np.inf, 1.0]])
    with pytest.raises(ArithmeticError, match="overflowed.*time column's unit"):
        Engine._solve(G, np.ones(2), -np.ones(2), np.ones(2))


def test_a_test_timed_a_hundred_times_too_slow_is_diagnosed():
    # the time column of a clean 1.7 min test read as 2.8 h (a unit mix-up the time check lets
    # through: one sample every 1.5 s is a slow recorder's rate): an accelerating drift's column
    # then sits nearly all in the last fold and a training matrix came out indefinite
    # ("12-th leading minor of the array is not positive definite")
    case = V.draw_case(424242, "isobaric", "clean")
    rec = V.make(case)
    slow = Recording(rec.time_s * 100.0, rec.length_m, rec.pressure_Pa, rec.force_N, meta=dict(rec.meta))
    d = diagnose([slow], load_muscle(case.base_name), next_experiment=False)
    assert d.verdict is not None and np.isfinite(d.heldout_rms_before_N)


def test_a_recording_where_nothing_varies_gets_a_finite_noise_floor():
    # length, pressure and force all constant (the plausibility checks refuse it unless the
    # user allows it): the residual is exactly zero, and a zero noise floor made every
    # chi-square infinite ("float division by zero"), a rounding-negative sum of squares a
    # "math domain error"
    assert noise_floor(0.0, []) == MIN_NOISE_N
    muscle = load_muscle("FAM1")
    n = 2000
    t = np.arange(n) * 0.01
    rec = Recording(t, np.full(n, muscle.rest_length_m), np.full(n, 200e3), np.full(n, 12.0))
    with pytest.raises(PlausibilityError, match=r"\[nothing-varies\]"):  # refused by default, as the CLI does
        diagnose([rec], muscle, next_experiment=False)
    d = diagnose([rec], muscle, next_experiment=False, allow="all")
    assert d.noise_N >= MIN_NOISE_N and np.isfinite(d.heldout_rms_before_N)
