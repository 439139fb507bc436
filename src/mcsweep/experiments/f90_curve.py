"""sigma_F90 from a curve of the fraction of actual errors inside the P ellipse against
the prior (paper Sect. 3.3), its bootstrap interval over the stars and the test for a
curve whose crossing is set by noise. Shared by the sweep's cells and by Table 3's
factor search (k sigma_F90 over a primary solution's stars).
"""

from __future__ import annotations


import numpy as np

__all__ = ["prior_crossings", "sigma_f90_from_curve", "sigma_f90_interval", "bootstrap_fractions", "flag_patterns",
           "key_patterns", "merge_patterns", "pattern_fractions", "pattern_interval", "ill_determined",
           "INTERVAL_QUANTILES", "ILL_BAND_SIGMAS", "ILL_RANGE_DEX"]

#: Bootstrap interval of sigma_F90: the 16th and 84th percentiles (a 68 % interval,
#: "1 sigma" for a Gaussian).
INTERVAL_QUANTILES = (0.16, 0.84)
#: A cell is ill-determined when its fraction curve stays within ILL_BAND_SIGMAS
#: binomial standard deviations of P (sqrt(P(1-P)/n)) over at least ILL_RANGE_DEX of
#: prior widths: the crossing is then set by noise, not by the stars.
ILL_BAND_SIGMAS = 2.0
ILL_RANGE_DEX = 1.0


def prior_crossings(priors, fraction, p: float, interpolation: str) -> tuple[np.ndarray, np.ndarray]:
    """Rule of :func:`sigma_f90_from_curve` for many curves at once, ``fraction (r, m)``.

    Returns the values (r,) and the index of the first grid point that reaches ``p``
    (-1 where none does: value NaN).
    """
    frac = np.asarray(fraction, float)
    with np.errstate(invalid="ignore"):
        hits = frac >= p
    first = np.argmax(hits, axis=1)
    none = ~hits[np.arange(len(frac)), first]
    first[none] = -1
    values = np.full(len(frac), np.nan)
    at0 = first == 0
    values[at0] = priors[0]
    inner = np.flatnonzero(first > 0)
    if inner.size:
        i = first[inner]
        if interpolation == "none":
            values[inner] = priors[i]
        else:
            # Linear in log(sigma) between the grid points that bracket the crossing.
            f0, f1 = frac[inner, i - 1], frac[inner, i]
            with np.errstate(invalid="ignore", divide="ignore"):
                w = np.where(f1 > f0, (p - f0) / (f1 - f0), 1.0)
            log_p = np.log(priors)
            values[inner] = np.exp((1 - w) * log_p[i - 1] + w * log_p[i])
    return values, first


def sigma_f90_from_curve(priors_mas, fraction, p: float, interpolation: str = "log") -> tuple[float, str]:
    """Smallest prior whose fraction inside reaches ``p`` (Sect. 3.3), and a flag.

    Flags: 'ok'; 'below_grid' (the tightest prior already reaches p: the value is the
    grid's lower end, an upper limit); 'never_reached' (NaN).
    """
    priors = np.asarray(priors_mas, float)
    values, first = prior_crossings(priors, np.asarray(fraction, float)[None, :], p, interpolation)
    if first[0] < 0:
        return float("nan"), "never_reached"
    return float(values[0]), "below_grid" if first[0] == 0 else "ok"


def flag_patterns(inside_flags, valid_flags) -> dict[bytes, int]:
    """How many stars show each distinct pattern of (inside, valid) flags over the grid.

    ``inside_flags`` and ``valid_flags`` are (n_priors, n_stars); a pattern's key is its
    flags packed into bytes (the inside rows, then the valid rows; :func:`numpy.packbits`),
    its value the number of stars. Counts of disjoint sets of stars add
    (:func:`merge_patterns`): a cell read part by part has the patterns of the whole
    (:mod:`mcsweep.experiments.primary.reduction`).
    """
    inside_flags = np.asarray(inside_flags, bool)
    valid_flags = np.asarray(valid_flags, bool)
    if inside_flags.shape[1] == 0:
        return {}
    packed = np.packbits(np.concatenate([inside_flags, valid_flags]), axis=0)  # (bytes, n)
    keys = np.ascontiguousarray(packed.T).view(np.dtype((np.void, packed.shape[0]))).ravel()
    unique, counts = np.unique(keys, return_counts=True)
    return {k.tobytes(): int(c) for k, c in zip(unique, counts)}


def key_patterns(key_inside, key_valid, n_priors: int) -> dict[bytes, int]:
    """:func:`flag_patterns` of stars whose flags over ``n_priors`` priors are given as the
    bits of one integer each (bit i: prior i; :meth:`mcsweep.astrometry.prior_scan.PriorScan.inside_counts`):
    the same patterns under the same keys."""
    k_in, k_val = np.asarray(key_inside, np.uint64), np.asarray(key_valid, np.uint64)
    if k_in.size == 0:
        return {}
    order = np.lexsort((k_val, k_in))
    k_in, k_val = k_in[order], k_val[order]
    first = np.flatnonzero(np.r_[True, (k_in[1:] != k_in[:-1]) | (k_val[1:] != k_val[:-1])])
    counts = np.diff(np.r_[first, k_in.size])
    bit = np.uint64(1) << np.arange(n_priors, dtype=np.uint64)
    flags = np.concatenate([(k_in[first, None] & bit) != 0, (k_val[first, None] & bit) != 0], axis=1)  # (u, 2 m)
    packed = np.packbits(flags, axis=1)
    return {row.tobytes(): int(c) for row, c in zip(packed, counts)}


def merge_patterns(total: dict[bytes, int], more: dict[bytes, int]) -> dict[bytes, int]:
    """``total`` with the pattern counts ``more`` added (in place; returned)."""
    for key, count in more.items():
        total[key] = total.get(key, 0) + count
    return total


def pattern_fractions(patterns: dict[bytes, int], n_priors: int, n_resamples: int,
                      rng: np.random.Generator) -> np.ndarray:
    """Fractions inside of ``n_resamples`` bootstrap resamples of the stars counted in
    ``patterns`` (:func:`flag_patterns` over ``n_priors`` priors), (n_resamples, n_priors).

    A resample's curve depends only on how many times it draws each distinct pattern of
    (inside, valid) flags over the grid. With ``n_u`` of the ``n`` stars in pattern
    ``u`` those counts are multinomial(n, n_u / n) -- exactly the distribution of
    resampling the stars one by one -- so each resample costs one multinomial draw over
    the distinct patterns (a few hundred), and all curves one matrix product. The patterns
    are taken in the order of their keys' bytes: the draws do not depend on the order of
    the stars, nor on how they were split into parts.
    """
    keys = sorted(patterns)
    counts = np.array([patterns[k] for k in keys], dtype=float)
    n = int(counts.sum())
    bits = np.unpackbits(np.frombuffer(b"".join(keys), np.uint8).reshape(len(keys), -1), axis=1)
    inside, valid = bits[:, :n_priors].astype(float), bits[:, n_priors:2 * n_priors].astype(float)
    weights = rng.multinomial(n, counts / n, size=n_resamples).astype(float)
    # Integer-valued sums below 2^53: exact whatever the summation order (bit-identical).
    n_in = weights @ inside
    n_val = weights @ valid
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n_val > 0, n_in / n_val, np.nan)


def bootstrap_fractions(inside_flags, valid_flags, n_resamples: int, rng: np.random.Generator) -> np.ndarray:
    """Fractions inside of ``n_resamples`` bootstrap resamples of the stars, (n_resamples, n_priors):
    :func:`pattern_fractions` of the stars' :func:`flag_patterns`."""
    inside_flags = np.asarray(inside_flags, bool)
    return pattern_fractions(flag_patterns(inside_flags, valid_flags), inside_flags.shape[0], n_resamples, rng)


def sigma_f90_interval(priors_mas, inside_flags, valid_flags, p: float, interpolation: str,
                       n_resamples: int, rng: np.random.Generator) -> tuple[float, float]:
    """Bootstrap interval (INTERVAL_QUANTILES) of sigma_F90 over the cell's stars.

    Each resample draws the stars with replacement (one draw serves all priors, so the
    curve keeps its correlation between priors) and finds its crossing with the rule
    of :func:`sigma_f90_from_curve`; a resample whose fraction never reaches ``p``
    counts as +inf, one below the grid as the grid's lower end. ``inside_flags`` and
    ``valid_flags`` are (n_priors, n_stars) (NaN rule of ``inside_counts``); the
    resamples come from :func:`bootstrap_fractions`.
    """
    return pattern_interval(priors_mas, flag_patterns(inside_flags, valid_flags), p, interpolation, n_resamples, rng)


def pattern_interval(priors_mas, patterns: dict[bytes, int], p: float, interpolation: str,
                     n_resamples: int, rng: np.random.Generator) -> tuple[float, float]:
    """:func:`sigma_f90_interval` of the stars counted in ``patterns`` (:func:`flag_patterns`)."""
    priors = np.asarray(priors_mas, float)
    if n_resamples <= 0 or not patterns:
        return float("nan"), float("nan")
    frac = pattern_fractions(patterns, priors.size, n_resamples, rng)
    values = prior_crossings(priors, frac, p, interpolation)[0]
    values[np.isnan(values)] = np.inf
    lo, hi = np.quantile(values, INTERVAL_QUANTILES, method="inverted_cdf")
    return float(lo), float(hi)


def ill_determined(priors_mas, fraction, n_valid, p: float) -> bool:
    """True when the fraction curve runs within ILL_BAND_SIGMAS binomial sigma of ``p``
    over ILL_RANGE_DEX or more of contiguous prior grid around its crossing of ``p``
    (or, if it never crosses, anywhere): the crossing is then set by noise."""
    priors = np.asarray(priors_mas, float)
    frac = np.asarray(fraction, float)
    nv = np.asarray(n_valid, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        near = np.abs(frac - p) <= ILL_BAND_SIGMAS * np.sqrt(p * (1.0 - p) / nv)
    hits = np.flatnonzero(frac >= p)
    if hits.size and hits[0] > 0:
        # The run of near points that contains the crossing (either bracketing point).
        i = int(hits[0]) if near[hits[0]] else int(hits[0]) - 1
        if not near[i]:
            return False
        lo = hi = i
        while lo > 0 and near[lo - 1]:
            lo -= 1
        while hi < len(near) - 1 and near[hi + 1]:
            hi += 1
        span = np.log10(priors[hi]) - np.log10(priors[lo])
    else:
        if not near.any():
            return False
        span = np.log10(priors[near]).max() - np.log10(priors[near]).min()
    return bool(span >= ILL_RANGE_DEX - 1e-9)
