"""The stars of the global experiments and which of their transits are kept.

*Classes of stars* (paper Sect. 4: "the 5e5 brightest stars fainter than G0 = 11, 15
and 19" over the whole sky). From the galaxy model a faint limit G1 is found with
``expected_count(whole sky, G0..G1)`` a little above the class size (``class_size + 6
sqrt(class_size)``, so a Poisson draw almost surely holds enough stars), the stars of
[G0, G1) are drawn, and the ``class_size`` brightest are kept; from a catalogue its
brightest stars in [G0, 21) (21 = the noise model's limit). Stars keep the order in
which the source returned them. Each class (or group of extra stars) has a key, round(100
G0) (0 for extra primary sources), its identity in the seeds and the results.

*Transits* of the configured scanning law over the mission, compact (16 bytes each; the
paper's primary solution finds 2.6e7), then thinned in either or both of two ways:
*dilution* (Sect. 4.1: each FoV transit removed with a probability, by a counter-based
hash of the star's index in its class, so a chunk of stars needs nothing but its own
indices) and *dead time* (Sect. 4.2: 20 % of the time line in blocks, one draw for the
whole data set).
"""

from __future__ import annotations

import math
import warnings
from typing import Callable, Sequence

import astropy.units as u
import numpy as np
import pandas as pd

from ...astrometry.noise import G_MAX
from ...population import make_source
from ...scanning import find_transits
from ...scanning.timeline import DeadTime, dilution_key, draw_dead_time, keep_after_dilution

__all__ = ["STAR_COLUMNS", "MARGIN_SIGMAS", "POPULATION_STREAM", "SKY_ORDER_LEVEL", "class_key", "faint_limit",
           "select_class_stars", "draw_classes", "sky_pixels", "sky_order", "class_table", "star_transits", "diluted", "dead_time"]

#: The population columns the experiments use (Gaia archive names).
STAR_COLUMNS = ("ra", "dec", "l", "b", "parallax", "pmra", "pmdec", "phot_g_mean_mag")
#: Extra stars asked of the galaxy model beyond the class size, in Poisson sigmas.
MARGIN_SIGMAS = 6.0
#: Stream number of the population in every global experiment's seeds: (tag, 0, class key).
POPULATION_STREAM = 0
#: HEALPix level of :func:`sky_order`: 12, the level Gaia's source_id encodes (module notes).
SKY_ORDER_LEVEL = 12


def class_key(g_class: float) -> int:
    """Stable identity of a magnitude class (0.01 mag resolution)."""
    return int(round(100.0 * g_class))


def faint_limit(count, g_min: float, g_limit: float, target: float, *, rtol: float = 0.05,
                max_iter: int = 60) -> float:
    """Smallest convenient G1 with ``target <= count(G1) <= (1 + rtol) target``.

    ``count(g)`` is the (monotone) number of stars in [g_min, g); the search is a
    safeguarded secant in (log(g - g_min), log count), where counts are close to power
    laws. Returns ``g_limit`` if even ``count(g_limit) < target``; if the tolerance is not
    reached (e.g. a catalogue with many equal magnitudes), the bracketing G1 with
    ``count >= target``.
    """
    total = count(g_limit)
    if total < target:
        return g_limit
    lo_x, lo_y = None, -math.inf
    hi_x, hi_y = math.log(g_limit - g_min), math.log(total)
    y_ok, y_aim = math.log(target * (1.0 + rtol)), math.log(target * (1.0 + 0.5 * rtol))
    x = min(math.log(0.01), hi_x - 1.0)
    for _ in range(max_iter):
        if hi_y <= y_ok:
            break
        c = count(g_min + math.exp(x))
        if c >= target:
            hi_x, hi_y = x, math.log(c)
        else:
            lo_x, lo_y = x, (math.log(c) if c > 0 else -math.inf)
        if lo_x is None:
            x = hi_x - 2.0
        elif not math.isfinite(lo_y):
            x = 0.5 * (lo_x + hi_x)
        else:
            x = lo_x + (y_aim - lo_y) * (hi_x - lo_x) / (hi_y - lo_y)
            span = hi_x - lo_x
            if not lo_x + 0.01 * span < x < hi_x - 0.01 * span:
                x = 0.5 * (lo_x + hi_x)
    return g_min + math.exp(hi_x)


def select_class_stars(source, g_min: float, n: int, rng, *,
                       size_key: str = "experiment.secondary.class_size") -> pd.DataFrame:
    """The ``n`` brightest stars with G >= g_min over the whole sky (module notes).

    ``df.attrs['g_upper']`` is the faint limit of the draw. Fewer than ``n`` stars (a small
    catalogue) are returned with a warning naming the setting ``size_key``.
    """
    target = n + MARGIN_SIGMAS * math.sqrt(n)
    g_upper = faint_limit(lambda g: source.expected_count(0.0, 90.0, 180.0, g_min, g), g_min, G_MAX, target)
    df = source.sample_sky(g_min, g_upper, rng)
    g = df["phot_g_mean_mag"].to_numpy()
    if len(df) > n:
        keep = np.sort(np.argsort(g, kind="stable")[:n])
        df = df.iloc[keep].reset_index(drop=True)
    elif len(df) < n:
        warnings.warn(f"magnitude class G >= {g_min:g}: only {len(df)} stars available below G = "
                      f"{g_upper:.3f}, fewer than {size_key}={n}", stacklevel=2)
    df.attrs["g_upper"] = g_upper
    return df


def draw_class(job: tuple) -> tuple[int, pd.DataFrame, list]:
    """One class drawn where an executor runs it (a worker process or a Dask worker):
    ``job = (population config, g_min, size, key, seed, size_key)``, the source made there
    from its config. Returns ``(key, stars, warnings)``, the warnings it raised as
    ``(category, message)`` for the caller to repeat where the user sees them."""
    population, g, n, key, seed, size_key = job
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stars = select_class_stars(make_source(population), g, n, np.random.default_rng(seed), size_key=size_key)
    return key, stars, [(w.category, str(w.message)) for w in caught]


def draw_classes(population: dict, groups: Sequence[tuple[float, int, int]],
                 seed_of: Callable[[int], np.random.SeedSequence], *, size_key: str, run=None,
                 bar=None) -> list[tuple[float, int, pd.DataFrame]]:
    """``(g_min, key, stars)`` of every group ``(g_min, size, key)`` of the population of
    config ``population`` (:func:`mcsweep.population.make_source`), in order.

    Each group's stars come from its own generator ``seed_of(key)``, so a class is the
    same whatever other classes are drawn, and wherever. ``run``: an executor's
    ``run(fn, jobs)`` (:func:`mcsweep.runtime.execution.executor`) drawing each class as a
    task (:func:`draw_class`), so the galaxy model's whole-sky tables and the draw's
    temporaries (1.4 GB for 3 x 5e5 stars) stay off this process; None: drawn here from
    one source. ``bar`` (a progress bar) advances per group.
    """
    if run is None:  # one source for every class (its tables are built once)
        source = make_source(population)
        drawn = ((key, select_class_stars(source, float(g), n, np.random.default_rng(seed_of(key)),
                                          size_key=size_key), []) for g, n, key in groups)
    else:
        drawn = run(draw_class, [(population, float(g), n, key, seed_of(key), size_key) for g, n, key in groups])
    out = {}
    for key, stars, caught in drawn:
        for category, message in caught:  # a worker's warnings, repeated here (none in-process)
            warnings.warn(message, category, stacklevel=2)
        out[key] = stars
        if bar is not None:
            bar.update(1)
    return [(float(g), key, out[key]) for g, _, key in groups]


def sky_pixels(ra_deg, dec_deg) -> np.ndarray:
    """HEALPix level-:data:`SKY_ORDER_LEVEL` nested pixel of each star (ICRS ``ra, dec`` [deg]):
    the key of :func:`sky_order`."""
    from astropy_healpix import lonlat_to_healpix

    return lonlat_to_healpix(np.radians(np.asarray(ra_deg, dtype=float)) * u.rad,
                             np.radians(np.asarray(dec_deg, dtype=float)) * u.rad,
                             2 ** SKY_ORDER_LEVEL, order="nested")


def sky_order(ra_deg, dec_deg) -> np.ndarray:
    """Indices that put stars (ICRS ``ra, dec`` [deg]) in sky order: by HEALPix level-12 nested
    pixel, as Gaia's source_id orders them (module notes); stars of one pixel keep their order."""
    return np.argsort(sky_pixels(ra_deg, dec_deg), kind="stable")


def class_table(stars: pd.DataFrame, key: int) -> pd.DataFrame:
    """A class's stars as one global solution holds them: :data:`STAR_COLUMNS` and ``class_key``."""
    out = stars[list(STAR_COLUMNS)].copy()
    out["class_key"] = key
    return out


def star_transits(ra, dec, start_jd: float, end_jd: float, law, *, first: int = 0,
                  with_fov: bool = False) -> dict:
    """FoV transits of the stars ``first, first + 1, ...`` (``ra, dec`` [deg]), sorted by
    (star, time): ``star`` (int32), ``t`` (TCB JD), ``psi`` (float32 scan angle [deg],
    find_transits' own precision in compact form) and with ``with_fov`` ``following``
    (True in the following FoV; dilution hashes it)."""
    tr = find_transits(ra, dec, start_jd, end_jd, law=law, compact=True)
    out = {"star": (first + tr["source_index"].to_numpy()).astype(np.int32),
           "t": tr["tcb_jd"].to_numpy(), "psi": tr["scan_angle_deg"].to_numpy().astype(np.float32)}
    if with_fov:
        out["following"] = tr["fov"].cat.codes.to_numpy() == 1
    return out


def diluted(seed: np.random.SeedSequence, transits: dict, probability: float) -> np.ndarray:
    """Which of ``transits`` (:func:`star_transits` with ``with_fov``) survive a dilution
    removing each with ``probability`` (Sect. 4.1); ``seed``: the class's dilution stream."""
    key = dilution_key(np.random.default_rng(seed))
    return keep_after_dilution(key, transits["star"], transits["following"], transits["t"], probability)


def dead_time(seed: np.random.SeedSequence, start_jd: float, end_jd: float, fraction: float, *,
              outage_days: float) -> DeadTime:
    """The dead outages of the time line (Sect. 4.2: 20 % dead time), one draw for the data set."""
    return draw_dead_time(start_jd, end_jd, fraction, outage_days=outage_days, rng=np.random.default_rng(seed))
