"""The parallax and proper-motion prior of Michalik et al. (2015, Sect. 3.4, Eqs. 14-18).

Modules
-------
formula
    Eqs. 14-17 for any coefficients; the paper's coefficient table and fit range.
model
    :class:`Prior`: the paper's prior or a run's fit, queried with SkyCoord or (l, b)
    and G; :func:`sigma_f90` (the paper's formula as plain numbers).
run_record
    What a sweep's run directory holds for the prior: file names, the coefficient schema,
    the run's parsed record (:class:`~.run_record.SweepRecord`).
"""

from ..lazy_exports import attach

# imported on first use (mcsweep.lazy_exports): the config schema needs two of these names,
# not scipy.stats, astropy and pandas
__getattr__, __dir__, __all__ = attach(__name__, {
    "formula": ["BRIGHT_CHOICES", "G_FIT_MAX", "G_FIT_MIN", "PAPER_COEFFICIENTS", "s_coefficients",
                "sigma_from_coefficients"],
    "model": ["PAPER_CONFIDENCE", "PAPER_RATIO_R", "Prior", "sigma_f90"],
    "run_record": ["COEFFICIENTS_FILE"],
})
