"""astrometry stage: Eq. 1 design matrix, simulated measurements, and the batched
least-squares / Bayesian solutions of Michalik et al. (2015, Sect. 2) for many stars.

Modules
-------
design
    Normalised AL/AC design-matrix rows of FoV transits (Eq. 1), reference epoch.
noise
    Per-FoV-transit AL/AC uncertainties as functions of G (published Gaia figures).
measurements
    Simulated normalised measurements ``h = A x_true + N(0, 1)``.
solve
    Normal equations, prior solutions (Eqs. 9-13, 18), position-only and no-prior
    solutions (:class:`Solution`).
linalg
    Batched Cholesky solver for stacks of small SPD matrices.
confidence
    Confidence ellipses, fraction inside, percentiles of actual errors (P a parameter).

Arrays are padded per star, ``n`` stars x ``k`` transits with a boolean mask; see
``docs/architecture.md``.
"""

from ..lazy_exports import attach

# imported on first use (mcsweep.lazy_exports): the config schema needs two of these names,
# not scipy.stats, astropy and pandas
__getattr__, __dir__, __all__ = attach(__name__, {
    "confidence": ["chi2_threshold", "ellipse_semi_axes", "error_percentile", "fraction_inside",
                   "inside_counts", "inside", "mahalanobis_sq"],
    "design": ["JULIAN_YEAR_DAYS", "PARAMETER_NAMES", "design_matrix", "reference_epoch", "tangent_triad",
               "years_since"],
    "measurements": ["simulate"],
    "noise": ["NoiseModel"],
    "noise_models": ["NOISE_MODELS", "noise_model"],
    "solve": ["DEFAULT_MAX_CONDITION", "DEFAULT_RATIO_R", "Solution", "normal_equations", "prior_diagonal",
              "solve_no_prior", "solve_position_only", "solve_with_prior"],
})
