"""Per-FoV-transit measurement uncertainties of Gaia, along and across scan.

Along scan (AL)
---------------
Perryman, Hartman, Bakos & Lindegren (2014, ApJ 797, 14, Eqs. 1-3; "Astrometric
exoplanet detection with Gaia") give the AL accuracy per field-of-view crossing from
the post-commissioning performance assessment:

    z        = 10^(0.4 (max(G, 12) - 15))
    sigma_eta^2 = 53000 z + 310 z^2                       [uas^2, one AF CCD]
    sigma_fov^2 = sigma_eta^2 / 9 + sigma_att^2 + sigma_cal^2,  sigma_att = sigma_cal = 20 uas

i.e. photon noise of one CCD transit averaged over the 9 astrometric-field CCDs of a
FoV transit, plus attitude and calibration errors. Numbers: 0.034 mas at G <= 12,
0.042 mas at G = 13, 0.082 mas at G = 15, 0.25 mas at G = 17.5, 0.97 mas at G = 20.
Provenance and accuracy: the formula was taken from a transcription in public code
(bmorris3/mrspoc, ``mrspoc/gaia.py``, two versions, citing "Perryman et al. 2014,
Eqn. 1-3"); the value at G <= 12 (34.23 uas) matches a number used in an unrelated
public code (a Gaia/TESS Fisher-matrix script). The paper itself could not be
consulted here, so the equation numbers are as cited there. The model is a
prediction made before DR1, good to a factor ~2: it ignores the calibration-limited floor of the
real bright-star data and the extra noise of crowded fields. As a cross-check, the
test-suite compares it with the Gaia (E)DR3 sky-averaged parallax uncertainty
relation (Lindegren et al. 2021, A&A 649, A2; the Gaia science-performance pages):
with ~35 FoV transits spread over the 34 months of EDR3, the model's parallax
uncertainty is 1.0 times the EDR3 value at G = 13, 0.8 at G = 17 and 0.5 at G = 20,
i.e. the model is optimistic for faint stars by up to a factor 2 (use ``al_scale``).

Across scan (AC)
----------------
Gaia measures AC positions much less precisely, for two reasons given in the mission
description (Gaia Collaboration, Prusti et al. 2016, A&A 595, A1, Sect. 3.3; de
Bruijne 2012, Ap&SS 341, 31): (1) the image is about 3 times wider AC than AL (the
primary mirrors are 1.45 m x 0.50 m, the pixels 59 mas x 177 mas AL x AC), and the
centroiding error scales with the image width; (2) only stars with G < 13 get
two-dimensional windows in the 9 astrometric-field CCDs; for fainter stars the AF
windows are binned across scan and the only AC information comes from the single
sky-mapper (SM) window. Hence the model

    sigma_ac^2 = (3 sigma_eta)^2 / N_AC + 3^2 (sigma_att^2 + sigma_cal^2),
    N_AC = 9 for G < 13 (2D AF windows), 1 for G >= 13 (SM only),

giving sigma_ac / sigma_al ~ 3 for G < 13 and ~ 7-9 for G >= 13 (0.10 mas at
G = 12, 0.70 mas at G = 15, 8.7 mas at G = 20). This is a derived, approximate
model (factor ~2; the 2 x 2 binned SM samples degrade it further, which is not
modelled); use ``ac_scale`` to explore it, or ``use_ac=False`` to drop AC entirely.

Calibration-limited floor (option, default off)
-----------------------------------------------
``al_floor_mas`` adds an extra AL error per FoV transit in quadrature:

    sigma_al = sqrt((al_scale sigma_fov)^2 + al_floor^2).

Default 0: the model above, unchanged. The real Gaia data of bright stars are
limited by attitude and calibration errors well above the photon noise: the robust
scatter of the AL residuals per CCD observation in Gaia EDR3 is ~0.15 mas at
G ~ 9-13 (Lindegren et al. 2021, A&A 649, A2, Fig. A.1, read off the figure; see
docs/noise_floor.md for the read-off, its uncertainty and the conversion to a FoV
transit), against 0.058 mas of photon noise per CCD at G <= 12 in the model above.
The preset ``noise=edr3_floor`` holds the published value converted to one FoV
transit. AC is left as it is (no published AC floor was found).

Validity
--------
The formulas hold for 12 <= G <= 20.7 (Gaia's faint detection limit). Brighter than
G = 12 the value at G = 12 is used (Perryman et al.: gated exposures keep the photon
noise roughly constant; the real bright stars are calibration-limited at a similar
level). Fainter than G = 20.7 the formulas are extrapolated up to ``G_MAX`` = 21;
fainter or non-finite magnitudes raise :class:`mcsweep.errors.UserInputError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserInputError

__all__ = [
    "G_BRIGHT_FLOOR",
    "G_2D_WINDOW_LIMIT",
    "G_MAX",
    "NoiseModel",
]

#: Perryman et al. (2014): z uses max(G, 12); brighter stars are gated.
G_BRIGHT_FLOOR = 12.0
#: Stars brighter than this get 2D windows in the AF CCDs (Gaia Collaboration 2016, Sect. 3.3).
G_2D_WINDOW_LIMIT = 13.0
#: Faintest accepted magnitude (Gaia's detection limit is G ~ 20.7).
G_MAX = 21.0

# Perryman et al. (2014) Eqs. 1-3, in micro-arcsec.
_ETA_LINEAR_UAS2 = 53000.0  # photon-noise term of sigma_eta^2 per CCD, uas^2
_ETA_QUADRATIC_UAS2 = 310.0  # background/readout term of sigma_eta^2 per CCD, uas^2
_N_AF_CCD = 9  # astrometric-field CCDs crossed in one FoV transit
_SIGMA_ATT_UAS = 20.0  # attitude error per FoV transit, uas
_SIGMA_CAL_UAS = 20.0  # calibration error per FoV transit, uas
# AC/AL image-width ratio: aperture 1.45 m / 0.50 m = 2.9, pixels 177 mas / 59 mas = 3.
_AC_WIDTH_RATIO = 3.0
_N_AC_2D = 9  # AF CCDs with 2D windows for G < 13
_N_AC_SM = 1  # only the sky-mapper window for G >= 13


@dataclass(frozen=True)
class NoiseModel:
    """Per-FoV-transit AL and AC uncertainties as functions of G (module notes).

    Parameters
    ----------
    al_scale : float
        Multiplies the AL uncertainty (positive).
    ac_scale : float
        Multiplies the AC uncertainty (positive).
    use_ac : bool
        Whether AC measurements enter the solution. The model always returns AC
        numbers; callers consult this flag (see :meth:`design_sigmas`).
    al_floor_mas : float
        Extra AL error per FoV transit in mas, added in quadrature after ``al_scale``
        (non-negative; 0 = the published model alone; module notes).

    Examples
    --------
    >>> from mcsweep.astrometry.noise import NoiseModel
    >>> model = NoiseModel(al_floor_mas=0.039)  # noise=edr3_floor
    >>> round(float(model.sigma_al_mas(10.0)), 4)  # mas per FoV transit  # doctest: +FLOAT_CMP
    0.0519
    """

    al_scale: float = 1.0
    ac_scale: float = 1.0
    use_ac: bool = True
    al_floor_mas: float = 0.0

    def __post_init__(self):
        for name in ("al_scale", "ac_scale"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v > 0):
                raise UserInputError(f"{name}={v!r} is not accepted; expected a positive finite factor")
        f = self.al_floor_mas
        if not (isinstance(f, (int, float, np.floating, np.integer)) and not isinstance(f, bool)
                and np.isfinite(f) and f >= 0):
            raise UserInputError(f"al_floor_mas={f!r} is not accepted; expected a non-negative finite "
                                 "AL error per FoV transit in mas")
        if not isinstance(self.use_ac, (bool, np.bool_)):
            raise UserInputError(f"use_ac={self.use_ac!r} is not accepted; expected true or false")

    @classmethod
    def from_config(cls, cfg) -> "NoiseModel":
        """Build the model from the ``noise`` config section.

        Parameters
        ----------
        cfg : mapping or object
            With ``al_scale``, ``ac_scale``, ``use_ac`` and ``al_floor_mas`` (any missing
            one takes its default).

        Returns
        -------
        NoiseModel
            The model; a bad value raises :class:`~mcsweep.errors.UserInputError`.

        Examples
        --------
        >>> from mcsweep.astrometry.noise import NoiseModel
        >>> model = NoiseModel.from_config({'al_scale': 2.0, 'use_ac': False})
        >>> model.al_scale, model.use_ac  # doctest: +FLOAT_CMP
        (2.0, False)
        """
        get = cfg.get if hasattr(cfg, "get") else lambda k, d: getattr(cfg, k, d)
        return cls(al_scale=float(get("al_scale", 1.0)), ac_scale=float(get("ac_scale", 1.0)),
                   use_ac=bool(get("use_ac", True)), al_floor_mas=float(get("al_floor_mas", 0.0)))

    def sigma_al_mas(self, G) -> np.ndarray:
        """AL uncertainty per FoV transit (Perryman et al. 2014, Eqs. 1-3).

        With the optional floor ``al_floor_mas`` in quadrature (module notes).

        Parameters
        ----------
        G : float or array_like
            Gaia G magnitudes, within 0..21 (brighter than G = 12 the value at 12).

        Returns
        -------
        ndarray
            sigma_AL per FoV transit, mas, the shape of ``G``.

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.astrometry.noise import NoiseModel
        >>> g = np.array([10.0, 15.0, 20.0])
        >>> np.round(NoiseModel().sigma_al_mas(g), 4)  # doctest: +FLOAT_CMP
        array([0.0342, 0.082 , 0.9665])
        """
        eta2 = _sigma_eta2_uas2(G)
        var = eta2 / _N_AF_CCD + _SIGMA_ATT_UAS**2 + _SIGMA_CAL_UAS**2
        sigma = self.al_scale * 1e-3 * np.sqrt(var)
        if self.al_floor_mas == 0:
            return sigma  # the published model exactly, bit for bit
        return np.sqrt(sigma**2 + self.al_floor_mas**2)

    def sigma_ac_mas(self, G) -> np.ndarray:
        """AC uncertainty per FoV transit (module notes).

        Parameters
        ----------
        G : float or array_like
            Gaia G magnitudes, within 0..21 (brighter than G = 12 the value at 12).

        Returns
        -------
        ndarray
            sigma_AC per FoV transit, mas, the shape of ``G``.

        Examples
        --------
        >>> import numpy as np
        >>> from mcsweep.astrometry.noise import NoiseModel
        >>> g = np.array([10.0, 15.0, 20.0])
        >>> np.round(NoiseModel().sigma_ac_mas(g), 4)  # doctest: +FLOAT_CMP
        array([0.1027, 0.6978, 8.6952])
        """
        g = _check_g(G)
        eta2 = _sigma_eta2_uas2(g)
        n_ac = np.where(g < G_2D_WINDOW_LIMIT, _N_AC_2D, _N_AC_SM)
        var = _AC_WIDTH_RATIO**2 * (eta2 / n_ac + _SIGMA_ATT_UAS**2 + _SIGMA_CAL_UAS**2)
        return self.ac_scale * 1e-3 * np.sqrt(var)

    def design_sigmas(self, G):
        """The AL and AC uncertainties as :func:`~mcsweep.astrometry.design_matrix` takes them.

        Parameters
        ----------
        G : float or array_like
            Gaia G magnitudes, within 0..21 (brighter than G = 12 the value at 12).

        Returns
        -------
        sigma_al : ndarray, shape (n, 1)
            AL uncertainty per FoV transit, mas.
        sigma_ac : ndarray, shape (n, 1), or None
            AC uncertainty per FoV transit, mas; None when ``use_ac`` is False.

        Examples
        --------
        >>> from mcsweep.astrometry.noise import NoiseModel
        >>> al, ac = NoiseModel(use_ac=False).design_sigmas([12.0, 18.0])
        >>> al.shape, ac
        ((2, 1), None)
        """
        g = np.atleast_1d(np.asarray(G, dtype=float))[:, None]
        return self.sigma_al_mas(g), (self.sigma_ac_mas(g) if self.use_ac else None)


def _check_g(G) -> np.ndarray:
    g = np.asarray(G, dtype=float)
    if not np.all(np.isfinite(g)):
        raise UserInputError("G magnitude NaN/inf is not accepted; expected finite G <= 21")
    if np.any(g > G_MAX):
        raise UserInputError(
            f"G={float(np.max(g)):.3g} is not accepted by the noise model; expected G <= {G_MAX} "
            "(Gaia does not observe fainter sources)")
    return g


def _sigma_eta2_uas2(G) -> np.ndarray:
    """Single-CCD AL centroiding variance in uas^2 (Perryman et al. 2014)."""
    g = _check_g(G)
    z = 10.0 ** (0.4 * (np.maximum(g, G_BRIGHT_FLOOR) - 15.0))
    return _ETA_LINEAR_UAS2 * z + _ETA_QUADRATIC_UAS2 * z * z
