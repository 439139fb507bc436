"""What the primary experiment's tests share: the tiny run's settings, its config, and
synthetic stars spread over the sky (not a test module)."""

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from mcsweep.command.validate import compose_config, to_config

#: A few hundred stars per class, 1500 extra stars, 1 day knots: a run of under a minute.
TINY = ["experiment=primary", "experiment.primary.class_size=150", "experiment.primary.extra_sources=1500",
        "experiment.primary.knot_interval_hours=24", "experiment.primary.attitude_timescale_hours=192",
        "experiment.primary.priors=[F90,10F90]", "execution.progress=false", "execution.n_jobs=1"]
#: The unit tests' settings: a quarter of a year, 12 h knots, 4 day perturbations.
SHORT = ["experiment.primary.mission_years=0.25", "experiment.primary.knot_interval_hours=12",
         "experiment.primary.attitude_timescale_hours=96"]


def primary_config(overrides):
    """(typed config, plain dict) of TINY + SHORT + ``overrides``."""
    cfg = compose_config([*TINY, *SHORT, *overrides])
    return to_config(cfg), OmegaConf.to_container(cfg, resolve=True)


def synthetic_stars(n, seed):
    """``n`` stars uniform on the sky, G 12-18, of one class."""
    rng = np.random.default_rng(seed)
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    return pd.DataFrame({"ra": ra, "dec": dec, "l": ra, "b": dec, "parallax": rng.uniform(0.1, 5.0, n),
                         "pmra": rng.normal(0.0, 10.0, n), "pmdec": rng.normal(0.0, 10.0, n),
                         "phot_g_mean_mag": rng.uniform(12.0, 18.0, n), "class_key": 1500})
