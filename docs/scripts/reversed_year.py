"""The reversed-precession year of the flown law before and after its phases were refitted
(docs/scanning_law_reversed_year.md): transit counts over Gaia DR4's span against Prusti et
al. (2016, A&A 595, A1, Table 1) and the scan-angle distribution of the year against the
years around it. Run from a checkout: ``python docs/scripts/reversed_year.py``."""

import dataclasses

import astropy.units as u
import numpy as np
from astropy.coordinates import SkyCoord

from mcsweep.scanning import ScanningLaw, find_transits
from mcsweep.scanning.segments import DATA_RELEASE_SPANS, FLOWN_SEGMENTS
from mcsweep.scanning.timescale import tcb_jd

#: Prusti et al. 2016, Table 1: 5-year FoV transits per source per sin|beta| band, 6 % dead time.
PRUSTI_TABLE1_NOBS = np.array([61, 61, 62, 62, 63, 65, 66, 68, 71, 75, 80, 87, 98, 122, 144, 106, 93, 85, 80, 75])
BEFORE_REFIT = (315.314, 169.887)
YEARS = {"NSL 2018-07-05 - 2019-07-05": ("2018-07-05T00:00:00", "2019-07-05T00:00:00"),
         "reversed 2019-07-05 - 2020-07-05": ("2019-07-05T00:00:00", "2020-07-05T00:00:00"),
         "NSL 2020-08-01 - 2021-08-01": ("2020-08-01T00:00:00", "2021-08-01T00:00:00")}


def law_before_refit() -> ScanningLaw:
    segs = list(FLOWN_SEGMENTS)
    k = [s.kind for s in segs].index("nsl_reversed")
    segs[k] = dataclasses.replace(segs[k], nu_ref_deg=BEFORE_REFIT[0], omega_ref_deg=BEFORE_REFIT[1])
    return ScanningLaw(segments=tuple(s.as_dict() for s in segs))


def directions(n: int, seed: int = 20160916):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))


def dr4_counts(laws: dict, n: int = 20000) -> None:
    ra, dec = directions(n)
    sin_beta = np.abs(np.sin(SkyCoord(ra=ra * u.deg, dec=dec * u.deg).barycentrictrueecliptic.lat.rad))
    band = np.minimum((sin_beta / 0.05).astype(int), 19)
    start, end = DATA_RELEASE_SPANS["dr4"]
    years = (tcb_jd(end, "end") - tcb_jd(start, "start")) / 365.25
    print(f"DR4 {start} - {end} ({years:.3f} yr); Prusti Table 1 scaled: {81 * years / 5:.2f} (sky average)")
    counts = {}
    for name, law in laws.items():
        tr = find_transits(ra, dec, start, end, law=law, compact=True)
        c = counts[name] = np.bincount(tr["source_index"].to_numpy(), minlength=n)
        per_band = 0.94 * np.array([c[band == k].mean() for k in range(20)]) / (PRUSTI_TABLE1_NOBS * years / 5) - 1
        print(f"  {name}: {c.mean():.3f} +- {c.std() / np.sqrt(n):.3f} transits per source, x 0.94 = "
              f"{0.94 * c.mean():.2f}; per band / Prusti - 1: {per_band.min():+.3f} ... {per_band.max():+.3f}")
    d = counts["after"] - counts["before"]
    print(f"  changed for {np.mean(d != 0):.1%} of sources, sd {d.std():.2f}, 1/99 % "
          f"{np.percentile(d, 1):+.0f}/{np.percentile(d, 99):+.0f}, mean {d.mean():+.3f}")


def scan_angles(law: ScanningLaw, n: int = 4000) -> None:
    ra, dec = directions(n)
    for name, (a, b) in YEARS.items():
        df = find_transits(ra, dec, a, b, law=law).sort_values(["source_index", "tcb_jd"])
        psi, src = np.radians(df["scan_angle_deg"].to_numpy()), df["source_index"].to_numpy()
        m = np.bincount(src, minlength=n)
        ok = m >= 4
        R = np.hypot(np.bincount(src, np.cos(2 * psi), n), np.bincount(src, np.sin(2 * psi), n))[ok] / m[ok]
        p = (df["fov"].astype(str) == "P").to_numpy()
        t, sp, pp = df["tcb_jd"].to_numpy()[p], src[p], np.degrees(psi[p])
        turn = ((np.diff(pp) + 180) % 360 - 180)[(sp[1:] == sp[:-1]) & (np.diff(t) < 0.3)]
        print(f"  {name}: {m.mean():.2f} transits per source; resultant of 2 psi median {np.median(R):.3f} "
              f"(10/90 % {np.percentile(R, 10):.3f}/{np.percentile(R, 90):.3f}); turn per spin {turn.mean():+.4f} deg")


if __name__ == "__main__":
    laws = {"before": law_before_refit(), "after": ScanningLaw()}
    dr4_counts(laws)
    print("Scan angles, the refitted law:")
    scan_angles(laws["after"])
