"""A sweep's config and the prior reading that sweep's record accept the same skies: one check."""

from __future__ import annotations

import pandas as pd
import pytest

from mcsweep.errors import UserInputError
from mcsweep.experiments.f90_sweep.conf import SkyConf
from mcsweep.prior.means import MEANS_TABLE_COLUMNS, PriorMeans

BAD_SKIES = [
    ({"kind": "disc"}, "sky.kind='disc' is not accepted; expected 'healpix' or 'list'"),
    ({"kind": "healpix", "nside": 3}, "sky.nside=3 is not accepted; expected a power of two >= 1"),
    ({"kind": "healpix", "nside": 2, "order": "zigzag"}, "sky.order='zigzag' is not accepted; expected 'nested' or 'ring'"),
    ({"kind": "healpix", "nside": 2, "frame": "ecliptic"},
     "sky.frame='ecliptic' is not accepted; expected 'galactic' or 'icrs'"),
    ({"kind": "list", "directions": []},
     "sky.directions=[] is not accepted; expected a non-empty list of [lon_deg, lat_deg] pairs"),
    ({"kind": "list", "directions": [[10.0, 95.0]]},
     "sky.directions=[10.0, 95.0] is not accepted; expected [lon_deg in 0..360, lat_deg in -90..90] pairs"),
]


@pytest.mark.parametrize("sky, message", BAD_SKIES)
def test_a_sky_the_config_refuses_is_refused_in_a_runs_record_in_the_same_words(sky, message, tmp_path):
    with pytest.raises(UserInputError) as conf_error:
        SkyConf(**sky)
    assert str(conf_error.value) == message
    path = tmp_path / "prior_means.csv"
    pd.DataFrame({c: [1.0] for c in MEANS_TABLE_COLUMNS}).to_csv(path, index=False)
    with pytest.raises(UserInputError) as record_error:
        PriorMeans.read(path, sky)
    assert str(record_error.value) == f"{path}: the run's {message}"


def test_a_listed_skys_directions_are_read_as_floats():
    sky = {"kind": "list", "frame": "galactic", "directions": [[10, 20], [200.5, -30]]}
    assert SkyConf(**sky).directions == [[10.0, 20.0], [200.5, -30.0]]
