"""The prior as an object a user queries: load once, ask with sky coordinates and G.

:class:`Prior` holds the coefficients of Eqs. 15-17, the magnitude range they were
fitted over, the confidence level P and the ratio R = sigma_mu / sigma_plx of Eq. 18.
``Prior.paper()`` is the paper's formula (Sect. 3.4); ``Prior.from_run(run_dir)`` a
sweep's own fit (``coefficients.csv``, read by column name, and ``provenance.json``).

A sweep run with a colour axis (``prior_model.colour_edges``) also fitted Eqs. 14-17 per
Gaia BP-RP bin (:mod:`mcsweep.prior.colour`, the "photometric information" of the
paper's Sect. 3.4); every query then takes ``bp_rp=`` and a star of unknown colour (NaN)
gets the colour-blind prior of the same run. A run with ``prior_model.mean`` centres the
prior on the galaxy model's mean parallax and proper motion per cell
(:mod:`mcsweep.prior.means`; :meth:`~mcsweep.prior.Prior.mean_parallax`, :meth:`~mcsweep.prior.Prior.mean_pm`), zero for
every other prior, as in the paper (Sect. 3.1). ``bp_rp`` given to a prior without a
colour axis is ignored. A colour bin's width is held constant beyond the centres of its
outer G bins with a fit (:mod:`mcsweep.prior.colour`), whatever ``bright`` says: a colour's
population changes with G too fast to extrapolate (docs/prior_colour.md).

Magnitudes outside the fit range follow the rules of :mod:`mcsweep.prior.formula`
for both kinds: fainter than ``g_max`` the value at ``g_max`` (the paper's rule at
G > 20, Sect. 3.4); brighter than ``g_min`` the documented choice ``bright``
(``"extrapolate"``, default, or ``"clamp"``). For a run whose G range starts fainter
than 6 the extrapolation is only as good as the fitted polynomials, so check
``prior.g_min`` before querying far brighter stars, or use ``bright="clamp"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np
from astropy import units as u
from astropy.coordinates import Galactic, SkyCoord

from ..errors import UserInputError
from .colour import ColourBins, colour_values
from .columns import unit_scale
from .means import PriorMeans
from .run_record import COEFFICIENTS_FILE, COLOUR_COEFFICIENTS_FILE, MEANS_FILE, read_coefficients, read_record
from .formula import (
    G_FIT_MAX,
    G_FIT_MIN,
    PAPER_COEFFICIENTS,
    check_bright,
    sigma_from_coefficients,
)

__all__ = ["Prior", "PAPER_CONFIDENCE", "PAPER_RATIO_R", "sigma_f90"]

#: Confidence level of the paper's sigma_F90 (Sect. 2.4).
PAPER_CONFIDENCE = 0.9
#: R = sigma_mu,p / sigma_plx,p in 1/yr (Sect. 3.1, Eq. 18).
PAPER_RATIO_R = 10.0
#: The fitted coefficients in a run directory (written by the sweep: :func:`mcsweep.experiments.f90_sweep.runner.write_fit`).


def _frozen(coefficients: Mapping) -> Mapping[str, tuple[float, ...]]:
    return MappingProxyType({k: tuple(float(c) for c in coefficients[k]) for k in ("s0", "s1", "s2")})


@dataclass(frozen=True, eq=False)
class Prior:
    """The all-sky parallax and proper-motion prior of Eqs. 14-18.

    Parameters
    ----------
    coefficients : mapping
        ``{"s0": (c0, c1, c2), "s1": (c0, .., c3), "s2": (c0, c1)}`` of Eqs. 15-17,
        increasing powers of G.
    g_min, g_max : float
        Magnitude range of the fit (module notes on what happens outside).
    confidence : float
        Confidence level P for which sigma_F90 was determined.
    ratio_R : float
        ``sigma_mu / sigma_plx`` in 1/yr (Eq. 18).
    bright : {"extrapolate", "clamp"}
        Treatment of G < ``g_min``.
    origin : str
        Where the coefficients come from ("paper" or the run directory).
    colour : ColourBins or None
        Coefficients per BP-RP bin (``mcsweep.prior.colour``); None: no colour axis.
    means : PriorMeans or None
        The prior's centre per cell (``mcsweep.prior.means``); None: centred on zero.

    Examples
    --------
    >>> from astropy.coordinates import SkyCoord
    >>> import astropy.units as u
    >>> prior = Prior.paper()
    >>> prior.sigma_parallax(SkyCoord(ra=150 * u.deg, dec=20 * u.deg), G=15.0)  # doctest: +FLOAT_CMP
    <Quantity 2.04467153 mas>
    """

    coefficients: Mapping[str, tuple[float, ...]]
    g_min: float = G_FIT_MIN
    g_max: float = G_FIT_MAX
    confidence: float = PAPER_CONFIDENCE
    ratio_R: float = PAPER_RATIO_R
    bright: str = "extrapolate"
    origin: str = field(default="paper")
    colour: ColourBins | None = None
    means: PriorMeans | None = None

    def __post_init__(self):
        missing = [k for k in ("s0", "s1", "s2") if k not in self.coefficients]
        if missing:
            raise UserInputError(f"coefficients {sorted(self.coefficients)} are not accepted; "
                                 f"missing {missing} (expected keys s0, s1, s2)")
        object.__setattr__(self, "coefficients", _frozen(self.coefficients))
        bad = [k for k, v in self.coefficients.items() if not v or not all(map(math.isfinite, v))]
        if bad:
            raise UserInputError(f"coefficients of {bad} from {self.origin} are not finite numbers; "
                                 "expected a fitted prior (a sweep with at least 4 G bins fitted)")
        check_bright(self.bright)
        if not (math.isfinite(self.g_min) and math.isfinite(self.g_max) and self.g_min < self.g_max):
            raise UserInputError(f"G range ({self.g_min}, {self.g_max}) is not accepted; "
                                 "expected finite g_min < g_max")
        if not 0.0 < self.confidence < 1.0:
            raise UserInputError(f"confidence={self.confidence!r} is not accepted; "
                                 "expected a probability strictly between 0 and 1")
        if not (self.ratio_R > 0 and math.isfinite(self.ratio_R)):
            raise UserInputError(f"ratio_R={self.ratio_R!r} is not accepted; expected a positive finite number per year")

    # -- construction -------------------------------------------------------------------
    @classmethod
    def paper(cls, *, bright: str = "extrapolate") -> "Prior":
        """The paper's prior: Eqs. 14-17 fitted to GUMS at G = 6-20, P = 0.9, R = 10/yr.

        Parameters
        ----------
        bright : {'extrapolate', 'clamp'}, keyword-only
            Stars brighter than G = 6: the polynomials extrapolated (default), or the
            value at G = 6.

        Returns
        -------
        Prior
            The prior of Eqs. 14-18.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.origin, prior.confidence, prior.ratio_R  # doctest: +FLOAT_CMP
        ('paper', 0.9, 10.0)
        >>> prior.g_min, prior.g_max  # doctest: +FLOAT_CMP
        (6.0, 20.0)
        """
        return cls(PAPER_COEFFICIENTS, G_FIT_MIN, G_FIT_MAX, PAPER_CONFIDENCE, PAPER_RATIO_R, bright, "paper")

    @classmethod
    def from_run(cls, run_dir, *, bright: str = "extrapolate") -> "Prior":
        """The prior fitted by a sigma_F90 sweep.

        Coefficients from the ``fitted`` column of the run's ``coefficients.csv``
        (rows named by ``term``: ``s0_c0`` ... ``s2_c1``); the G range (outer edges of
        the magnitude bins), P (``confidence``) and R (``ratio_R``) from the config
        recorded in ``provenance.json``.

        With ``config["prior_model"]["colour_edges"]`` not empty, also the coefficients
        per BP-RP bin (``colour_coefficients.csv``, ``mcsweep.prior.colour``); with
        ``config["prior_model"]["mean"]`` the prior's centre per cell
        (``prior_means.csv`` on the grid of ``config["sky"]``, ``mcsweep.prior.means``).
        A run without ``prior_model`` (or with the default ``direction_g``) reads as the
        colour-blind, zero-centred prior of Eqs. 14-18.

        Parameters
        ----------
        run_dir : str or path-like
            A finished sweep's run directory.
        bright : {'extrapolate', 'clamp'}, keyword-only
            Stars brighter than the fit range: the polynomials extrapolated (default), or
            the value at its bright edge.

        Returns
        -------
        Prior
            The run's fitted prior.

        Raises
        ------
        mcsweep.errors.UserInputError
            If the directory is not a finished sweep with fitted coefficients.

        Examples
        --------
        These read a run's files; the lines are skipped when the examples run as
        tests (no run directory there).

        >>> from mcsweep.prior import Prior
        >>> prior = Prior.from_run('results/default')  # doctest: +SKIP
        >>> prior.origin  # the run directory  # doctest: +SKIP
        """
        run_dir = Path(run_dir)
        coef_path = run_dir / COEFFICIENTS_FILE
        if not coef_path.is_file():
            raise UserInputError(f"run directory {run_dir} has no {COEFFICIENTS_FILE}; expected the directory "
                                 "of a finished mcsweep sigma_F90 sweep")
        coefficients = read_coefficients(coef_path)
        record = read_record(run_dir, "expected a sigma_F90 sweep (experiment=f90_sweep)")
        colour_edges = record.colour_edges
        colour = ColourBins.read(run_dir / COLOUR_COEFFICIENTS_FILE, colour_edges) if colour_edges else None
        means = PriorMeans.read(run_dir / MEANS_FILE, record.sky, colour_edges) if record.mean else None
        confidence = PAPER_CONFIDENCE if record.confidence is None else record.confidence
        ratio_r = PAPER_RATIO_R if record.ratio_R is None else record.ratio_R
        return cls(coefficients, float(min(record.g_edges)), float(max(record.g_edges)), confidence, ratio_r,
                   bright, str(run_dir), colour, means)

    @property
    def has_colour(self) -> bool:
        """True if the prior has a width per BP-RP bin (a run with ``prior_model.colour_edges``).

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.has_colour, prior.has_mean
        (False, False)
        """
        return self.colour is not None

    @property
    def has_mean(self) -> bool:
        """True if the prior is centred on the model's mean parallax and proper motion per cell.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.has_mean
        False
        """
        return self.means is not None

    # -- queries ------------------------------------------------------------------------
    def colour_bin(self, bp_rp) -> np.ndarray:
        """Index of each star's colour bin (outer bins extended), -1 for the colour-blind prior.

        Parameters
        ----------
        bp_rp : array_like or astropy.units.Quantity
            Gaia BP - RP, mag; NaN where unknown.

        Returns
        -------
        ndarray of int
            The bin of each star in the run's ``prior_model.colour_edges``; -1 without a colour,
            and everywhere for a prior without a colour axis. Labels: :meth:`colour_bin_label`.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.colour_bin([0.4, 1.5])  # no colour axis: -1 everywhere
        array([-1, -1])
        """
        if self.colour is None:
            return np.full(np.shape(colour_values(bp_rp)), -1)
        return self.colour.index(bp_rp)

    def colour_bin_label(self, bp_rp) -> np.ndarray:
        """Which prior each star gets, by name.

        Parameters
        ----------
        bp_rp : array_like or astropy.units.Quantity
            Gaia BP - RP, mag; NaN where unknown.

        Returns
        -------
        ndarray of str
            The star's BP-RP bin as ``'lo..hi'`` (mag) or ``'colour_blind'``.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.colour_bin_label([0.4, float('nan')])
        array(['colour_blind', 'colour_blind'], dtype='<U12')
        """
        from .colour import COLOUR_BLIND

        if self.colour is None:
            return np.full(np.shape(colour_values(bp_rp)), COLOUR_BLIND)
        return self.colour.label(self.colour.index(bp_rp))

    def _sigma(self, l_deg, b_deg, G, coefficients) -> np.ndarray:
        g_low = self.g_min if self.bright == "clamp" else None
        return sigma_from_coefficients(l_deg, b_deg, G, coefficients, g_min=g_low, g_max=self.g_max)

    def sigma_parallax_mas(self, l_deg, b_deg, G, bp_rp=None) -> np.ndarray:
        """sigma_F90 (Eqs. 14-17) as a plain array, for hot paths.

        Parameters
        ----------
        l_deg, b_deg : array_like
            Galactic longitude and latitude, deg.
        G : array_like
            Gaia G, mag (beyond ``g_max``: the value at ``g_max``; below ``g_min``: as
            ``bright`` says).
        bp_rp : array_like, optional
            BP - RP, mag (broadcast; NaN where unknown): selects the coefficients of the star's
            colour bin; None or NaN: the colour-blind prior. Ignored by a prior without a
            colour axis.

        Returns
        -------
        ndarray
            sigma_F90 of the parallax, mas (the broadcast shape of the inputs).

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> import numpy as np
        >>> l, b, g = [0.0, 90.0], [0.0, 30.0], [15.0, 15.0]  # deg, deg, mag
        >>> np.round(prior.sigma_parallax_mas(l, b, g), 4)  # doctest: +FLOAT_CMP
        array([0.5501, 1.2926])
        """
        if bp_rp is None or self.colour is None:
            return self._sigma(l_deg, b_deg, G, self.coefficients)
        idx = self.colour.index(bp_rp)
        if np.all(idx < 0):  # colour-blind for every star: exactly the plain evaluation
            plain = self._sigma(l_deg, b_deg, G, self.coefficients)
            return np.broadcast_to(plain, np.broadcast_shapes(plain.shape, idx.shape)).copy()
        l_deg, b_deg, g, idx = np.broadcast_arrays(np.asarray(l_deg, float), np.asarray(b_deg, float),
                                                   np.asarray(G, float), idx)
        out = np.empty(idx.shape)
        for k in np.unique(idx):  # one evaluation per colour bin present (Eq. 14 with its coefficients)
            sel = idx == k
            if k < 0:
                out[sel] = self._sigma(l_deg[sel], b_deg[sel], g[sel], self.coefficients)
            else:
                out[sel] = self.colour.sigma_mas(int(k), l_deg[sel], b_deg[sel], g[sel], self.g_min, self.g_max,
                                                 self.bright)
        return out

    def _mean_galactic(self, l_deg, b_deg, G, bp_rp):
        slot = None if (bp_rp is None or self.colour is None) else self.colour.index(bp_rp) + 1
        return self.means.galactic(l_deg, b_deg, G, slot)

    def _zeros(self, l_deg, b_deg, G, bp_rp) -> np.ndarray:
        g = np.asarray(G, dtype=float)
        if np.any(np.isnan(g)):
            raise UserInputError("G magnitude NaN is not accepted; expected finite magnitudes")
        shapes = [np.shape(l_deg), np.shape(b_deg), g.shape]
        if bp_rp is not None and self.colour is not None:
            shapes.append(np.shape(colour_values(bp_rp)))
        return np.zeros(np.broadcast_shapes(*shapes))

    def mean_parallax_mas(self, l_deg, b_deg, G, bp_rp=None) -> np.ndarray:
        """The prior's centre in parallax, plain arrays (zeros for a zero-mean prior).

        Parameters
        ----------
        l_deg, b_deg : array_like
            Galactic longitude and latitude, deg.
        G : array_like
            G magnitude, mag, broadcast with the positions.
        bp_rp : array_like, optional
            Gaia BP-RP, mag; NaN where unknown (the run's colour-blind prior).

        Returns
        -------
        ndarray
            Mean parallax of the star's cell in the galaxy model, mas.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.mean_parallax_mas([0.0], [0.0], [15.0])
        array([0.])
        """
        if self.means is None:
            return self._zeros(l_deg, b_deg, G, bp_rp)
        return self._mean_galactic(l_deg, b_deg, G, bp_rp)[0]

    def mean_pm_masyr(self, l_deg, b_deg, G, bp_rp=None) -> tuple[np.ndarray, np.ndarray]:
        """The prior's centre in proper motion, plain arrays (zeros for a zero-mean prior).

        Parameters
        ----------
        l_deg, b_deg : array_like
            Galactic longitude and latitude, deg.
        G : array_like
            G magnitude, mag, broadcast with the positions.
        bp_rp : array_like, optional
            Gaia BP-RP, mag; NaN where unknown (the run's colour-blind prior).

        Returns
        -------
        pmra, pmdec : ndarray
            (mu_alpha*, mu_delta), mas/yr, ICRS.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> prior.mean_pm_masyr([0.0], [0.0], [15.0])
        (array([0.]), array([0.]))
        """
        if self.means is None:
            z = self._zeros(l_deg, b_deg, G, bp_rp)
            return z, z.copy()
        from ..galactic import pm_icrs_from_galactic

        _, pml, pmb = self._mean_galactic(l_deg, b_deg, G, bp_rp)
        return pm_icrs_from_galactic(l_deg, b_deg, pml, pmb)

    def sigma_parallax(self, *where, G=None, bp_rp=None) -> u.Quantity:
        """Parallax prior sigma_F90 (Eqs. 14-17) as a Quantity in mas.

        Parameters
        ----------
        *where : SkyCoord, or l and b
            A :class:`~astropy.coordinates.SkyCoord` (or frame) in any frame, or
            galactic longitude and latitude (degrees, or angle Quantities). G may
            follow as the last positional argument.
        G : array_like, keyword
            G magnitude (plain numbers or a Quantity in mag). Broadcast with the
            positions.
        bp_rp : array_like, keyword, optional
            Gaia BP-RP in mag (numbers or a Quantity), broadcast with the others; NaN
            where unknown gives the colour-blind prior of the same run. Ignored by a
            prior without a colour axis (:attr:`has_colour`).

        Returns
        -------
        Quantity
            In mas, broadcast shape of the inputs.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> # galactic l, b [deg] and G: the paper's Table 1 beam
        >>> Prior.paper().sigma_parallax(245.7, 46.5, 15.0)  # doctest: +FLOAT_CMP
        <Quantity 1.85478666 mas>
        """
        l_deg, b_deg, g = self._parse(where, G)
        return self.sigma_parallax_mas(l_deg, b_deg, g, bp_rp) * u.mas

    def sigma_pm(self, *where, G=None, bp_rp=None) -> u.Quantity:
        """Proper-motion prior ``R * sigma_F90`` (Eq. 18) as a Quantity in mas/yr.

        Parameters
        ----------
        *where : SkyCoord, or l and b
            As for :meth:`sigma_parallax`: a SkyCoord in any frame, or galactic l and b
            (degrees or angle Quantities); G may follow as the last one.
        G : array_like, keyword
            G magnitude (numbers or a Quantity in mag), broadcast with the positions.
        bp_rp : array_like, keyword, optional
            Gaia BP-RP in mag; NaN where unknown (the run's colour-blind prior).

        Returns
        -------
        Quantity
            In mas/yr, broadcast shape of the inputs.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> from astropy.coordinates import SkyCoord
        >>> import astropy.units as u
        >>> c = SkyCoord(ra=[10.68, 266.4] * u.deg, dec=[41.27, -28.9] * u.deg)
        >>> prior.sigma_pm(c, G=[12.0, 18.0])  # doctest: +FLOAT_CMP
        <Quantity [18.20898358,  3.88854608] mas / yr>
        """
        l_deg, b_deg, g = self._parse(where, G)
        return self.ratio_R * self.sigma_parallax_mas(l_deg, b_deg, g, bp_rp) * (u.mas / u.yr)

    def mean_parallax(self, *where, G=None, bp_rp=None) -> u.Quantity:
        """Centre of the parallax prior as a Quantity in mas; zero for a zero-mean prior.

        For a run with ``prior_model.mean``, the galaxy model's mean parallax of the
        star's cell, interpolated (``mcsweep.prior.means``).

        Parameters
        ----------
        *where : SkyCoord, or l and b
            As for :meth:`sigma_parallax`: a SkyCoord in any frame, or galactic l and b
            (degrees or angle Quantities); G may follow as the last one.
        G : array_like, keyword
            G magnitude (numbers or a Quantity in mag), broadcast with the positions.
        bp_rp : array_like, keyword, optional
            Gaia BP-RP in mag; NaN where unknown (the run's colour-blind prior).

        Returns
        -------
        Quantity
            In mas, broadcast shape of the inputs.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> from astropy.coordinates import SkyCoord
        >>> import astropy.units as u
        >>> c = SkyCoord(ra=[10.68, 266.4] * u.deg, dec=[41.27, -28.9] * u.deg)
        >>> prior.mean_parallax(c, G=[12.0, 18.0])  # zero-centred
        <Quantity [0., 0.] mas>
        """
        l_deg, b_deg, g = self._parse(where, G)
        return self.mean_parallax_mas(l_deg, b_deg, g, bp_rp) * u.mas

    def mean_pm(self, *where, G=None, bp_rp=None) -> tuple[u.Quantity, u.Quantity]:
        """Centre of the proper-motion prior, ``(pmra*, pmdec)`` Quantities in mas/yr, ICRS.

        ``pmra* = mu_alpha cos(delta)`` as in the Gaia archive's ``pmra``. Zero for a
        zero-mean prior.

        Parameters
        ----------
        *where : SkyCoord, or l and b
            As for :meth:`sigma_parallax`: a SkyCoord in any frame, or galactic l and b
            (degrees or angle Quantities); G may follow as the last one.
        G : array_like, keyword
            G magnitude (numbers or a Quantity in mag), broadcast with the positions.
        bp_rp : array_like, keyword, optional
            Gaia BP-RP in mag; NaN where unknown (the run's colour-blind prior).

        Returns
        -------
        pmra, pmdec : Quantity
            In mas/yr, broadcast shape of the inputs.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> from astropy.coordinates import SkyCoord
        >>> import astropy.units as u
        >>> c = SkyCoord(ra=[10.68, 266.4] * u.deg, dec=[41.27, -28.9] * u.deg)
        >>> prior.mean_pm(c, G=[12.0, 18.0])
        (<Quantity [0., 0.] mas / yr>, <Quantity [0., 0.] mas / yr>)
        """
        l_deg, b_deg, g = self._parse(where, G)
        pmra, pmdec = self.mean_pm_masyr(l_deg, b_deg, g, bp_rp)
        return pmra * (u.mas / u.yr), pmdec * (u.mas / u.yr)

    def normal_matrix(self, *where, G=None, bp_rp=None, factor: float = 1.0) -> np.ndarray:
        """Prior normal matrix N_p of Eq. 18 for every star.

        ``N_p = diag(0, 0, sigma_plx^-2, sigma_mu^-2, sigma_mu^-2)`` with
        ``sigma_plx = factor * sigma_F90`` and ``sigma_mu = R sigma_plx``; parameter
        order (dalpha*, ddelta, parallax, pmra, pmdec) as in :mod:`mcsweep.astrometry`.
        The prior's centre (:meth:`mean_parallax`, :meth:`mean_pm`) enters the
        right-hand side as ``N_p m`` (Eqs. 11-12).

        Parameters
        ----------
        *where : SkyCoord, or l and b
            As for :meth:`sigma_parallax`.
        G : array_like, keyword
            G magnitude, mag.
        bp_rp : array_like, keyword, optional
            Gaia BP-RP, mag.
        factor : float, keyword-only
            Multiplier K of sigma_F90 (Sect. 3.3: priors up to ~10 x sigma_F90 keep
            the errors at the same level with conservative formal uncertainties).

        Returns
        -------
        ndarray, shape ``broadcast_shape + (5, 5)``
            In mas^-2 (parallax) and (mas/yr)^-2 (proper motion); no units attached
            because they differ between elements.

        Examples
        --------
        >>> from mcsweep.prior import Prior
        >>> prior = Prior.paper()
        >>> from astropy.coordinates import SkyCoord
        >>> import astropy.units as u
        >>> c = SkyCoord(ra=[10.68, 266.4] * u.deg, dec=[41.27, -28.9] * u.deg)
        >>> import numpy as np
        >>> N_p = prior.normal_matrix(c, G=[12.0, 18.0])
        >>> N_p.shape
        (2, 5, 5)
        >>> # sigma_plx, sigma_mu, sigma_mu of the first star
        >>> np.round(1 / np.sqrt(N_p[0].diagonal()[2:]), 3)  # doctest: +FLOAT_CMP
        array([ 1.821, 18.209, 18.209])
        """
        if not (np.isscalar(factor) and factor > 0 and math.isfinite(factor)):
            raise UserInputError(f"factor={factor!r} is not accepted; expected a positive finite number")
        l_deg, b_deg, g = self._parse(where, G)
        w_plx = 1.0 / (factor * self.sigma_parallax_mas(l_deg, b_deg, g, bp_rp)) ** 2
        out = np.zeros(w_plx.shape + (5, 5))
        out[..., 2, 2] = w_plx
        out[..., 3, 3] = out[..., 4, 4] = w_plx / self.ratio_R**2
        return out

    def __repr__(self) -> str:
        extra = (f", colour bins {list(self.colour.labels)}" if self.colour is not None else "") \
            + (", mean-centred" if self.means is not None else "")
        return (f"Prior(origin={self.origin!r}, G {self.g_min:g}-{self.g_max:g}, P={self.confidence:g}, "
                f"R={self.ratio_R:g}/yr, bright={self.bright!r}{extra})")

    # -- argument handling --------------------------------------------------------------
    @staticmethod
    def _parse(where: tuple, G) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        where = list(where)
        is_coord = bool(where) and hasattr(where[0], "transform_to")
        n_pos = 1 if is_coord else 2
        if len(where) == n_pos + 1 and G is None:
            G = where.pop()
        if len(where) != n_pos or G is None:
            raise TypeError("expected (coord, G) with coord a SkyCoord, or (l, b, G) with galactic l, b in "
                            f"degrees; got {len(where)} positional argument(s) and G={'set' if G is not None else 'None'}")
        if is_coord:
            gal = where[0].transform_to(Galactic())
            l_deg, b_deg = gal.l.to_value(u.deg), gal.b.to_value(u.deg)
        else:
            l_deg, b_deg = (_angle_deg(v, name) for v, name in zip(where, ("l", "b")))
        if isinstance(G, u.Quantity):
            G = G.value * unit_scale(G.unit, "mag", "G")
        return l_deg, b_deg, np.asarray(G, dtype=float)


def _angle_deg(value, name: str) -> np.ndarray:
    if isinstance(value, u.Quantity):
        return value.value * unit_scale(value.unit, "angle", name)
    if isinstance(value, SkyCoord):  # pragma: no cover - caught by _parse
        raise TypeError(f"{name} must be a number, not a SkyCoord")
    return np.asarray(value, dtype=float)


def sigma_f90(l_deg, b_deg, G, *, bright: str = "extrapolate") -> np.ndarray:
    """Optimum parallax prior sigma_F90 in mas (paper Eqs. 14-17), as plain numbers.

    The paper's formula, through :meth:`Prior.paper` (kept for existing callers).

    Parameters
    ----------
    l_deg, b_deg : array_like
        Galactic longitude and latitude, degrees.
    G : array_like
        G magnitude; broadcast with ``l_deg``, ``b_deg``. G > 20 uses G = 20 (paper
        Sect. 3.4).
    bright : {"extrapolate", "clamp"}, keyword-only
        Treatment of G < 6 (``mcsweep.prior.formula``): evaluate the polynomials
        (default) or use the value at G = 6.

    Returns
    -------
    ndarray
        sigma_F90 in mas.

    Examples
    --------
    >>> import numpy as np
    >>> from mcsweep.prior import sigma_f90
    >>> # Eqs. 14-17 at (l, b) = (0, 0) and (180, 90) deg, G = 15, mas
    >>> np.round(sigma_f90([0.0, 180.0], [0.0, 90.0], 15.0), 4)  # doctest: +FLOAT_CMP
    array([0.5501, 2.633 ])
    """
    return _paper(check_bright(bright)).sigma_parallax_mas(l_deg, b_deg, G)


@lru_cache(maxsize=None)
def _paper(bright: str) -> Prior:
    return Prior.paper(bright=bright)
