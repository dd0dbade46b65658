"""Stress laws: the paper's equations, their derivatives, bounds and Drucker stability."""

import numpy as np
import pytest

from efam_mujoco import LAW_NAMES, StressLaw, StressLawError, load_muscle
from efam_mujoco.stress import LAWS

STABLE = {
    "linear": (1.766e6, 1.5717),
    "polynomial": (2.367e6, 1.9749, -1822118.0, 1151902.0),
    "exponential_decay": (1.479e6, 1.9771, 121646.0, 13.0762),
    "exponent": (0.538e6, 1.9782, 0.5061, 1.3539),
    "sigmoid": (1.5e6, 2.0, 1.2e5, 12.0),
    "arccot": (1.5e6, 2.0, 1.2e5, 12.0),
}


@pytest.mark.parametrize("name", LAW_NAMES)
def test_slope_is_the_strain_derivative(name):
    law = StressLaw(name, STABLE[name])
    eps = np.array([-0.4, -0.1, 0.05, 0.3, 1.2])
    h = 1e-6
    numeric = (law(eps + h, 3e5) - law(eps - h, 3e5)) / (2 * h)
    np.testing.assert_allclose(law.slope(eps, 3e5), numeric, rtol=1e-6)


@pytest.mark.parametrize("name", LAW_NAMES)
def test_zero_strain_zero_stress(name):
    assert StressLaw(name, STABLE[name])(0.0, 5e5) == 0.0


def test_paper_equations_by_hand():
    eps, P = 0.2, 3e5
    E1, E2, E3, E4 = STABLE["exponential_decay"]
    assert StressLaw("exponential_decay", STABLE["exponential_decay"])(eps, P) == pytest.approx(
        (E1 + E2 * P) * eps + E3 * (1 - np.exp(-E4 * eps))
    )
    E1, E2, E3, E4 = STABLE["exponent"]
    assert StressLaw("exponent", STABLE["exponent"])(-eps, P) == pytest.approx(
        -(E1 + E2 * P) * eps - E1 * (eps**E3 + eps**E4)  # sign(e)|e|^p for negative strain (Eq. 21)
    )


@pytest.mark.parametrize("name", ["sigmoid", "arccot"])
def test_future_work_laws_saturate_at_E3_and_stay_odd(name):
    E1, E2, E3, E4 = STABLE[name]
    law = StressLaw(name, (E1, 0.0, E3, E4))
    far = 1e4 / E4
    transient = law(far, 0.0) - E1 * far
    assert transient == pytest.approx(E3, rel=1e-3)
    assert law(-0.3, 0.0) == pytest.approx(-law(0.3, 0.0))


def test_polynomial_drucker_check_finds_negative_slope():
    # Eq. 18: E1 + 2 E3 eps + 3 E4 eps^2 > 0; with E4 = 0 and E3 < 0 the slope goes negative
    law = StressLaw("polynomial", (1e6, 1.0, -2e6, 0.0))
    law.check_stable(-0.2, 0.2)  # slope at 0.2 is 0.2 MPa: fine
    with pytest.raises(StressLawError, match="Drucker"):
        law.check_stable(-0.2, 0.5)  # slope at 0.5 is -1 MPa


def test_paper_polynomial_is_stable_over_fam1_range():
    muscle = load_muscle("fam1", "polynomial")
    assert muscle.stress.min_slope(*muscle.strain_range()) > 0


@pytest.mark.parametrize(
    "name, coefficients, key",
    [
        ("linear", (-1e6, 1.0), "E1_Pa"),
        ("linear", (1e6, -1.0), "E2"),
        ("exponential_decay", (1e6, 1.0, -5.0, 3.0), "E3_Pa"),
        ("exponential_decay", (1e6, 1.0, 5.0, 0.0), "E4"),
        ("exponent", (1e6, 1.0, 1.2, 2.0), "E3"),
        ("exponent", (1e6, 1.0, 0.5, 0.9), "E4"),
        ("sigmoid", (1e6, 1.0, 1e5, -1.0), "E4"),
    ],
)
def test_bounds_violations_name_the_coefficient(name, coefficients, key):
    with pytest.raises(StressLawError, match=key):
        StressLaw(name, coefficients)


def test_unknown_law_and_wrong_count():
    with pytest.raises(StressLawError, match="unknown stress law 'ogden'"):
        StressLaw("ogden", (1.0, 2.0))
    with pytest.raises(StressLawError, match="takes 4 coefficients"):
        StressLaw("polynomial", (1.0, 2.0))


def test_from_dict_names_missing_and_unknown_keys():
    with pytest.raises(StressLawError, match="missing coefficient key 'E2'"):
        StressLaw.from_dict("linear", {"E1_Pa": 1e6})
    with pytest.raises(StressLawError, match="unknown coefficient key 'E1'"):
        StressLaw.from_dict("linear", {"E1": 1e6, "E2": 1.0})


def test_search_boxes_sit_inside_hard_bounds():
    for law in LAWS.values():
        for (lo, hi), (blo, bhi, _, _) in zip(law.search, law.bounds):
            assert blo <= lo < hi <= bhi
