"""Tests for thermocal.constants: CODATA 2018 values and their consistency."""

import math

import pytest
from scipy.optimize import brentq

from thermocal import constants as C


def test_exact_defining_constants():
    # SI 2019 exact values (CODATA 2018).
    assert C.PLANCK_H == 6.62607015e-34
    assert C.SPEED_OF_LIGHT_C == 299792458.0
    assert C.BOLTZMANN_K == 1.380649e-23
    assert C.ZERO_CELSIUS_K == 273.15
    assert C.ABSOLUTE_ZERO_C == -273.15


@pytest.mark.parametrize(
    ("value", "codata_2018"),
    [
        (C.STEFAN_BOLTZMANN_SIGMA, 5.670374419e-8),
        (C.FIRST_RADIATION_C1L, 1.191042972e-16),
        (C.SECOND_RADIATION_C2, 1.438776877e-2),
        (C.WIEN_B, 2.897771955e-3),
    ],
)
def test_derived_constants_match_codata_2018(value, codata_2018):
    # CODATA prints ten significant digits.
    assert value == pytest.approx(codata_2018, rel=1e-9)


def test_stefan_boltzmann_from_radiation_constants():
    # sigma = pi * (pi^4 / 15) c1L / c2^4 (exitance = pi x radiance), a route through c1L and c2.
    sigma = math.pi**5 * C.FIRST_RADIATION_C1L / (15.0 * C.SECOND_RADIATION_C2**4)
    assert sigma == pytest.approx(C.STEFAN_BOLTZMANN_SIGMA, rel=1e-13)


def test_wien_constant_from_second_radiation_constant():
    # The peak of B(lambda) solves x = 5 (1 - exp(-x)) with x = c2 / (lambda T).
    x = brentq(lambda x: x - 5.0 * (1.0 - math.exp(-x)), 4.0, 6.0, xtol=1e-15)
    assert C.SECOND_RADIATION_C2 / x == pytest.approx(C.WIEN_B, rel=1e-10)


def test_tau2_band():
    assert C.TAU2_BAND_M == (7.5e-6, 13.5e-6)
    lo, hi = C.TAU2_BAND_M
    assert 0 < lo < hi
