"""The real-sky fractions carried over to the complete sky.

Hipparcos 2 is complete only to its Survey limit, V = 7.9 + 1.1 sin|b| for spectral types
earlier than G5 and 7.3 + 1.1 sin|b| for later ones (ESA 1997, The Hipparcos and Tycho
Catalogues, ESA SP-1200, Vol. 1, Sect. 1.2); fainter stars are there only if an observing
proposal asked for them. Against Gaia DR3's own stars (:mod:`mcsweep.population.gaia_bright`)
it lacks part of the sky's G = 6-8 stars, more at G = 7-8 than at G = 6-7, mostly red ones
(docs/galaxy_model.md), i.e. distant giants. Kinds of star differ in how often their errors
fall inside the P ellipse (red giants more often than other stars; the measured fractions
are in docs/research_notes_moved.md), so the catalogue's mix of kinds sets a cell's
fraction, not only the prior.

Here each cell's fraction is carried over to the complete sky by colour and magnitude: the
stars of the cell, Hipparcos' and the Gaia stars it lacks
(:func:`~mcsweep.population.gaia_bright.hipparcos_match`), are sorted into classes of Gaia
BP - RP (:data:`BP_RP_EDGES`; Hipparcos' stars take the colour of their Gaia counterpart;
stars without one form a class of their own) within each :data:`SUB_BINS`-th of the G bin (the stars Hipparcos lacks lie toward
the faint side of a bin, and the prior changes with G); the complete sky's fraction is the mean
of the classes' Hipparcos fractions weighted by the classes' shares of all the cell's stars.

The assumption: within a class, the stars Hipparcos lacks fall inside as often as those it
holds. At a given G and colour, V is fixed, so the Survey took a class's stars all or none
in a band (up to the class's width and the G5 split); the others Hipparcos holds came from
proposals, which favoured nearby stars (large parallaxes, outside the ellipse more often), so
the carried-over fraction leans low if anything. Its interval is +-1 sigma of the weighted
binomial (normal approximation, 68 %). Stars without a colour are shared out like the rest of
their sub-bin when Hipparcos has none of them solved; any other class with stars but none
solved makes the cell's value NaN. A G range beyond the bundled Gaia stars (G >= 10) has no
rows.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...population import gaia_bright
from ...population.hipparcos import load_hipparcos
from .experiment import B_BANDS, band_of, g_bins, gbin_of

__all__ = ["BP_RP_EDGES", "SUB_BINS", "N_COLOUR_CLASSES", "COLUMNS", "colour_class", "colour_magnitude_class",
           "carried_fraction", "carried_quantile", "complete_rows", "complete_markdown"]

#: Class edges in Gaia BP - RP [mag]: B-A stars; F; G; K0-K3 dwarfs and the red clump; K
#: giants; M giants and red dwarfs.
BP_RP_EDGES = (0.5, 0.8, 1.1, 1.4, 1.8)
#: Sub-bins of each G bin in which the colour classes are formed (half magnitudes).
SUB_BINS = 2
#: Classes per sub-bin: the colour classes and the one without colour (the last).
N_COLOUR_CLASSES = len(BP_RP_EDGES) + 2
#: The columns of ``real_sky_complete.csv``.
COLUMNS = ("prior", "truth", "case", "b_band_deg", "g_bin", "n_hipparcos", "n_not_in_hipparcos",
           "hipparcos_completeness", "n_solved", "fraction_hipparcos", "fraction_complete_sky",
           "fraction_complete_sky_sigma")


def colour_class(bp_rp) -> np.ndarray:
    """Class index of each colour: 0 ... len(BP_RP_EDGES) by the edges, one more for NaN."""
    c = np.asarray(bp_rp, dtype=float)
    out = np.searchsorted(np.asarray(BP_RP_EDGES), c, side="right")
    out[~np.isfinite(c)] = len(BP_RP_EDGES) + 1
    return out


def carried_fraction(inside, classes, class_counts) -> tuple[float, float]:
    """(fraction, its 1-sigma) of the whole: ``inside`` (1/0) and ``classes`` of the solved
    stars, ``class_counts`` the number of stars of each class in the whole (solved or not).
    NaN when a class of the whole has no solved star."""
    inside, classes = np.asarray(inside, dtype=float), np.asarray(classes)
    counts = np.asarray(class_counts, dtype=float)
    n_solved = np.bincount(classes, minlength=counts.size).astype(float)
    counts = _colourless_shared_out(counts, n_solved)
    if counts.sum() == 0 or np.any((counts > 0) & (n_solved == 0)):
        return np.nan, np.nan
    k_in = np.bincount(classes, weights=inside, minlength=counts.size)
    use = counts > 0
    f = k_in[use] / n_solved[use]
    w = counts[use] / counts.sum()
    return float(w @ f), float(np.sqrt(np.sum(w ** 2 * f * (1.0 - f) / n_solved[use])))


def carried_quantile(values, classes, class_counts, q) -> float:
    """The ``q`` quantile of the whole, each value of class k standing for
    ``class_counts[k] / (values of class k)`` stars (the inverse of the weighted empirical
    distribution, interpolated between the weights' midpoints); NaN when a class of the
    whole has no value."""
    values, classes = np.asarray(values, dtype=float), np.asarray(classes)
    counts = np.asarray(class_counts, dtype=float)
    n_seen = np.bincount(classes, minlength=counts.size).astype(float)
    counts = _colourless_shared_out(counts, n_seen)
    if values.size == 0 or np.any((counts > 0) & (n_seen == 0)):
        return np.nan
    w = counts[classes] / n_seen[classes]
    keep = w > 0  # values of a class absent from the whole stand for no star
    order = np.argsort(values[keep], kind="stable")
    v, w = values[keep][order], w[keep][order]
    mid = (np.cumsum(w) - 0.5 * w) / w.sum()
    return float(np.interp(q, mid, v))


def _colourless_shared_out(counts, n_seen):
    """``counts`` without the stars of a no-colour class (the last of each group of
    :data:`N_COLOUR_CLASSES`) none of whose stars is seen, shared out over the coloured
    classes of the same group in proportion; then they count like the coloured ones."""
    if counts.size % N_COLOUR_CLASSES:
        return counts
    c = counts.reshape(-1, N_COLOUR_CLASSES).copy()
    seen = n_seen.reshape(-1, N_COLOUR_CLASSES)
    lost = (c[:, -1] > 0) & (seen[:, -1] == 0)
    coloured = c[:, :-1].sum(axis=1)
    share = lost & (coloured > 0)
    c[share, :-1] *= (1.0 + c[share, -1] / coloured[share])[:, None]
    c[share, -1] = 0.0
    return c.ravel()


def complete_rows(stars: pd.DataFrame, results: pd.DataFrame, settings, *, truth="hipparcos") -> pd.DataFrame:
    """``real_sky_complete.csv``: per prior x case x |b| band x G bin, Hipparcos' stars and
    the Gaia stars it lacks in the cell, its completeness, its fraction inside and the
    complete sky's (module notes). G bins beyond Gaia's bundled G < 10 are left out."""
    bins = [bn for bn in g_bins(settings.g_min, settings.g_max) if bn[1] <= gaia_bright.G_LIMIT]
    if not bins:
        return pd.DataFrame(columns=list(COLUMNS))
    lo, hi = bins[0][0], bins[-1][1]
    hip_all, gaia = load_hipparcos(), gaia_bright.gaia_sources()
    match = gaia_bright.hipparcos_match()
    g = gaia.phot_g_mean_mag.to_numpy()
    missing = gaia[match.gaia_unmatched & (g >= lo) & (g < hi)]
    m_gmag = missing.phot_g_mean_mag.to_numpy()
    m_class = colour_magnitude_class((missing.phot_bp_mean_mag - missing.phot_rp_mean_mag).to_numpy(), m_gmag, bins)
    m_band, m_g = band_of(missing.b.to_numpy()), gbin_of(m_gmag, bins)
    # every Hipparcos star of the range sets the weights, the solved ones (a subset with
    # max_stars) the fractions; colours from all of Gaia (a counterpart's G may lie outside)
    h_gmag = hip_all.phot_g_mean_mag.to_numpy()
    in_range = (h_gmag >= lo) & (h_gmag < hi)
    hip, h_gmag = hip_all[in_range], h_gmag[in_range]
    h_class = colour_magnitude_class(match.hip_bp_rp[in_range], h_gmag, bins)
    h_band, h_g = band_of(hip.b.to_numpy()), gbin_of(h_gmag, bins)
    s_gmag = stars["phot_g_mean_mag"].to_numpy()
    s_in = (s_gmag >= lo) & (s_gmag < hi)
    # the solved stars are Hipparcos stars of the range: their classes by identifier
    s_class = pd.Series(h_class, index=hip.hip.to_numpy()).reindex(stars["hip"].to_numpy(),
                                                                   fill_value=0).to_numpy()
    s_band, s_g = band_of(stars["b"].to_numpy()), gbin_of(s_gmag, bins)
    n_classes = N_COLOUR_CLASSES * SUB_BINS
    rows = []
    for prior, _ in settings.priors:
        for case, _ in settings.cases:
            flags = results[f"inside_{case}_{truth}_{prior}"].to_numpy()
            for i, (b0, b1) in enumerate(B_BANDS):
                for j, (g0, g1) in enumerate(bins):
                    h_cell, m_cell = (h_band == i) & (h_g == j), (m_band == i) & (m_g == j)
                    solved = s_in & (s_band == i) & (s_g == j) & (flags >= 0)
                    counts = (np.bincount(h_class[h_cell], minlength=n_classes)
                              + np.bincount(m_class[m_cell], minlength=n_classes))
                    frac, sigma = carried_fraction(flags[solved], s_class[solved], counts)
                    n_hip, n_miss = int(h_cell.sum()), int(m_cell.sum())
                    rows.append({"prior": prior, "truth": truth, "case": case, "b_band_deg": f"{b0:g}-{b1:g}",
                                 "g_bin": f"{g0:g}-{g1:g}", "n_hipparcos": n_hip, "n_not_in_hipparcos": n_miss,
                                 "hipparcos_completeness": n_hip / (n_hip + n_miss) if n_hip + n_miss else np.nan,
                                 "n_solved": int(solved.sum()),
                                 "fraction_hipparcos": float(flags[solved].mean()) if solved.any() else np.nan,
                                 "fraction_complete_sky": frac, "fraction_complete_sky_sigma": sigma})
    return pd.DataFrame(rows, columns=list(COLUMNS))


def colour_magnitude_class(bp_rp, gmag, bins) -> np.ndarray:
    """Class index of each star: its colour class (:func:`colour_class`) within its
    :data:`SUB_BINS`-th of its G bin (``bins``: (lo, hi) pairs, each 1 mag wide);
    ``N_COLOUR_CLASSES * SUB_BINS`` classes in all."""
    lo = np.asarray([b[0] for b in bins])[gbin_of(gmag, bins)]
    sub = np.clip(np.floor((np.asarray(gmag, float) - lo) * SUB_BINS), 0, SUB_BINS - 1).astype(int)
    return sub * N_COLOUR_CLASSES + colour_class(bp_rp)


def complete_markdown(rows: pd.DataFrame, confidence: float) -> list[str]:
    """The section of ``real_sky.md``: per prior and case, the complete sky's fraction
    +- 1 sigma, Hipparcos' own and its completeness, per |b| band (rows) and G bin."""
    if rows.empty:
        return []
    pct = f"{100 * confidence:g}"
    lines = ["## Carried over to the complete sky (Gaia DR3's stars by BP - RP)", "",
             "Per cell: the complete sky's fraction inside +- 1 sigma / Hipparcos' own (Hipparcos' share of "
             "Gaia DR3's stars); each colour class weighted by its share of all the cell's stars, on the "
             "assumption that the stars Hipparcos lacks fall inside as often as those of their class it holds "
             "(docs/galaxy_model.md).", ""]
    gnames = list(dict.fromkeys(rows["g_bin"]))
    for (prior, case), sub in rows.groupby(["prior", "case"], sort=False):
        lines += [f"### Prior '{prior}', case '{case}': in {pct} % ellipse [%]", ""]
        head = ["abs(b) band [deg]"] + [f"G {g}" for g in gnames]
        lines += ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
        for bname, part in sub.groupby("b_band_deg", sort=False):
            cells = []
            for g in gnames:
                r = part[part["g_bin"] == g].iloc[0]
                full = ("–" if not np.isfinite(r["fraction_complete_sky"]) else
                        f"{100 * r['fraction_complete_sky']:.1f} +- {100 * r['fraction_complete_sky_sigma']:.1f}")
                cells.append(f"{full} / {100 * r['fraction_hipparcos']:.1f} "
                             f"({100 * r['hipparcos_completeness']:.0f} %)")
            lines.append("| " + " | ".join([bname] + cells) + " |")
        lines.append("")
    return lines
