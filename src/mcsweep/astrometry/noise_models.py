"""The noise models, by the name the config's ``noise.model`` gives: one registry.

A noise model gives the per-FoV-transit AL and AC uncertainties of a star of magnitude G.
Every experiment builds its model with :func:`noise_model` from the ``noise`` config
section (``mcsweep.command.schema.NoiseConf``, whose check is this function too), so a new
model is one class and one :func:`register` call: it is then ``noise.model=<name>`` on
every command line, and a run records it with its config. The section's other keys are
the published model's settings (``al_scale``, ``ac_scale``, ``use_ac``, ``al_floor_mas``);
a model reads those it understands from the section in its ``from_config``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import UserInputError
from .noise import NoiseModel

__all__ = ["PUBLISHED", "NoiseModelLike", "NOISE_MODELS", "register", "noise_model"]

#: The published model of :mod:`mcsweep.astrometry.noise` (Perryman et al. 2014), the default.
PUBLISHED = "published"


@runtime_checkable
class NoiseModelLike(Protocol):
    """What the experiments use of a noise model.

    Examples
    --------
    >>> from mcsweep.astrometry.noise import NoiseModel
    >>> from mcsweep.astrometry.noise_models import NoiseModelLike
    >>> isinstance(NoiseModel(), NoiseModelLike)
    True
    """

    #: Whether AC measurements enter the solution.
    use_ac: bool

    def sigma_al_mas(self, G) -> np.ndarray:
        """AL uncertainty per FoV transit at magnitudes ``G``.

        Parameters
        ----------
        G : float or array_like
            Gaia G magnitudes.

        Returns
        -------
        ndarray
            sigma_AL, mas, the shape of ``G``.

        Examples
        --------
        >>> from mcsweep.astrometry.noise_models import noise_model
        >>> model = noise_model({})  # the published model
        >>> round(float(model.sigma_al_mas(15.0)), 4)  # mas  # doctest: +FLOAT_CMP
        0.082
        """

    def sigma_ac_mas(self, G) -> np.ndarray:
        """AC uncertainty per FoV transit at magnitudes ``G``.

        Parameters
        ----------
        G : float or array_like
            Gaia G magnitudes.

        Returns
        -------
        ndarray
            sigma_AC, mas, the shape of ``G``.

        Examples
        --------
        >>> from mcsweep.astrometry.noise_models import noise_model
        >>> round(float(noise_model({}).sigma_ac_mas(15.0)), 4)  # mas  # doctest: +FLOAT_CMP
        0.6978
        """

    def design_sigmas(self, G):
        """The uncertainties as :func:`~mcsweep.astrometry.design_matrix` takes them.

        Parameters
        ----------
        G : float or array_like
            Gaia G magnitudes.

        Returns
        -------
        sigma_al : ndarray, shape (n, 1)
            AL uncertainty per FoV transit, mas.
        sigma_ac : ndarray, shape (n, 1), or None
            AC uncertainty per FoV transit, mas; None without AC measurements.

        Examples
        --------
        >>> from mcsweep.astrometry.noise_models import noise_model
        >>> al, ac = noise_model({}).design_sigmas([12.0, 18.0])
        >>> al.shape, ac.shape
        ((2, 1), (2, 1))
        """


#: name -> class with a ``from_config(section)`` classmethod returning a :class:`NoiseModelLike`.
NOISE_MODELS: dict[str, type] = {PUBLISHED: NoiseModel}


def register(name: str, cls: type) -> None:
    """Make ``cls`` the noise model ``noise.model=name``.

    Parameters
    ----------
    name : str
        The name the config's ``noise.model`` will give; a name is registered once.
    cls : type
        A class with ``from_config(section)`` returning a :class:`NoiseModelLike`.

    Examples
    --------
    >>> from mcsweep.astrometry import noise_models
    >>> sorted(noise_models.NOISE_MODELS)  # register(name, cls) adds
    ['published']
    """
    if name in NOISE_MODELS and NOISE_MODELS[name] is not cls:
        raise ValueError(f"noise model {name!r} is already registered ({NOISE_MODELS[name].__name__})")
    NOISE_MODELS[name] = cls


def noise_model(section) -> NoiseModelLike:
    """Build the noise model a ``noise`` config section names.

    Parameters
    ----------
    section : mapping or object
        The ``noise`` section: ``model`` (default ``published``) and the model's settings.

    Returns
    -------
    NoiseModelLike
        The registered model of that name, built from the section.

    Raises
    ------
    mcsweep.errors.UserInputError
        One line naming the ``noise.`` key, for an unknown name or a bad setting.

    Examples
    --------
    >>> from mcsweep.astrometry.noise_models import noise_model
    >>> model = noise_model({'model': 'published', 'al_floor_mas': 0.039})
    >>> type(model).__name__, model.al_floor_mas  # doctest: +FLOAT_CMP
    ('NoiseModel', 0.039)
    """
    get = section.get if hasattr(section, "get") else lambda k, d: getattr(section, k, d)
    name = get("model", PUBLISHED)
    cls = NOISE_MODELS.get(name)
    if cls is None:
        raise UserInputError(f"noise.model={name!r} is not accepted; expected one of {sorted(NOISE_MODELS)}")
    try:
        return cls.from_config(section)
    except UserInputError as exc:
        raise UserInputError(f"noise.{exc}") from None
