"""Cone cells: exact areas, uniform sampling, membership."""

import numpy as np
import pytest

from mcsweep.population.sky import cone_cells, in_cone

AREA_REL_TOL = 1e-12
UNIFORM_ABS_TOL = 0.01   # fraction of 40000 uniform points (binomial sigma 0.0025)


@pytest.mark.parametrize("radius", [0.3, 1.0, 7.5, 60.0, 180.0, 250.0])
def test_cells_cover_the_cone_exactly(radius):
    g = cone_cells(245.7, 46.5, radius, min(max(radius / 2, 0.05), 5.0))
    cap = 2 * np.pi * (1 - np.cos(np.radians(min(radius, 180.0))))
    assert g.solid_angle_sr.sum() == pytest.approx(cap, rel=AREA_REL_TOL)
    assert in_cone(g.l_deg, g.b_deg, 245.7, 46.5, radius).all()


def test_samples_are_uniform_inside_the_cone(rng):
    r = 2.0
    g = cone_cells(10.0, -60.0, r, 0.5)
    p = g.solid_angle_sr / g.solid_angle_sr.sum()
    cell = rng.choice(p.size, size=40000, p=p)
    l, b = g.sample(cell, rng.random(cell.size), rng.random(cell.size))
    assert in_cone(l, b, 10.0, -60.0, r).all()
    inner = in_cone(l, b, 10.0, -60.0, r / 2).mean()
    expect = (1 - np.cos(np.radians(r / 2))) / (1 - np.cos(np.radians(r)))
    assert inner == pytest.approx(expect, abs=UNIFORM_ABS_TOL)


def test_in_cone_whole_sky_and_edges():
    assert in_cone(np.array([0.0, 180.0]), np.array([-90.0, 0.0]), 0, 90, 180).all()
    assert not in_cone(np.array([12.0]), np.array([0.0]), 10.0, 0.0, 1.0)[0]
    assert in_cone(np.array([10.9]), np.array([0.0]), 10.0, 0.0, 1.0)[0]
