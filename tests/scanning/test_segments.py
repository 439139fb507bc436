"""The flown law as segments (scanning.segments.FLOWN_SEGMENTS): each segment's attitude
against an independent evaluation of its equations, the boundaries the note declares, and the
transit search across boundaries and in the gap.

Source of the segments and their phases: the research note scanning-law-history.md
(GOST forecast fits), mirrored by mcsweep.scanning.segments.FLOWN_SEGMENTS.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mcsweep.errors import UserInputError
from mcsweep.scanning import ScanningLaw, find_transits
from mcsweep.scanning.attitude import attitude_for
from mcsweep.scanning.segments import FLOWN_SEGMENTS
from mcsweep.scanning.sun import nominal_sun_longitude
from mcsweep.scanning.timescale import tcb_jd

#: Table interpolation vs a direct solve_ivp of the segment's ODE [rad] (the table's
#: Hermite error is ~1e-11 rad; both integrations run at rtol 1e-12 over <= 5 years).
DIRECT_SOLVE_TOLERANCE_RAD = 1e-8
#: The same for Omega, which the direct solve integrates itself (its slow part, Omega -
#: omega_z (t - t_ref)); omega_z t is ~2e4 rad in a 2.4-year segment, so its rounding
#: (~4e-12 rad) is negligible; 1e-8 rad is 34 us of spin.
DIRECT_OMEGA_TOLERANCE_RAD = 1e-8
#: EPSL closed form (nu fixed, Omega linear in t) [rad]: only rounding remains.
CLOSED_FORM_TOLERANCE_RAD = 1e-9


@pytest.fixture(scope="module")
def law():
    return ScanningLaw()


@pytest.fixture(scope="module")
def att(law):
    return attitude_for(law)


def _direct(law, seg, t_end):
    """nu and Omega at t_end by solve_ivp of the segment's own ODE (no closed form, no table)."""
    xi = math.radians(law.solar_aspect_deg)
    sign = {"nsl": 1.0, "nsl_reversed": -1.0, "epsl": 0.0}[seg.kind]

    def rhs(t, y):
        _, lam_dot = nominal_sun_longitude(t)
        root = sign * math.sqrt(law.precession_S ** 2 - math.cos(y[0]) ** 2) if sign else 0.0
        nu_dot = lam_dot * (root + math.cos(xi) * math.sin(y[0])) / math.sin(xi) if sign else 0.0
        # dOmega/dt less its constant omega_z (added back below), so the integrated value stays
        # small and the solver's relative tolerance means the same as for nu.
        om_slow_dot = -math.cos(xi) * nu_dot - math.sin(xi) * math.sin(y[0]) * lam_dot
        return [nu_dot, om_slow_dot]

    y0 = [math.radians(seg.nu_ref_deg), math.radians(seg.omega_ref_deg)]
    sol = solve_ivp(rhs, (seg.ref_epoch_jd, t_end), y0, method="LSODA", rtol=1e-12, atol=1e-12)
    return sol.y[0, -1], sol.y[1, -1] + law.spin_rate_rad_day * (t_end - seg.ref_epoch_jd)


def _wrap(x):
    return (x + math.pi) % (2 * math.pi) - math.pi


@pytest.mark.parametrize("k", range(len(FLOWN_SEGMENTS)))
def test_each_segment_matches_a_direct_integration_of_its_equations(att, law, k):
    seg = FLOWN_SEGMENTS[k]
    # A few epochs inside the segment (start, a third, two thirds, just before the end).
    for frac in (0.0, 0.33, 0.67, 0.999):
        t = seg.start_jd + frac * (seg.end_jd - seg.start_jd)
        assert att.segment_index(t) == k
        nu_dir, om_dir = _direct(law, seg, t)
        _, _, nu, _, om, _ = att.heliotropic(np.array([t]))
        assert abs(_wrap(nu[0] - nu_dir)) < DIRECT_SOLVE_TOLERANCE_RAD
        assert abs(_wrap(om[0] - om_dir)) < DIRECT_OMEGA_TOLERANCE_RAD


def test_epsl_segment_is_its_closed_form(att, law):
    seg = FLOWN_SEGMENTS[0]
    assert seg.kind == "epsl"
    t = np.linspace(seg.start_jd, seg.end_jd - 1e-6, 50)
    _, _, nu, nu_dot, om, _ = att.heliotropic(t)
    np.testing.assert_allclose(nu, math.radians(180.0), atol=CLOSED_FORM_TOLERANCE_RAD)
    np.testing.assert_array_equal(nu_dot, 0.0)
    expected = math.radians(seg.omega_ref_deg) + law.spin_rate_rad_day * (t - seg.ref_epoch_jd)
    np.testing.assert_allclose(_wrap(om - expected), 0.0, atol=CLOSED_FORM_TOLERANCE_RAD)
    # nu = 180 deg: the spin axis lies in the ecliptic, so every scan passes the ecliptic poles.
    np.testing.assert_allclose(att.spin_axis(t)[:, 2], 0.0, atol=1e-12)


def test_epsl_to_nsl_is_continuous_at_2014_08_23(att):
    # Note: "Omega = 330.518 deg at 2014-08-23T00:00, i.e. continuous with the next segment";
    # the next one starts at nu = 180.006 deg: a 0.006 deg step of nu (0.004 deg of spin axis).
    b = tcb_jd("2014-08-23T00:00:00", "b")
    before, after = att.parts[0], att.parts[1]
    _, nu0, om0 = before.lam_nu_omega(np.array([b]))
    _, nu1, om1 = after.lam_nu_omega(np.array([b]))
    assert abs(_wrap(om1[0] - om0[0])) < 1e-12
    assert math.degrees(abs(nu1[0] - nu0[0])) == pytest.approx(0.006, abs=1e-9)
    z0, z1 = before.spin_axis(np.array([b])), after.spin_axis(np.array([b]))
    assert math.degrees(math.acos(min(1.0, float(np.sum(z0 * z1))))) < 0.005


def test_declared_discontinuity_at_2017_02_08(att):
    # Note: "nu(t) continuing the previous segment, spin phase re-set: Omega lower by 82.5 deg
    # than the previous segment's law gives (equivalently nu = 51.062 deg, Omega = 169.969 deg
    # at 2017-02-08T12:00)". We use the explicit phases; the previous segment's law gives
    # nu = 51.329 deg and Omega - 82.5 = 169.597 deg there, so the explicit phases differ from
    # "continuing" by -0.27 deg in nu and +0.37 deg in Omega (the note is not self-consistent
    # at that level). This test pins what we ship.
    t = np.array([tcb_jd("2017-02-08T12:00:00", "t")])
    _, nu_prev, om_prev = att.parts[2].lam_nu_omega(t)
    _, nu_new, om_new = att.parts[3].lam_nu_omega(t)
    step_om = math.degrees(_wrap(om_new[0] - om_prev[0]))
    step_nu = math.degrees(_wrap(nu_new[0] - nu_prev[0]))
    assert step_om == pytest.approx(-82.5, abs=0.5)
    assert abs(step_nu) < 0.3
    assert math.degrees(nu_new[0]) % 360 == pytest.approx(51.062, abs=1e-9)
    # And the 2017-01-27 - 02-08 gap has no attitude.
    gap = np.array([tcb_jd("2017-02-01T00:00:00", "g")])
    assert att.segment_index(gap)[0] == -1
    assert np.all(np.isnan(att.matrix(gap)))


def test_sign_of_the_precession_rate_per_segment(att):
    for k, seg in enumerate(FLOWN_SEGMENTS):
        t = np.linspace(seg.start_jd, seg.end_jd, 200, endpoint=False)
        _, _, _, nu_dot, _, _ = att.heliotropic(t)
        if seg.kind == "nsl_reversed":
            assert np.all(nu_dot < 0), k
        elif seg.kind == "nsl":
            assert np.all(nu_dot > 0), k
        else:
            assert np.all(nu_dot == 0), k


@pytest.fixture(scope="module")
def directions():
    rng = np.random.default_rng(28)
    n = 400
    return rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))


def _keys(df):
    return list(zip(df["source_index"], df["fov"].astype(str), np.round(df["tcb_jd"].to_numpy() * 86400).astype(int)))


@pytest.mark.parametrize("boundary", ["2014-08-23T00:00:00", "2014-09-25T11:30:00", "2019-07-05T00:00:00",
                                      "2020-08-01T00:00:00"])
def test_transits_at_a_boundary_are_found_once(law, directions, boundary):
    ra, dec = directions
    b = tcb_jd(boundary, "b")
    whole = find_transits(ra, dec, b - 3.0, b + 3.0, law=law)
    left = find_transits(ra, dec, b - 3.0, b, law=law)
    right = find_transits(ra, dec, b, b + 3.0, law=law)
    assert len(whole) == len(left) + len(right) > 0
    assert sorted(_keys(whole)) == sorted(_keys(left) + _keys(right))
    assert len(set(_keys(whole))) == len(whole)
    # Each side is its own segment's law alone: the same transits as a one-segment law.
    k = int(attitude_for(law).segment_index(b))
    seg = FLOWN_SEGMENTS[k]
    alone = ScanningLaw(name="alone", segments=(), ref_epoch_tcb=seg.ref_epoch_tcb,
                        nu_ref_deg=seg.nu_ref_deg, omega_ref_deg=seg.omega_ref_deg) \
        if seg.kind == "nsl" else None
    if alone is not None:
        ref = find_transits(ra, dec, b, b + 3.0, law=alone)
        np.testing.assert_array_equal(ref["tcb_jd"].to_numpy(), right["tcb_jd"].to_numpy())


def test_no_transits_in_the_2017_gap_and_none_lost_around_it(law, directions):
    ra, dec = directions
    gap = find_transits(ra, dec, "2017-01-27T00:00:00", "2017-02-08T00:00:00", law=law)
    assert len(gap) == 0
    whole = find_transits(ra, dec, "2017-01-20T00:00:00", "2017-02-15T00:00:00", law=law)
    parts = [find_transits(ra, dec, "2017-01-20T00:00:00", "2017-01-27T00:00:00", law=law),
             find_transits(ra, dec, "2017-02-08T00:00:00", "2017-02-15T00:00:00", law=law)]
    assert sorted(_keys(whole)) == sorted(_keys(parts[0]) + _keys(parts[1]))
    t = whole["tcb_jd"].to_numpy()
    assert not np.any((t >= tcb_jd("2017-01-27T00:00:00", "a")) & (t < tcb_jd("2017-02-08T00:00:00", "b")))


def test_extrapolation_is_said(law):
    inside = law.extrapolation_note(tcb_jd("2015-01-01T00:00:00", "a"), tcb_jd("2020-01-01T00:00:00", "b"))
    assert inside is None
    outside = law.extrapolation_note(tcb_jd("2014-07-01T00:00:00", "a"), tcb_jd("2015-01-01T00:00:00", "b"))
    assert "extrapolated" in outside and "2014-07-25T10:30" in outside
    assert "extrapolated" in ScanningLaw.preset("nominal").extrapolation_note(2457023.5, 2457100.5)


def test_overlapping_segments_are_refused():
    segs = [s.as_dict() for s in FLOWN_SEGMENTS[:2]]
    segs[1]["start_tcb"] = "2014-08-01T00:00:00"
    with pytest.raises(UserInputError, match=r"segments\[1\].start_tcb"):
        ScanningLaw(segments=segs)
    with pytest.raises(UserInputError, match="kind"):
        ScanningLaw(segments=[dict(FLOWN_SEGMENTS[0].as_dict(), kind="spiral")])


#: The research note scanning-law-history.md, its table: (kind, start, end, epoch of the
#: phases, nu, Omega) per segment, as the note gives them (the reversed-precession year as
#: refitted to Gaia's observation forecasts on 2026-11-28).
NOTE_SEGMENTS = (
    ("epsl", "2014-07-25T10:30:00", "2014-08-23T00:00:00", "2014-08-23T00:00:00", 180.0, 330.518),
    ("nsl", "2014-08-23T00:00:00", "2014-09-25T11:30:00", "2014-08-23T00:00:00", 180.006, 330.518),
    ("nsl", "2014-09-25T11:30:00", "2017-01-27T00:00:00", "2015-01-01T00:00:00", 323.3708, 95.1324),
    ("nsl", "2017-02-08T00:00:00", "2019-07-05T00:00:00", "2017-02-08T12:00:00", 51.062, 169.969),
    ("nsl_reversed", "2019-07-05T00:00:00", "2020-08-01T00:00:00", "2019-07-05T00:00:00", 314.6231, 170.3941),
    ("nsl", "2020-08-01T00:00:00", "2025-01-15T00:00:00", "2020-08-01T00:00:00", 244.289, 32.975),
)


@pytest.mark.parametrize("k", range(len(NOTE_SEGMENTS)))
def test_the_shipped_segments_are_the_notes(k):
    # Both copies of the law (the module's constant and conf/scanning/flown.yaml, which every
    # run reads) against the note's table. A phase of the reversed year 0.57 deg off put a
    # third of its transits in the other field of view while every geometric check of the
    # law's own (45 deg from the Sun, the sense of precession, the transits at the segment's
    # bounds, the two fields of view's shares) still held: the law is a valid scanning law
    # for any phases, so only the fitted values themselves can say which one Gaia flew.
    kind, start, end, epoch, nu, omega = NOTE_SEGMENTS[k]
    for seg in (FLOWN_SEGMENTS[k], ScanningLaw.preset("flown").segment_list[k]):
        assert (seg.kind, seg.start_tcb, seg.end_tcb, seg.ref_epoch_tcb) == (kind, start, end, epoch)
        assert (seg.nu_ref_deg, seg.omega_ref_deg) == (nu, omega)
    assert len(FLOWN_SEGMENTS) == len(ScanningLaw.preset("flown").segment_list) == len(NOTE_SEGMENTS)


#: The phases of the reversed year before the refit (nu = 315.314 deg, Omega = 169.887 deg).
REVERSED_BEFORE_REFIT = (315.314, 169.887)
#: Share of the earlier fit's transits with no transit of the refitted law within 30 min over
#: 2019-08-01 - 2020-07-15: the check against Gaia's forecasts found 36.7 % of the forecast
#: transits without one of the earlier fit's within 30 min (research note); the two
#: measure the same displacement from either side, so they agree to the sampling error of
#: a few percent (24 forecast directions there, 300 random ones here).
DISPLACED_SHARE, DISPLACED_TOLERANCE = 0.367, 0.06


def test_the_refit_moves_a_third_of_the_reversed_years_transits(directions):
    # The refit does what the note says the forecasts asked for: about a third of the
    # transits of 2019-08 - 2020-07 move to the other field of view (106.5 or 253.6 min
    # away) or the next spin (360 min); elsewhere the law is untouched.
    ra, dec = directions[0][:300], directions[1][:300]
    k = [s.kind for s in FLOWN_SEGMENTS].index("nsl_reversed")
    segs = [s.as_dict() for s in FLOWN_SEGMENTS]
    segs[k].update(nu_ref_deg=REVERSED_BEFORE_REFIT[0], omega_ref_deg=REVERSED_BEFORE_REFIT[1])
    before_law = ScanningLaw(segments=segs)
    span = ("2019-08-01T00:00:00", "2020-07-15T00:00:00")
    now, before = (find_transits(ra, dec, *span, law=law) for law in (ScanningLaw(), before_law))
    t_now = np.sort(now["source_index"].to_numpy() * 1e4 + now["tcb_jd"].to_numpy())
    t_before = before["source_index"].to_numpy() * 1e4 + before["tcb_jd"].to_numpy()
    i = np.clip(np.searchsorted(t_now, t_before), 1, len(t_now) - 1)
    gap_min = np.minimum(np.abs(t_now[i] - t_before), np.abs(t_now[i - 1] - t_before)) * 1440.0
    assert abs(np.mean(gap_min > 30.0) - DISPLACED_SHARE) < DISPLACED_TOLERANCE
    # the same displacements the forecasts showed: the other FoV (106.5, 253.5 min) or a spin
    far = gap_min[gap_min > 30.0]
    lag = 1440.0 * ScanningLaw().fov_lag_days
    spin = 1440.0 * ScanningLaw().spin_period_days
    near_alias = np.min(np.abs(far[:, None] - np.array([lag, spin - lag, spin])[None, :]), axis=1) < 30.0
    assert np.mean(near_alias) > 0.9
    # the year before the segment is the same law, transit for transit
    pre = [find_transits(ra, dec, "2019-06-01T00:00:00", "2019-07-05T00:00:00", law=law) for law in (ScanningLaw(), before_law)]
    np.testing.assert_array_equal(pre[0]["tcb_jd"].to_numpy(), pre[1]["tcb_jd"].to_numpy())
