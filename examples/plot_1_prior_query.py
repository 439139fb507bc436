"""
Query the prior for a few stars
===============================

:class:`mcsweep.prior.Prior` is the all-sky parallax and proper-motion prior of the paper's
Eqs. 14-18. Load it once, then query it with sky coordinates in any frame (or galactic
l, b in degrees) and G; scalars and arrays broadcast.
"""

import astropy.units as u
import matplotlib.pyplot as plt
import numpy as np
from astropy.coordinates import SkyCoord

from mcsweep.prior import Prior

# or Prior.from_run("results/default"): a sweep's own fit
prior = Prior.paper()

# %%
# Three stars: M31's direction, the Galactic centre and the north Galactic pole.
stars = SkyCoord(
    ra=[10.68, 266.4, 192.86] * u.deg, dec=[41.27, -28.9, 27.13] * u.deg
)
G = np.array([12.0, 18.0, 15.0])
print("sigma_F90 (parallax):", prior.sigma_parallax(stars, G=G))
print("sigma_mu = R sigma_F90:", prior.sigma_pm(stars, G=G))
print("N_p of Eq. 18 has shape", prior.normal_matrix(stars, G=G).shape)

# %%
# The same prior against G in three directions, in galactic coordinates.
g = np.linspace(6, 21, 151)
fig, ax = plt.subplots(figsize=(6, 4))
for l_deg, b_deg in [(0, 0), (90, 30), (180, 90)]:
    ax.plot(
        g,
        prior.sigma_parallax(l_deg, b_deg, G=g).to_value(u.mas),
        label=f"l = {l_deg}, b = {b_deg} deg",
    )
ax.axvspan(
    prior.g_max,
    g.max(),
    color="0.9",
    label="beyond the fit: its faint edge",
)
ax.set_yscale("log")
ax.set_xlabel("G [mag]")
ax.set_ylabel(r"$\sigma_{F90}$ [mas]")
ax.set_title("The paper's prior, Eqs. 14-17")
ax.legend(fontsize=8)
fig.tight_layout()
