"""The priors of the global experiments' solutions, named as the rows of Tables 2 and 3.

Each solution of a global experiment is made under one prior on parallax and proper motion
(Eq. 18, sigma_mu = R sigma_plx). The paper's rows name them: a multiple of the star's
sigma_F90 (Eqs. 14-17; "sigma_F90", "10 sigma_F90") or one sigma for every star ("0.01
mas", "1000 mas"). Settings and tables write them ``'<k>F90'`` and ``'<sigma>mas'``:
Table 2's rows (:data:`~mcsweep.experiments.secondary.table.PRIORS`), the primary's
``experiment.primary.priors`` and its factor grid all use this one grammar.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ...errors import UserInputError

__all__ = ["parse_prior", "prior_sigma_mas", "prior_label"]

_NUMBER = r"\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"
_PRIOR_RE = re.compile(rf"^(?:(?P<k>{_NUMBER})?F90|(?P<s>{_NUMBER})mas)$")


def parse_prior(label: str, key: str = "experiment.primary.priors") -> tuple[str, float]:
    """``'10F90'`` -> ('F90', 10.0); ``'1000mas'`` -> ('mas', 1000.0); a user error naming
    the setting ``key`` otherwise."""
    m = _PRIOR_RE.match(str(label).strip())
    value = None
    if m:
        kind, value = ("F90", float(m["k"] or 1.0)) if m["s"] is None else ("mas", float(m["s"]))
    if value is None or not (math.isfinite(value) and value > 0):
        raise UserInputError(f"{key} entry {label!r} is not accepted; expected "
                             "'<k>F90' (k times sigma_F90, e.g. F90, 10F90) or '<sigma>mas' (e.g. 1000mas) "
                             "with a positive number")
    return kind, value


def prior_sigma_mas(label: str, sigma_f90_mas: np.ndarray) -> np.ndarray:
    """Parallax prior sigma [mas] of every star under the prior ``label``, from the stars'
    sigma_F90 [mas]."""
    kind, value = parse_prior(label)
    return value * sigma_f90_mas if kind == "F90" else np.full(np.shape(sigma_f90_mas), value)


def prior_label(prior: str) -> str:
    """The paper's row label of a prior ('10F90' -> '10 sigma_F90', '1000mas' -> '1000 mas')."""
    if prior.endswith("F90"):
        k = prior[:-3]
        return "sigma_F90" if k in ("", "1") else f"{k} sigma_F90"
    return prior.replace("mas", " mas")
