"""The galaxy model's bright stars against Hipparcos 2 per |b| band: counts, parallaxes, proper motions.

For G = 6-7 and 7-8 (Hipparcos is nearly complete at G = 6-7 away from the plane; in the plane
Gaia DR3 holds 17 % more, red stars beyond its Survey limit: :func:`gaia_band_counts`) and the
real-sky validation's |b| bands (0-15, 15-35, 35-90 deg): the number of stars, the 90th
percentile parallax and the median total proper motion, model over Hipparcos. The model's
values come from ``n_draw`` stars drawn from its density (seeded), its counts from its
expectation; Hipparcos' from the catalogue (G derived as in :mod:`mcsweep.population.hipparcos`;
its parallax errors, 0.5-1 mas, are left in).

By absolute magnitude (``--by-absolute-magnitude``, :func:`absolute_magnitude_comparison`):
the same stars counted per bin of M' = G + 5 log10(parallax / 100 mas), the absolute
magnitude with the extinction left in, so that model and catalogue are read alike (the
model's parallaxes get Hipparcos-sized errors, drawn from the catalogue's errors in the same
G bin). It says which kind of star the model has too many or too few of; the catalogue's
stars lying 1-3 mag above the dwarf sequence at F0-K2 colours (subgiants, which the model's
luminosity function holds only with ``subgiants=true``, the default since besancon-r03-5:
:mod:`mcsweep.population.galaxy.luminosity`) are counted per bin too.

Completeness (``compare``, with the optional extra ``realsky``): Gaia DR3's stars of each cell
with no Hipparcos 2 star within 3 arcsec (:func:`mcsweep.population.gaia_bright.hipparcos_match`)
are the ones Hipparcos lacks (its Survey is complete only to V = 7.3-7.9 + 1.1 sin|b|: ESA 1997,
The Hipparcos and Tycho Catalogues, Vol. 1, Sect. 1.2). They are red or early-type and crowd
to the plane (docs/galaxy_model.md): distant giants and OB-A stars. If every one of them has a
parallax below the complete sample's 90th percentile, that percentile is the catalogue's own at a
known higher quantile (:func:`quantile_with_unseen`): ``plx90_hip_complete``, the lower end of the
range in which the complete sky's value lies (``plx90_hip`` the upper). Proper motions are not
bracketed so: a giant at 300 pc moving at 30 km/s has ~20 mas/yr, the size of the median.
Both are also carried over to the complete sky by colour, as the real-sky fractions are
(:mod:`mcsweep.experiments.real_sky.complete`: each class of Gaia BP - RP weighted by its share
of all the cell's stars, the stars Hipparcos lacks taken to be like those of their class it
holds): ``plx90_hip_carried``, ``pm50_hip_carried`` and their ratios.

Usage::

    python -m mcsweep.validation.hipparcos_population [--extinction-model arenou1992]
        [--giant-thickness-factor 0.6] [--thin-disc-factor 1.18] [--[no-]subgiants]
        [--by-absolute-magnitude | --gaia-counts] [--out FILE.csv]

``--gaia-counts`` (:func:`gaia_band_counts`): the model's stars per band at G = 6-10 against
Gaia DR3's own counts (the optional extra ``realsky``), complete where Hipparcos is not.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import UserInputError
from ..experiments.real_sky.complete import N_COLOUR_CLASSES, SUB_BINS, carried_quantile, colour_magnitude_class
from ..population import GalaxyModel
from ..population import gaia_bright, hipparcos

__all__ = ["BANDS_DEG", "G_BINS", "MPRIME_EDGES", "absolute_magnitude_comparison", "above_main_sequence", "compare",
           "gaia_band_counts", "in_band", "main", "quantile_with_unseen"]

#: |b| bands of the real-sky validation, deg.
BANDS_DEG = ((0.0, 15.0), (15.0, 35.0), (35.0, 90.0))
#: G bins compared.
G_BINS = ((6.0, 7.0), (7.0, 8.0))
SEED = 20150821
#: Bins of M' = G + 5 log10(parallax / 100 mas) [mag]: luminous giants and B stars; giants and
#: B8-A0 dwarfs; the red clump and A0-A3; A3-F0 dwarfs and subgiants; F dwarfs and subgiants;
#: G dwarfs; later.
MPRIME_EDGES = (-np.inf, -1.0, 0.0, 1.0, 2.0, 3.0, 4.0, np.inf)
#: The dwarf sequence (B - V, M_G) from F0V to K3V: E. Mamajek, "A Modern Mean Dwarf Stellar
#: Color and Effective Temperature Sequence" (version 2021.03.02; Pecaut & Mamajek 2013, ApJS
#: 208, 9, Table 5, to be cited), columns B-V and M_G. (The galaxy model's copy of the table,
#: version 2024.05.15, has no B - V; its M_V + (G - V) differs from these M_G by <= 0.02 mag.)
DWARF_BV = (0.295, 0.440, 0.595, 0.680, 0.816, 0.884, 0.990)
DWARF_MG = (2.51, 3.26, 4.325, 4.801, 5.553, 5.83, 6.20)
#: Colours (F0V-K2V) and heights above the sequence [mag] counted as subgiants: an unresolved
#: equal binary sits 0.75 mag above, the red clump is redder (B - V ~ 1).
SUBGIANT_BV = (0.295, 0.884)
SUBGIANT_ABOVE = (1.0, 3.0)


def _stats(b, plx, pmra, pmdec):
    out = []
    for lo, hi in BANDS_DEG:
        sel = in_band(b, lo, hi)
        out.append((sel.sum(), np.percentile(plx[sel], 90), np.median(np.hypot(pmra[sel], pmdec[sel]))))
    return out


def compare(model, *, n_draw=200_000, seed=SEED):
    """One row per (G bin, |b| band): counts, p90 parallax [mas], median proper motion
    [mas/yr], model and Hipparcos, and their ratios; Hipparcos' p90 parallax and median
    proper motion without its stars above the dwarf sequence (:func:`above_main_sequence`);
    and, with Gaia DR3 (the extra ``realsky``; NaN without it), the Gaia stars of the cell
    Hipparcos lacks (``n_not_hip``), ``hip_completeness`` and ``plx90_hip_complete`` with
    ``plx90_ratio_complete`` (module notes)."""
    hip = hipparcos.load_hipparcos()
    rng = np.random.default_rng(seed)
    rows = []
    for g0, g1 in G_BINS:
        in_bin = (hip.phot_g_mean_mag >= g0) & (hip.phot_g_mean_mag < g1)
        h = hip[in_bin]
        hs = _stats(h.b.to_numpy(), h.parallax.to_numpy(), h.pmra.to_numpy(), h.pmdec.to_numpy())
        # the catalogue without its stars above the dwarf sequence (a model without subgiants lacks them)
        on = ~above_main_sequence(h.b_v, _mprime(h.phot_g_mean_mag, h.parallax))
        hs_on = _stats(h.b.to_numpy()[on], h.parallax.to_numpy()[on], h.pmra.to_numpy()[on], h.pmdec.to_numpy()[on])
        missing_b, missing_class, hip_class = _not_in_hipparcos(in_bin.to_numpy(), h, g0, g1)
        total, s = _model_draw(model, g0, g1, rng, n_draw)
        ms = _stats(s.b.to_numpy(), s.parallax.to_numpy(), s.pmra.to_numpy(), s.pmdec.to_numpy())
        for (lo, hi), (hn, hp, hm), (mn, mp, mm), (_, hp_on, hm_on) in zip(BANDS_DEG, hs, ms, hs_on):
            n_model = total * mn / len(s)
            row = dict(g_min=g0, g_max=g1, b_lo=lo, b_hi=hi, n_hip=hn, n_model=n_model,
                       count_ratio=n_model / hn, plx90_hip=hp, plx90_model=mp, plx90_ratio=mp / hp,
                       pm50_hip=hm, pm50_model=mm, pm50_ratio=mm / hm,
                       plx90_hip_not_above_ms=hp_on, pm50_hip_not_above_ms=hm_on)
            row.update(_completeness(h, hip_class, missing_b, missing_class, lo, hi, mp, mm))
            rows.append(row)
    return pd.DataFrame(rows)


def quantile_with_unseen(values, q, *, n_below=0, n_above=0) -> float:
    """The ``q`` quantile (numpy's linear interpolation) of a sample made of ``values`` and of
    ``n_below`` unseen values below it and ``n_above`` above it; NaN if it falls among the
    unseen ones. Exact: the seen values hold ranks ``n_below ... n_below + len(values) - 1`` of
    the whole sorted sample, so the whole's interpolation position maps onto theirs."""
    v = np.sort(np.asarray(values, dtype=float))
    n = v.size
    if n == 0:
        return np.nan
    pos = q * (n + n_below + n_above - 1) - n_below
    if pos < 0 or pos > n - 1:
        return np.nan
    return float(np.quantile(v, pos / (n - 1))) if n > 1 else float(v[0])


def _not_in_hipparcos(in_bin, h, g0, g1):
    """Latitudes [deg] and BP - RP classes of the Gaia stars with ``g0 <= G < g1`` that no
    Hipparcos 2 star matches (the catalogue searched whole, so a star whose derived G falls
    outside the bin still counts as present), and the classes of the bin's Hipparcos stars
    ``h`` (rows ``in_bin`` of the catalogue; by their Gaia counterparts); three Nones without
    Gaia."""
    if not gaia_bright.have_catalogue():
        return None, None, None
    gaia, match = gaia_bright.gaia_sources(), gaia_bright.hipparcos_match()
    g = gaia.phot_g_mean_mag.to_numpy()
    missing = gaia[match.gaia_unmatched & (g >= g0) & (g < g1)]
    bins = [(g0, g1)]
    return (missing.b.to_numpy(),
            colour_magnitude_class((missing.phot_bp_mean_mag - missing.phot_rp_mean_mag).to_numpy(),
                                   missing.phot_g_mean_mag.to_numpy(), bins),
            colour_magnitude_class(match.hip_bp_rp[in_bin], h.phot_g_mean_mag.to_numpy(), bins))


def _completeness(h, hip_class, missing_b, missing_class, lo, hi, plx90_model, pm50_model) -> dict:
    """The completeness columns of one (G bin, band) row of :func:`compare` (NaN without Gaia)."""
    keys = ("n_not_hip", "hip_completeness", "plx90_hip_complete", "plx90_ratio_complete", "plx90_hip_carried",
            "plx90_ratio_carried", "pm50_hip_carried", "pm50_ratio_carried")
    if missing_b is None:
        return dict.fromkeys(keys, np.nan)
    inb, inm = in_band(h.b, lo, hi), in_band(missing_b, lo, hi)
    plx, pm = h.parallax.to_numpy()[inb], np.hypot(h.pmra, h.pmdec).to_numpy()[inb]
    n_not = int(np.count_nonzero(inm))
    n_classes = N_COLOUR_CLASSES * SUB_BINS
    counts = np.bincount(hip_class[inb], minlength=n_classes) + np.bincount(missing_class[inm], minlength=n_classes)
    plx_bound = quantile_with_unseen(plx, 0.9, n_below=n_not)
    plx_carried = carried_quantile(plx, hip_class[inb], counts, 0.9)
    pm_carried = carried_quantile(pm, hip_class[inb], counts, 0.5)
    return dict(zip(keys, (n_not, plx.size / (plx.size + n_not), plx_bound, plx90_model / plx_bound, plx_carried,
                           plx90_model / plx_carried, pm_carried, pm50_model / pm_carried)))


def _model_draw(model, g0, g1, rng, n_draw):
    """The model's expected all-sky stars with ``g0 <= G < g1`` and a seeded draw of them, whose
    shares (per band, per bin) share out the expectation."""
    return (model.expected_count(0.0, 90.0, 180.0, g0, g1),
            model.sample_cone(0.0, 90.0, 180.0, g0, g1, rng, min_draw=n_draw))


def in_band(b, lo, hi) -> np.ndarray:
    """Whether latitudes ``b`` [deg] lie in the band ``lo <= |b| < hi`` (``hi = 90`` included)."""
    b = np.abs(np.asarray(b, dtype=float))
    return (b >= lo) & ((b < hi) | (hi == 90.0))


def _mprime(g, parallax) -> np.ndarray:
    """G + 5 log10(parallax / 100 mas); -inf for a parallax <= 0 (counted in the brightest bin)."""
    g, parallax = np.asarray(g, dtype=float), np.asarray(parallax, dtype=float)
    out = np.full(g.shape, -np.inf)
    pos = parallax > 0
    out[pos] = g[pos] + 5.0 * np.log10(parallax[pos] / 100.0)
    return out


def above_main_sequence(b_v, mprime) -> np.ndarray:
    """Whether a star of colour ``b_v`` and absolute magnitude ``mprime`` lies
    :data:`SUBGIANT_ABOVE` mag above the dwarf sequence at F0-K2 colours (:data:`SUBGIANT_BV`)."""
    b_v, mprime = np.asarray(b_v, dtype=float), np.asarray(mprime, dtype=float)
    above = np.interp(b_v, DWARF_BV, DWARF_MG) - mprime
    return ((b_v >= SUBGIANT_BV[0]) & (b_v < SUBGIANT_BV[1])
            & (above >= SUBGIANT_ABOVE[0]) & (above < SUBGIANT_ABOVE[1]))


def absolute_magnitude_comparison(model, *, n_draw=200_000, seed=SEED):
    """One row per (G bin, |b| band, M' bin): stars of the model (its expectation, shared out as
    its drawn stars fall) and of Hipparcos 2, their ratio, and the catalogue's stars above the
    dwarf sequence (:func:`above_main_sequence`). M' is read from parallaxes with Hipparcos-sized
    errors on both sides (module notes)."""
    hip = hipparcos.load_hipparcos()
    rng = np.random.default_rng(seed)
    edges = np.asarray(MPRIME_EDGES)
    rows = []
    for g0, g1 in G_BINS:
        h = hip[(hip.phot_g_mean_mag >= g0) & (hip.phot_g_mean_mag < g1)]
        mh = _mprime(h.phot_g_mean_mag, h.parallax)
        sub = above_main_sequence(h.b_v, mh)
        total, s = _model_draw(model, g0, g1, rng, n_draw)
        errors = rng.choice(h.parallax_error.to_numpy(), len(s))
        mm = _mprime(s.phot_g_mean_mag, s.parallax.to_numpy() + errors * rng.standard_normal(len(s)))
        for lo, hi in BANDS_DEG:
            inh, inm = in_band(h.b, lo, hi), in_band(s.b, lo, hi)
            n_hip = np.histogram(mh[inh], edges)[0]
            n_sub = np.histogram(mh[inh & sub], edges)[0]
            n_model = np.histogram(mm[inm], edges)[0] * (total / len(s))
            for k in range(len(edges) - 1):
                rows.append(dict(g_min=g0, g_max=g1, b_lo=lo, b_hi=hi, mprime_lo=edges[k], mprime_hi=edges[k + 1],
                                 n_hip=int(n_hip[k]), n_model=n_model[k],
                                 ratio=n_model[k] / n_hip[k] if n_hip[k] else np.nan,
                                 n_hip_above_ms=int(n_sub[k])))
    return pd.DataFrame(rows)


def gaia_band_counts(model, g_bins=((6.0, 7.0), (7.0, 8.0), (8.0, 9.0), (9.0, 10.0)), *, n_draw=200_000,
                     seed=SEED):
    """One row per (G bin, |b| band): the model's stars (its expectation, shared out as its drawn
    stars fall) against Gaia DR3's own (:mod:`mcsweep.population.gaia_bright`, G < 10, complete
    where Hipparcos is not, the Hipparcos gap-fill rows left out)."""
    gaia = gaia_bright.gaia_sources()
    b, g = gaia.b.to_numpy(), gaia.phot_g_mean_mag.to_numpy()
    rng = np.random.default_rng(seed)
    rows = []
    for g0, g1 in g_bins:
        in_g = (g >= g0) & (g < g1)
        total, s = _model_draw(model, g0, g1, rng, n_draw)
        for lo, hi in BANDS_DEG:
            n_gaia = int(np.count_nonzero(in_g & in_band(b, lo, hi)))
            n_model = total * np.count_nonzero(in_band(s.b, lo, hi)) / len(s)
            rows.append(dict(g_min=g0, g_max=g1, b_lo=lo, b_hi=hi, n_gaia=n_gaia, n_model=n_model,
                             ratio=n_model / n_gaia))
    return pd.DataFrame(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m mcsweep.validation.hipparcos_population",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--extinction-model", default=None, help="galaxy model extinction_model")
    ap.add_argument("--giant-thickness-factor", type=float, default=None,
                    help="galaxy model giant_thickness_factor")
    ap.add_argument("--thin-disc-factor", type=float, default=None,
                    help="galaxy model thin_disc_scale_height_factor")
    ap.add_argument("--subgiants", action=argparse.BooleanOptionalAction, default=None,
                    help="galaxy model subgiants (default: the model's)")
    ap.add_argument("--n-draw", type=int, default=200_000)
    table_kind = ap.add_mutually_exclusive_group()
    table_kind.add_argument("--by-absolute-magnitude", action="store_true",
                            help="counts per bin of M' = G + 5 log10(parallax / 100 mas) instead")
    table_kind.add_argument("--gaia-counts", action="store_true",
                            help="counts per band at G = 6-10 against Gaia DR3's own instead")
    ap.add_argument("--out", default=None, help="CSV file to write")
    args = ap.parse_args(argv)
    try:
        # a bad --out ends in one line before the computation, not in a traceback after it
        if args.out and not os.access(Path(args.out).resolve().parent, os.W_OK):
            raise UserInputError(f"--out={args.out!r} is not accepted; expected a file in an existing, "
                                 "writable folder")
        given = {"extinction_model": args.extinction_model,
                 "giant_thickness_factor": args.giant_thickness_factor,
                 "thin_disc_scale_height_factor": args.thin_disc_factor,
                 "subgiants": args.subgiants}
        params = {k: v for k, v in given.items() if v is not None}
        if args.n_draw < 1:
            raise UserInputError(f"--n-draw={args.n_draw} is not accepted; expected a positive integer")
        table = (absolute_magnitude_comparison if args.by_absolute_magnitude
                 else gaia_band_counts if args.gaia_counts else compare)
        df = table(GalaxyModel(params), n_draw=args.n_draw)
    except UserInputError as exc:
        print(f"hipparcos_population: {exc}", file=sys.stderr)
        return 2
    if args.out:
        df.to_csv(args.out, index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(df.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
