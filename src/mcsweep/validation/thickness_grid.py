"""The thin-disc and giants' thickness factors against published facts, on a grid.

Calibrates ``thin_disc_scale_height_factor`` and ``giant_thickness_factor``
(docs/galaxy_model.md) for a given extinction model, from the
model's expected counts (no sampling): per (giants' factor, thin-disc factor) the all-sky
counts per 1-mag G bin over Tycho-2/UCAC4 (``G4`` ...) and over Gaia DR3 (``gaia_G4`` ...;
the reference from G = 10 on, where the compilation is too bright) from
:func:`.published_counts.count_comparison`,
the paper's Table 1 beam (458 GUMS stars), N(G < 20) and N(G < 21), and the vertical
profiles the factors imply, to set against the published scale heights:

* ``giant_zhalf_pc``: height above the plane where the thin-disc giants' density (all age
  bins, weighted by the model's own giants per bin) falls to half its mid-plane value, at
  the Sun's radius. Bovy (2017, MNRAS 470, 1360, abstract [V]): sech^2 profiles with scale
  heights ~150 pc for giants; sech^2(z / h) halves at 0.881 h = 132 pc, sech^2(z / 2h) at
  264 pc (the abstract does not say which form).
* ``thin_hexp_pc``: e-folding height of the thin-disc dwarfs with M_G 8-12 (the M dwarfs
  Juric et al. 2008 traced), from a straight-line fit of ln(density) at |z| = 0.3-1.0 kpc;
  ``thin_zhalf_pc`` their half-density height. Juric et al. (2008, ApJ 673, 864, abstract
  [V]): thin-disc scale height 300 pc (bias-corrected for a 35 % binary fraction).

Usage::

    python -m mcsweep.validation.thickness_grid --extinction-model arenou1992 \\
        --giant 0.45,0.6,0.8,1.0 --thin 1.0,1.15,1.3,1.45 [--[no-]subgiants] [--out FILE.csv]
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import UserInputError
from ..population import GalaxyModel
from ..population.galaxy.density import component_shape
from . import published_counts as pc

__all__ = ["BEAM", "A_STAR_MG", "vertical_heights_pc", "a_star_half_height_pc", "grid", "main"]

#: The paper's Table 1 beam: (l, b, radius) deg and its G range.
BEAM = dict(l_deg=245.7, b_deg=46.5, radius_deg=1.0, g_min=14.5, g_max=15.5)
#: Dwarfs whose profile is compared with Juric et al. (2008): M_G range [mag].
DWARF_MG = (8.0, 12.0)
#: Heights of the straight-line fit to ln(density) of the dwarfs, kpc.
EXP_FIT_KPC = (0.3, 1.0)
#: A dwarfs: M_G range [mag], the class edges half-way between B9V and A0V and between A7V
#: and F0V on Mamajek's sequence (M_V 0.745 and 2.40, G - V 0.02 and -0.045), as in
#: :func:`.published_counts.local_density_by_class`. Bovy (2017, MNRAS 470, 1360, abstract
#: [V]): sech^2 profiles with scale heights of ~50 pc for A stars, i.e. half density at
#: 44 pc (sech^2(z / h)) or 88 pc (sech^2(z / 2h)).
A_STAR_MG = (0.76, 2.36)


def _thin_profile(model, part, z_kpc, mg=None):
    lf = model.lf
    r0 = float(model.params["r0_kpc"])
    eps_factor = float(model.params["thin_disc_scale_height_factor"])
    total = np.zeros_like(z_kpc)
    for k, comp in enumerate(model.components):
        if comp.label != "thin_disc" or comp.lf_part != part:
            continue
        w = lf.cdf[k, -1] if mg is None else (np.interp(mg[1], lf.mg, lf.cdf[k])
                                              - np.interp(mg[0], lf.mg, lf.cdf[k]))
        total += w * component_shape(comp, np.full_like(z_kpc, -r0), np.zeros_like(z_kpc), z_kpc,
                                     r0_kpc=r0, z_sun_pc=model.params["z_sun_pc"],
                                     eps_factor=eps_factor)
    return total / total[0]


def vertical_heights_pc(model):
    """(giants' half-density height, dwarfs' e-folding height, dwarfs' half-density
    height) of the model's thin disc at the Sun's radius, pc (module notes)."""
    z = np.linspace(0.0, 2.0, 2001)
    giants = _thin_profile(model, "giants", z)
    dwarfs = _thin_profile(model, "dwarfs", z, mg=DWARF_MG)
    sel = (z >= EXP_FIT_KPC[0]) & (z <= EXP_FIT_KPC[1])
    h_exp = -1.0 / np.polyfit(z[sel], np.log(dwarfs[sel]), 1)[0]
    return (1e3 * float(np.interp(-0.5, -giants, z)), 1e3 * float(h_exp),
            1e3 * float(np.interp(-0.5, -dwarfs, z)))


def a_star_half_height_pc(model):
    """Height above the plane (pc) where the density of the model's thin-disc A dwarfs
    (:data:`A_STAR_MG`, all age bins weighted by their A dwarfs) falls to half its value in
    the plane, at the Sun's radius."""
    z = np.linspace(0.0, 1.0, 2001)
    return 1e3 * float(np.interp(-0.5, -_thin_profile(model, "dwarfs", z, mg=A_STAR_MG), z))


def grid(giant_factors, thin_factors, *, extinction_model="arenou1992", subgiants=None, g_bins=range(4, 14)):
    """One row per (giants' factor, thin-disc factor): count ratios per G bin (``G4`` ...
    over Tycho-2/UCAC4, ``gaia_G4`` ... over Gaia DR3), ``beam``, ``N20``, ``N21`` and the
    heights of :func:`vertical_heights_pc`; ``subgiants`` None: the model's default."""
    rows = []
    extra = {} if subgiants is None else {"subgiants": bool(subgiants)}
    for fg, ft in itertools.product(giant_factors, thin_factors):
        m = GalaxyModel(extinction_model=extinction_model, giant_thickness_factor=fg,
                        thin_disc_scale_height_factor=ft, **extra)
        row = dict(giant_factor=fg, thin_factor=ft, subgiants=m.params["subgiants"])
        comp = pc.count_comparison(m, g_bins)
        row.update({f"G{r.G_min}": r.ratio for r in comp.itertuples()})
        row.update({f"gaia_G{r.G_min}": r.ratio_gaia for r in comp.itertuples()})
        row["beam"] = m.expected_count(**BEAM)
        row["N20"] = m.expected_count(0.0, 90.0, 180.0, -5.0, 20.0)
        row["N21"] = m.expected_count(0.0, 90.0, 180.0, -5.0, 21.0)
        row["giant_zhalf_pc"], row["thin_hexp_pc"], row["thin_zhalf_pc"] = vertical_heights_pc(m)
        row["a_star_zhalf_pc"] = a_star_half_height_pc(m)
        rows.append(row)
    return pd.DataFrame(rows)


def _floats(text, name):
    try:
        out = [float(x) for x in text.split(",")]
    except ValueError:
        raise UserInputError(f"--{name}={text!r} is not accepted; expected comma-separated numbers") from None
    if not out or any(not np.isfinite(x) or x <= 0 for x in out):
        raise UserInputError(f"--{name}={text!r} is not accepted; expected positive numbers")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m mcsweep.validation.thickness_grid",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--extinction-model", default="arenou1992")
    ap.add_argument("--giant", default="0.45,0.6,0.8,1.0", help="giants' thickness factors")
    ap.add_argument("--thin", default="1.0,1.15,1.3,1.45", help="thin-disc thickness factors")
    ap.add_argument("--subgiants", action=argparse.BooleanOptionalAction, default=None,
                    help="galaxy model subgiants (default: the model's)")
    ap.add_argument("--out", default=None, help="CSV file to write")
    args = ap.parse_args(argv)
    try:
        # a bad --out ends in one line before the computation, not in a traceback after it
        if args.out and not os.access(Path(args.out).resolve().parent, os.W_OK):
            raise UserInputError(f"--out={args.out!r} is not accepted; expected a file in an existing, "
                                 "writable folder")
        df = grid(_floats(args.giant, "giant"), _floats(args.thin, "thin"),
                  extinction_model=args.extinction_model, subgiants=args.subgiants)
    except UserInputError as exc:
        print(f"thickness_grid: {exc}", file=sys.stderr)
        return 2
    if args.out:
        df.to_csv(args.out, index=False)
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(df.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
