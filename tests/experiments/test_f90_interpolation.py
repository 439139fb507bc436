"""sigma_F90 = the smallest prior whose fraction inside reaches P (paper Sect. 3.3)."""

import math

import numpy as np
import pytest

from mcsweep.experiments.pencil_beam import sigma_f90_from_curve

GRID = np.geomspace(0.01, 1000, 41)


def test_log_interpolation_closed_form():
    # Fraction rising linearly in log10(sigma): f = 0.5 + 0.1 log10(sigma / 0.1) crosses
    # 0.9 exactly at sigma = 0.1 * 10**4 = 1000 ... use a steeper curve crossing mid-grid:
    frac = np.clip(0.5 + 0.2 * np.log10(GRID / 0.1), 0, 1)  # crosses 0.9 at sigma = 10**1 = 10 mas
    s, flag = sigma_f90_from_curve(GRID, frac, 0.9, "log")
    assert flag == "ok"
    assert s == pytest.approx(10.0, rel=1e-9)
    # A crossing between grid points (P = 0.87 -> log10(s/0.1) = 1.85 -> s = 7.0795 mas).
    s, _ = sigma_f90_from_curve(GRID, frac, 0.87, "log")
    assert s == pytest.approx(0.1 * 10**1.85, rel=1e-9)
    s, _ = sigma_f90_from_curve(GRID, frac, 0.87, "none")
    assert s == pytest.approx(GRID[np.flatnonzero(frac >= 0.87)[0]])


def test_smallest_crossing_wins_and_flags():
    frac = np.where(GRID < 1, 0.5, 0.95)
    frac[-3:] = 0.85  # falls below P again for very loose priors: the first crossing counts
    s, flag = sigma_f90_from_curve(GRID, frac, 0.9)
    assert flag == "ok" and GRID[15] < s <= 1.0 + 1e-12
    s, flag = sigma_f90_from_curve(GRID, np.full(41, 0.2), 0.9)
    assert flag == "never_reached" and math.isnan(s)
    s, flag = sigma_f90_from_curve(GRID, np.full(41, 0.95), 0.9)
    assert flag == "below_grid" and s == GRID[0]
