"""
Solve few-transit sources with the prior
========================================

A source seen in a handful of field-of-view transits has no usable five-parameter
solution on its own; with the prior (sigma_plx = K sigma_F90, sigma_mu = R sigma_plx) it
has one whose P confidence ellipse holds the true position P of the time (Sect. 3).
``examples/prior_solve/`` holds 1-8 transits per source written by ``mcsweep-prior
simulate`` (the flown scanning law over 60 days); this is what ``mcsweep-prior solve``
computes, from Python: :func:`mcsweep.prior.observations.read_observations` and
:func:`mcsweep.prior.observations.solve_observations`.
"""

from pathlib import Path

import matplotlib.pyplot as plt
from matplotlib.patches import Ellipse

from mcsweep.prior import Prior
from mcsweep.prior.observations import (
    read_observations,
    solve_observations,
)

try:
    here = Path(__file__).resolve().parent
except NameError:
    # sphinx-gallery runs the script from the examples folder
    here = Path.cwd()
data = here / "prior_solve"

obs = read_observations(data / "observations.csv", data / "sources.csv")
solutions = solve_observations(obs, Prior.paper())
columns = [
    "source_id",
    "n_transits",
    "parallax_mas",
    "parallax_error_mas",
    "ellipse_semi_major_mas",
    "ellipse_semi_minor_mas",
    "no_prior_ok",
]
print(solutions[columns].head(8).to_string(index=False, line_width=75))

# %%
# The simulator wrote the true parameters into ``sources.csv`` (``true_parallax_mas``,
# ``true_pmra_mas_yr``, ``true_pmdec_mas_yr``); each source sits at its reference
# position at its mean epoch, so the estimated offset is the actual position error.
#
# The actual position errors (+) against the 90 % ellipses of sources with at most four
# transits (x to the east, drawn to the left as on the sky).
few = solutions[solutions["n_transits"] <= 4].head(6)
fig, axes = plt.subplots(2, 3, figsize=(8, 5.5))
for ax, (_, row) in zip(axes.flat, few.iterrows()):
    a, b = row["ellipse_semi_major_mas"], row["ellipse_semi_minor_mas"]
    # the position angle runs from north through east;
    # matplotlib's angle from +x (east) to +y (north)
    ax.add_patch(
        Ellipse(
            (0, 0),
            2 * a,
            2 * b,
            angle=90.0 - row["ellipse_position_angle_deg"],
            fill=False,
            color="r",
        )
    )
    ax.plot(row["dalpha_star_mas"], row["ddelta_mas"], "k+")
    lim = 1.3 * a
    ax.set_xlim(lim, -lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_title(
        f"{row['source_id']}: {row['n_transits']} transits", fontsize=8
    )
fig.suptitle(
    "actual position error (+) and the 90 % confidence ellipse [mas]",
    fontsize=9,
)
fig.tight_layout()
