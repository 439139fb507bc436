"""The galaxy model's BP - RP colours and counts per colour against Gaia DR3's G < 10 stars.

Per 1-mag G bin (G = 5-10) and |b| band (0-15, 15-35, 35-90 deg), the Gaia DR3 sources of
:func:`mcsweep.population.gaia_bright.gaia_sources` with both BP and RP against a draw of the
model over the whole sky (:func:`colour_comparison`):

* the 10 / 50 / 90 % quantiles of BP - RP (target: within :data:`QUANTILE_TOL`);
* the share redder than :data:`RED_EDGE` (target: within :data:`RED_SHARE_TOL`);
* the number of stars in each of DR3's BP - RP terciles of that cell (target: within
  :data:`COUNT_TOL`), the model's being its expected count in the cell times the share of
  its drawn stars in the tercile.

The two thicknesses the model sets against these counts (``giant_thickness_factor`` and
``young_disc_thickness_factor``, :mod:`mcsweep.population.galaxy.parameters`) come from
:func:`fit_thicknesses`: the grid point with the smallest RMS of ln(model / DR3) over the 45
tercile counts. Only the counts enter the fit; Hipparcos parallaxes and proper motions are
kept for validation (:mod:`.hipparcos_population`).

Usage::

    python -m mcsweep.validation.dr3_colours [--out FILE.csv]
    python -m mcsweep.validation.dr3_colours --fit --giant 0.5,0.6,0.7 --young 0.5,0.7,0.9
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from scipy.optimize import brentq

from ..errors import UserInputError
from ..population import GalaxyModel
from .population_validation import GUMS_BEAM_COUNT
from .published_counts import count_comparison

__all__ = ["G_BINS", "B_BANDS", "QUANTILE_TOL", "RED_SHARE_TOL", "RED_EDGE", "COUNT_TOL", "TERCILES",
           "colour_comparison", "targets_met", "tercile_misfit", "thin_factor_for_beam", "fit_thicknesses", "main"]

#: Lower edges of the 1-mag G bins, mag (G < 10: the bundled DR3 stars' limit).
G_BINS = (5, 6, 7, 8, 9)
#: |b| bands, deg ([lo, hi)).
B_BANDS = ((0, 15), (15, 35), (35, 90))
#: Targets: quantiles of BP - RP within this, mag.
QUANTILE_TOL = 0.1
#: Share of stars redder than :data:`RED_EDGE` within this (absolute).
RED_SHARE_TOL = 0.05
#: BP - RP of the red share, mag.
RED_EDGE = 1.2
#: Counts per DR3 BP - RP tercile within this fraction.
COUNT_TOL = 0.10
TERCILES = ("blue", "mid", "red")
#: The paper's Table 1 beam: (l, b, radius) in deg (Michalik et al. 2015, Table 1).
TABLE1_BEAM = (245.7, 46.5, 1.0)


def _dr3():
    from ..population.gaia_bright import gaia_sources

    d = gaia_sources()
    return d.assign(bp_rp=d.phot_bp_mean_mag - d.phot_rp_mean_mag).dropna(subset=["bp_rp"])


def colour_comparison(model=None, *, max_stars=100_000, seed=0, dr3=None):
    """Model vs Gaia DR3 per G bin x |b| band (module notes).

    Parameters
    ----------
    model : GalaxyModel, optional
        The model (default: ``GalaxyModel()``).
    max_stars : int
        Stars drawn per G bin over the whole sky (seed ``[seed, G]``).
    dr3 : pandas.DataFrame, optional
        The DR3 stars (columns ``phot_g_mean_mag``, ``b``, ``bp_rp``); read once by default.

    Returns
    -------
    pandas.DataFrame
        One row per cell: ``g``, ``b``; ``dr3_q10`` ... ``model_q90`` [mag], ``dr3_red``,
        ``model_red``; ``dr3_n_blue`` ... ``model_n_red`` (stars per DR3 tercile).
    """
    model = model or GalaxyModel()
    d = _dr3() if dr3 is None else dr3
    rows = []
    for g0 in G_BINS:
        m = model.sample_sky(g0, g0 + 1, np.random.default_rng([seed, g0]), max_stars=max_stars)
        per_star = m.attrs["expected_count"] / max(len(m), 1)
        dg = d[(d.phot_g_mean_mag >= g0) & (d.phot_g_mean_mag < g0 + 1)]
        for b0, b1 in B_BANDS:
            cd = dg[dg.b.abs().between(b0, b1, inclusive="left")].bp_rp.to_numpy()
            cm = m[m.b.abs().between(b0, b1, inclusive="left")].bp_rp.to_numpy()
            edges = np.r_[-np.inf, np.quantile(cd, [1 / 3, 2 / 3]), np.inf]
            row = dict(g=f"{g0}-{g0 + 1}", b=f"{b0}-{b1}")
            for who, c, scale in (("dr3", cd, 1.0), ("model", cm, per_star)):
                q = np.quantile(c, [0.1, 0.5, 0.9])
                row.update({f"{who}_q10": q[0], f"{who}_q50": q[1], f"{who}_q90": q[2],
                            f"{who}_red": float(np.mean(c > RED_EDGE))})
                n = np.histogram(c, edges)[0] * scale
                row.update({f"{who}_n_{t}": float(v) for t, v in zip(TERCILES, n)})
            rows.append(row)
    return pd.DataFrame(rows)


def targets_met(t):
    """Per cell of :func:`colour_comparison`, whether each target is met (columns ``q10``,
    ``q50``, ``q90``, ``red``, ``counts``)."""
    out = pd.DataFrame({"g": t.g, "b": t.b})
    for q in ("q10", "q50", "q90"):
        out[q] = (t[f"model_{q}"] - t[f"dr3_{q}"]).abs() <= QUANTILE_TOL
    out["red"] = (t.model_red - t.dr3_red).abs() <= RED_SHARE_TOL
    ratio = np.stack([t[f"model_n_{k}"] / t[f"dr3_n_{k}"] for k in TERCILES], axis=1)
    out["counts"] = np.all(np.abs(ratio - 1.0) <= COUNT_TOL, axis=1)
    return out


def tercile_misfit(t):
    """RMS over cells and terciles of ln(model / DR3) counts (the fit's objective)."""
    r = np.stack([np.log(t[f"model_n_{k}"] / t[f"dr3_n_{k}"]) for k in TERCILES])
    return float(np.sqrt(np.mean(r ** 2)))


def thin_factor_for_beam(params=None, *, target=GUMS_BEAM_COUNT):
    """The ``thin_disc_scale_height_factor`` at which the paper's Table 1 beam (1 deg around
    (l, b) = (245.7, 46.5) deg, G = 14.5-15.5) holds ``target`` stars, the other parameters
    ``params``: the rule that factor was set by (:data:`mcsweep.population.galaxy.parameters.
    THIN_DISC_THICKNESS_FACTOR`), kept while the other thicknesses move. To 0.005."""
    params = dict(params or {})

    def excess(f):
        return GalaxyModel(params, thin_disc_scale_height_factor=f).expected_count(
            *TABLE1_BEAM, 14.5, 15.5) - target

    return round(float(brentq(excess, 0.8, 2.0, xtol=0.001)), 3)


def fit_thicknesses(giant, young, thin=None, *, max_stars=40_000, seed=0, **params):
    """:func:`tercile_misfit` on the grid ``giant`` x ``young`` (x ``thin``) of
    ``giant_thickness_factor``, ``young_disc_thickness_factor`` (and
    ``thin_disc_scale_height_factor``; without ``thin``, the one
    :func:`thin_factor_for_beam` gives at each point), the other model parameters ``params``.

    Each row also carries what the thin-disc factor is held to (the bars of
    :mod:`.published_counts`): ``beam`` (the Table 1 beam's expected count; GUMS 458, 10 %)
    and ``worst_count`` (the largest |model / Gaia DR3 - 1| of the all-sky counts per 1-mag G
    bin at G = 4-13; 8 %). Returns a DataFrame sorted by the misfit, best first."""
    d = _dr3()
    rows = []
    for gt, yf, th in itertools.product(giant, young, [None] if thin is None else thin):
        p = dict(params, giant_thickness_factor=gt, young_disc_thickness_factor=yf)
        p["thin_disc_scale_height_factor"] = thin_factor_for_beam(p) if th is None else th
        model = GalaxyModel(p)
        t = colour_comparison(model, max_stars=max_stars, seed=seed, dr3=d)
        met = targets_met(t)
        counts = count_comparison(model, list(range(4, 14))).ratio_gaia
        rows.append(dict(giant_thickness_factor=gt, young_disc_thickness_factor=yf,
                         thin_disc_scale_height_factor=p["thin_disc_scale_height_factor"],
                         misfit=tercile_misfit(t), beam=model.expected_count(*TABLE1_BEAM, 14.5, 15.5),
                         worst_count=float(np.abs(counts - 1.0).max()),
                         **{f"met_{k}": int(met[k].sum()) for k in ("q10", "q50", "q90", "red", "counts")}))
    return pd.DataFrame(rows).sort_values("misfit", ignore_index=True)


def _floats(text, option):
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(v > 0 for v in values):
        raise UserInputError(f"{option}={text!r} is not accepted; expected comma-separated positive factors")
    return values


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m mcsweep.validation.dr3_colours", description=__doc__.split("\n")[0])
    ap.add_argument("--fit", action="store_true", help="grid of the two thickness factors")
    ap.add_argument("--giant", default="0.45,0.6,0.75,1.0")
    ap.add_argument("--young", default="0.5,0.7,1.0")
    ap.add_argument("--thin", default=None, help="thin-disc factors (default: each point's Table 1 beam rule)")
    ap.add_argument("--max-stars", type=int, default=None)
    ap.add_argument("--out", help="write the table as CSV")
    a = ap.parse_args(argv)
    try:
        # a bad --out ends in one line before the draws, not in a traceback after them
        if a.out and not os.access(Path(a.out).resolve().parent, os.W_OK):
            raise UserInputError(f"--out={a.out!r} is not accepted; expected a file in an existing, "
                                 "writable folder")
        if a.fit:
            thin = None if a.thin is None else _floats(a.thin, "--thin")
            t = fit_thicknesses(_floats(a.giant, "--giant"), _floats(a.young, "--young"), thin,
                                max_stars=a.max_stars or 40_000)
        else:
            t = colour_comparison(max_stars=a.max_stars or 100_000)
            t = t.merge(targets_met(t), on=["g", "b"], suffixes=("", "_met"))
    except UserInputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    with pd.option_context("display.width", 250, "display.max_columns", 40):
        print(t.round(3).to_string(index=False))
    if a.out:
        t.to_csv(a.out, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
