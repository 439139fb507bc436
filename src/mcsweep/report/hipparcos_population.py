"""The galaxy model's bright stars against Hipparcos 2 per |b| band (issue 25, items 2-3).

For G = 6-7 and 7-8 (Hipparcos is complete there: V < 7.3-9, ESA 1997, Vol. 1) and the
real-sky validation's |b| bands (0-15, 15-35, 35-90 deg): the number of stars, the 90th
percentile parallax and the median total proper motion, model over Hipparcos. The model's
values come from ``n_draw`` stars drawn from its density (seeded), its counts from its
expectation; Hipparcos' from the catalogue (G derived as in :mod:`mcsweep.population.hipparcos`;
its parallax errors, 0.5-1 mas, are left in).

Usage::

    python -m mcsweep.report.hipparcos_population [--extinction-model arenou1992]
        [--giant-thickness-factor 0.6] [--thin-disc-factor 1.18] [--out FILE.csv]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import UserInputError
from ..population import GalaxyModel
from ..population import hipparcos

__all__ = ["BANDS_DEG", "G_BINS", "compare", "main"]

#: |b| bands of the real-sky validation, deg.
BANDS_DEG = ((0.0, 15.0), (15.0, 35.0), (35.0, 90.0))
#: G bins compared.
G_BINS = ((6.0, 7.0), (7.0, 8.0))
SEED = 20150821


def _stats(b, plx, pmra, pmdec):
    out = []
    for lo, hi in BANDS_DEG:
        sel = (np.abs(b) >= lo) & ((np.abs(b) < hi) | (hi == 90.0))
        out.append((sel.sum(), np.percentile(plx[sel], 90), np.median(np.hypot(pmra[sel], pmdec[sel]))))
    return out


def compare(model, *, n_draw=200_000, seed=SEED):
    """One row per (G bin, |b| band): counts, p90 parallax [mas], median proper motion
    [mas/yr], model and Hipparcos, and their ratios."""
    hip = hipparcos.load_hipparcos()
    rng = np.random.default_rng(seed)
    rows = []
    for g0, g1 in G_BINS:
        h = hip[(hip.phot_g_mean_mag >= g0) & (hip.phot_g_mean_mag < g1)]
        hs = _stats(h.b.to_numpy(), h.parallax.to_numpy(), h.pmra.to_numpy(), h.pmdec.to_numpy())
        total = model.expected_count(0.0, 90.0, 180.0, g0, g1)
        s = model.sample_cone(0.0, 90.0, 180.0, g0, g1, rng, min_draw=n_draw)
        ms = _stats(s.b.to_numpy(), s.parallax.to_numpy(), s.pmra.to_numpy(), s.pmdec.to_numpy())
        for (lo, hi), (hn, hp, hm), (mn, mp, mm) in zip(BANDS_DEG, hs, ms):
            n_model = total * mn / len(s)
            rows.append(dict(g_min=g0, g_max=g1, b_lo=lo, b_hi=hi, n_hip=hn, n_model=n_model,
                             count_ratio=n_model / hn, plx90_hip=hp, plx90_model=mp, plx90_ratio=mp / hp,
                             pm50_hip=hm, pm50_model=mm, pm50_ratio=mm / hm))
    return pd.DataFrame(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m mcsweep.report.hipparcos_population",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--extinction-model", default=None, help="galaxy model extinction_model")
    ap.add_argument("--giant-thickness-factor", type=float, default=None,
                    help="galaxy model giant_thickness_factor")
    ap.add_argument("--thin-disc-factor", type=float, default=None,
                    help="galaxy model thin_disc_scale_height_factor")
    ap.add_argument("--n-draw", type=int, default=200_000)
    ap.add_argument("--out", default=None, help="CSV file to write")
    args = ap.parse_args(argv)
    try:
        # a bad --out ends in one line before the computation, not in a traceback after it
        if args.out and not os.access(Path(args.out).resolve().parent, os.W_OK):
            raise UserInputError(f"--out={args.out!r} is not accepted; expected a file in an existing, "
                                 "writable folder")
        given = {"extinction_model": args.extinction_model,
                 "giant_thickness_factor": args.giant_thickness_factor,
                 "thin_disc_scale_height_factor": args.thin_disc_factor}
        params = {k: v for k, v in given.items() if v is not None}
        if args.n_draw < 1:
            raise UserInputError(f"--n-draw={args.n_draw} is not accepted; expected a positive integer")
        df = compare(GalaxyModel(params), n_draw=args.n_draw)
    except UserInputError as exc:
        print(f"hipparcos_population: {exc}", file=sys.stderr)
        return 2
    if args.out:
        df.to_csv(args.out, index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(df.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
