"""Reference epoch of the global experiments (Sect. 2.1)."""

import numpy as np
import pytest
from astropy.time import Time

from mcsweep.errors import UserInputError
from mcsweep.experiments.global_solution.epoch import describe_reference_epoch, resolve_reference_epoch

START, END = 2456863.9, 2458690.1  # TCB JD


def test_dataset_mean_is_the_mid_point_for_every_star():
    t = np.array([[START + 1.0, START + 30.0, np.nan]])
    ep = resolve_reference_epoch("dataset_mean", START, END, t, np.isfinite(t))
    assert ep.shape == (1,)
    assert ep[0] == pytest.approx(0.5 * (START + END), rel=0, abs=1e-9)
    # A star seen only early in the interval: every transit is before the epoch.
    assert np.all(t[0, :2] < ep[0])


def test_star_mean_is_each_stars_own_mean():
    t = np.array([[START + 2.0, START + 4.0], [END - 4.0, END - 2.0]])
    ep = resolve_reference_epoch("star_mean", START, END, t, np.ones_like(t, dtype=bool))
    np.testing.assert_allclose(ep, [START + 3.0, END - 3.0], rtol=0, atol=1e-9)


def test_iso_date_is_read_as_tcb_and_bad_values_are_one_line_user_errors():
    ep = resolve_reference_epoch("2016-01-01T00:00:00", START, END, np.zeros((3, 2)), None)
    assert ep == pytest.approx(np.full(3, Time("2016-01-01T00:00:00", scale="tcb").jd), rel=0, abs=1e-9)
    with pytest.raises(UserInputError, match="'mid-mission'.*dataset_mean") as err:
        resolve_reference_epoch("mid-mission", START, END)
    assert "\n" not in str(err.value)


def test_description_for_provenance_and_report():
    mid = describe_reference_epoch("dataset_mean", START, END)
    assert mid["tcb_jd"] == pytest.approx(0.5 * (START + END), rel=0, abs=1e-9)
    assert mid["iso"] == Time(0.5 * (START + END), format="jd", scale="tcb").isot
    assert mid["text"] == f"{mid['iso'][:10]} (mid-point of the data set, TCB)"
    assert describe_reference_epoch("star_mean", START, END)["tcb_jd"] is None
    assert describe_reference_epoch("2016-01-01", START, END)["text"] == "2016-01-01 (fixed date, TCB)"
    assert describe_reference_epoch("2016-01-01T06:00:00", START, END)["text"] == \
        "2016-01-01T06:00:00 (fixed date, TCB)"
