"""A small global problem from the real scanning law: a few thousand stars, a few weeks."""

from __future__ import annotations

import numpy as np
import pytest

from mcsweep.astrometry.noise import NoiseModel
from mcsweep.scanning import ScanningLaw, find_transits
from mcsweep.scanning.ephemeris import gaia_position_au
from mcsweep.scanning.timeline import draw_dead_time
from mcsweep.solver import AttitudeSpline, build_measurements

START_JD = 2456863.9375  # 2014-07-25 10:30 TCB, start of routine operations (Prusti et al. 2016)
# The solver's tests need a realistic NSL geometry, not the flown law's first weeks (now
# the Ecliptic Pole Scanning Law until 2014-08-23, whose pole-crossing scans change the
# conditioning these tolerances were set on): the flown law as it was before, one NSL
# segment with the 2014-09-25 - 2017-01-27 phases (conf/scanning/flown.yaml), extrapolated.
LAW = ScanningLaw(name="one_segment", segments=(), ref_epoch_tcb="2015-01-01T00:00:00",
                  nu_ref_deg=323.3708, omega_ref_deg=95.1324)


def make_problem(n_stars=20000, days=10.0, knot_days=0.5, seed=5, min_transits=4, use_ac=True, keep_fraction=1.0,
                 dead_fraction=0.0, dead_outage_days=0.25, transits_per_knot=None, knot_rule="counts"):
    """Random stars over the sky, their FoV transits, and the partials; truth drawn separately.

    ``keep_fraction < 1`` keeps that random fraction of the transits (dilution).
    ``dead_fraction > 0``: dead time in outages of ``dead_outage_days`` (the primary
    experiment's model), and the attitude spline broken at those gaps.
    ``transits_per_knot``: knots placed by the kept transits, that many per interval (or, with
    ``knot_rule='uniform'``, at their mean interval with that many as a floor), instead of
    ``knot_days``.
    """
    rng = np.random.default_rng(seed)
    ra = rng.uniform(0.0, 360.0, n_stars)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n_stars)))
    tr = find_transits(ra, dec, START_JD, START_JD + days, law=LAW)
    if keep_fraction < 1.0:
        tr = tr[rng.uniform(size=len(tr)) < keep_fraction].reset_index(drop=True)
    dead = None
    if dead_fraction > 0.0:
        dead = draw_dead_time(START_JD, START_JD + days, dead_fraction, outage_days=dead_outage_days, rng=rng)
        tr = tr[~dead.is_dead(tr["tcb_jd"].to_numpy())].reset_index(drop=True)
    src = tr["source_index"].to_numpy()
    count = np.bincount(src, minlength=n_stars)
    keep_star = count >= min_transits
    new_index = np.cumsum(keep_star) - 1
    sel = keep_star[src]
    tr = tr[sel]
    ra, dec = ra[keep_star], dec[keep_star]
    n = ra.size
    g = rng.uniform(12.0, 19.0, n)
    noise = NoiseModel(use_ac=use_ac)
    star = new_index[tr["source_index"].to_numpy()]
    t = tr["tcb_jd"].to_numpy()
    s_al = noise.sigma_al_mas(g)[star]
    s_ac = noise.sigma_ac_mas(g)[star] if use_ac else None
    if transits_per_knot is not None:
        live_days = days - (dead.total_days if dead is not None else 0.0)
        knot_days = live_days * transits_per_knot / len(tr)
    spline = AttitudeSpline(START_JD, START_JD + days, knot_days,
                            gaps=None if dead is None else (dead.starts, dead.stops),
                            epochs=tr["tcb_jd"].to_numpy(), transits_per_knot=transits_per_knot,
                            knot_rule=knot_rule)
    t_ref = START_JD + 0.5 * days
    obs = build_measurements(ra, dec, star, t, tr["scan_angle_deg"].to_numpy(), gaia_position_au(t),
                             t_ref_jd=t_ref, sigma_al_mas=s_al, sigma_ac_mas=s_ac, spline=spline)
    return {"ra": ra, "dec": dec, "g": g, "obs": obs, "spline": spline, "t_ref": t_ref, "rng": rng,
            "transits": tr, "star": star, "s_al": s_al, "s_ac": s_ac, "dead": dead, "days": days,
            "knot_days": knot_days}


@pytest.fixture(scope="session")
def small_problem():
    return make_problem()


@pytest.fixture(scope="session")
def weak_problem():
    """One year, a quarter of the transits kept: many stars with 1-4 transits, as Table 3's
    first subset, next to well-observed ones."""
    return make_problem(n_stars=2000, days=365.0, knot_days=4.0, seed=8, min_transits=1, keep_fraction=0.25)


@pytest.fixture(scope="session")
def gapped_problem():
    """One year with 20 % dead time in 2-day blocks (gaps longer than the knots) and ~12 FoV
    transits per knot interval: the attitude freedom of AGIS's 30 s knots at the paper's 1.5e6
    stars (~25 per knot), and less."""
    return make_problem(n_stars=800, days=365.0, seed=11, min_transits=1, keep_fraction=0.6, dead_fraction=0.2,
                        dead_outage_days=2.0,
                        transits_per_knot=12.0)


@pytest.fixture(scope="session")
def gapped_uniform_problem():
    """The gapped problem's stars and dead time with knots by the 'uniform' rule (AGIS's uniform
    knots at the mean interval of 12 transits, longer where fewer fall)."""
    return make_problem(n_stars=800, days=365.0, seed=11, min_transits=1, keep_fraction=0.6, dead_fraction=0.2,
                        dead_outage_days=2.0, transits_per_knot=12.0, knot_rule="uniform")


def _system(P):
    """``system(sigma_mas)``: problem ``P`` under a prior of ``sigma_mas`` (parallax; proper
    motion R = 10 /yr) and noisy measurements of a random truth and attitude (unit noise):
    ``(problem, h)``."""
    from mcsweep.astrometry.solve import prior_diagonal
    from mcsweep.solver import GlobalProblem

    def system(sigma_mas):
        obs, rng = P["obs"], np.random.default_rng(3)
        n = obs.n_stars
        x_true = np.column_stack([rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(0.2, 3.0, n),
                                  rng.normal(0, 5, n), rng.normal(0, 5, n)])
        problem = GlobalProblem(obs, prior_diagonal(sigma_mas, 10.0), P["ra"], P["dec"])
        a_true = rng.normal(0, 10.0, (obs.n_coef, 3))
        return problem, problem.forward(problem.join(x_true, a_true)) + rng.normal(size=obs.size)

    return system


@pytest.fixture(scope="session")
def gapped_system(gapped_problem):
    """:func:`_system` of the gapped problem (knots by equal counts)."""
    return _system(gapped_problem)


@pytest.fixture(scope="session")
def gapped_uniform_system(gapped_uniform_problem):
    """:func:`_system` of the gapped problem with uniform knots."""
    return _system(gapped_uniform_problem)

