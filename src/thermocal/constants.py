"""Physical constants used by thermocal, each with its source.

All values are SI. The defining constants of the SI (``h``, ``c``, ``k_B``) are exact since the 2019
redefinition and are identical in CODATA 2018 and CODATA 2022; they are taken from
:mod:`scipy.constants`, which tabulates CODATA. The derived radiation constants (``c1L``, ``c2``,
``sigma``) are computed here from the exact defining constants, so they are exact to double
precision; CODATA 2018 lists the same values rounded to ten significant digits
(``c1L = 1.191042972e-16 W m^2 sr^-1``, ``c2 = 1.438776877e-2 m K``,
``sigma = 5.670374419e-8 W m^-2 K^-4``).
"""

from __future__ import annotations

import math
from typing import Final

import scipy.constants as _sc

#: Planck constant ``h`` in J·s (exact, SI 2019; CODATA 2018 via :data:`scipy.constants.h`).
PLANCK_H: Final[float] = float(_sc.h)

#: Speed of light in vacuum ``c`` in m·s⁻¹ (exact, SI 2019; CODATA 2018 via
#: :data:`scipy.constants.c`).
SPEED_OF_LIGHT_C: Final[float] = float(_sc.c)

#: Boltzmann constant ``k_B`` in J·K⁻¹ (exact, SI 2019; CODATA 2018 via
#: :data:`scipy.constants.k`).
BOLTZMANN_K: Final[float] = float(_sc.k)

#: Stefan–Boltzmann constant ``sigma = 2 pi^5 k^4 / (15 h^3 c^2)`` in W·m⁻²·K⁻⁴ (derived from the
#: exact constants; CODATA 2018: 5.670374419e-8).
STEFAN_BOLTZMANN_SIGMA: Final[float] = (
    2.0 * math.pi**5 * BOLTZMANN_K**4 / (15.0 * PLANCK_H**3 * SPEED_OF_LIGHT_C**2)
)

#: First radiation constant for spectral radiance ``c1L = 2 h c^2`` in W·m²·sr⁻¹ (derived from the
#: exact constants; CODATA 2018: 1.191042972e-16).
FIRST_RADIATION_C1L: Final[float] = 2.0 * PLANCK_H * SPEED_OF_LIGHT_C**2

#: Second radiation constant ``c2 = h c / k_B`` in m·K (derived from the exact constants;
#: CODATA 2018: 1.438776877e-2).
SECOND_RADIATION_C2: Final[float] = PLANCK_H * SPEED_OF_LIGHT_C / BOLTZMANN_K

#: Wien wavelength displacement law constant ``b`` in m·K (CODATA 2018 via
#: :data:`scipy.constants.Wien`; 2.897771955e-3).
WIEN_B: Final[float] = float(_sc.Wien)

#: Zero degrees Celsius in kelvin (exact by definition of the Celsius scale;
#: :data:`scipy.constants.zero_Celsius`).
ZERO_CELSIUS_K: Final[float] = float(_sc.zero_Celsius)

#: Absolute zero in degrees Celsius (exact, ``-ZERO_CELSIUS_K``).
ABSOLUTE_ZERO_C: Final[float] = -ZERO_CELSIUS_K

#: Spectral band of a FLIR Tau2 long-wave core, ``(lower, upper)`` wavelength in m (FLIR Tau2
#: product specification: 7.5–13.5 µm).
TAU2_BAND_M: Final[tuple[float, float]] = (7.5e-6, 13.5e-6)

__all__ = [
    "ABSOLUTE_ZERO_C",
    "BOLTZMANN_K",
    "FIRST_RADIATION_C1L",
    "PLANCK_H",
    "SECOND_RADIATION_C2",
    "SPEED_OF_LIGHT_C",
    "STEFAN_BOLTZMANN_SIGMA",
    "TAU2_BAND_M",
    "WIEN_B",
    "ZERO_CELSIUS_K",
]
