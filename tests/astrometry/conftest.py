"""Shared geometry for the astrometry tests: the paper's Table 1 observations."""

import numpy as np
import pytest
from astropy.time import Time

# Paper Table 1 (alpha = 157.5 deg, delta = 0 deg): UTC date/time, FoV, scan position
# angle psi [deg], distinct-transit group.
TABLE1_RA_DEG = 157.5
TABLE1_DEC_DEG = 0.0
TABLE1_ROWS = [
    ("2014-10-30 17:00", "P", 230, 1), ("2014-10-30 18:48", "F", 230, 1),
    ("2014-11-20 17:00", "P", 156, 2), ("2014-11-20 18:48", "F", 156, 2),
    ("2014-12-19 16:36", "P", 247, 3), ("2014-12-19 18:24", "F", 247, 3),
    ("2015-04-29 05:12", "P", 341, 4), ("2015-04-29 07:00", "F", 342, 4),
    ("2015-05-23 18:54", "F", 65, 5),
    ("2015-06-21 04:54", "P", 344, 6), ("2015-06-21 06:42", "F", 344, 6),
    ("2015-11-09 06:06", "P", 238, 7), ("2015-11-09 07:54", "F", 238, 7),
    ("2015-12-29 11:48", "P", 243, 8), ("2015-12-29 13:36", "F", 244, 8),
]


@pytest.fixture(scope="session")
def table1():
    """Table 1 transits: tcb_jd, psi_deg, group (arrays of 15) and the star direction."""
    tcb_jd = Time([r[0] for r in TABLE1_ROWS], scale="utc").tcb.jd
    return {
        "ra_deg": TABLE1_RA_DEG,
        "dec_deg": TABLE1_DEC_DEG,
        "tcb_jd": np.asarray(tcb_jd, dtype=float),
        "psi_deg": np.array([r[2] for r in TABLE1_ROWS], dtype=float),
        "group": np.array([r[3] for r in TABLE1_ROWS]),
    }
