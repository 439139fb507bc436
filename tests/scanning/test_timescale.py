"""The package's one epoch conversion against the calendar and the published TCB - UTC."""

import pytest
from astropy.time import Time

from mcsweep.errors import UserInputError
from mcsweep.scanning.timescale import tcb_jd

# TCB - UTC on 2015-01-01: 35 leap seconds + 32.184 s (TT - TAI) + L_B (JD - 2443144.5003725)
# * 86400 s with L_B = 1.550519768e-8 (IAU 2006 Res. B3): 67.184 + 18.67 = 85.85 s.
TCB_MINUS_UTC_2015_S = 67.184 + 1.550519768e-8 * (2457023.5 - 2443144.5003725) * 86400
SECONDS_TOL = 0.01  # s (ignores the periodic TDB - TT terms, < 2 ms)


def test_iso_string_is_read_as_tcb_calendar_date():
    # Fliegel & Van Flandern: JD of 2015-01-01 0h is 2457023.5 (no scale conversion).
    assert tcb_jd("2015-01-01T00:00:00", "x") == 2457023.5
    assert tcb_jd(2457023.25, "x") == 2457023.25


def test_utc_time_is_converted_to_tcb():
    jd = tcb_jd(Time("2015-01-01T00:00:00", scale="utc"), "x")
    assert (jd - 2457023.5) * 86400 == pytest.approx(TCB_MINUS_UTC_2015_S, abs=SECONDS_TOL)


@pytest.mark.parametrize("bad", ["first of May", True, None, Time(["2015-01-01", "2015-01-02"])])
def test_bad_epochs_name_the_setting(bad):
    with pytest.raises(UserInputError, match="observations.start="):
        tcb_jd(bad, "observations.start")
