"""The prior's centre: the galaxy model's mean parallax and proper motion per cell.

The paper centres its prior on zero (Sect. 3.1; Sect. 5: "since any other choice would
necessarily involve additional assumptions"). A sweep run with ``prior_model.mean``
centres it instead on the galaxy model's mean parallax and proper motion of each
direction x G (x colour) cell and measures the F90 width around that mean. The means
are in ``prior_means.csv``, one row per cell:

``l_deg, b_deg, g_min, g_max, bp_rp_min, bp_rp_max, mean_parallax_mas, mean_pml_masyr,
mean_pmb_masyr`` with the proper motion in galactic components (mu_l* = mu_l cos b, mu_b)
and ``bp_rp_min = bp_rp_max = NaN`` for the colour-blind cells.

``PriorMeans`` interpolates them to any star:

* direction: bilinear on the sweep's HEALPix grid (``astropy_healpix``'s
  ``bilinear_interpolation_weights`` with the sky config's nside, order and frame; the
  sweep's directions are the pixel centres, where the interpolation returns the cell's
  value) for ``sky.kind = healpix``; the nearest sweep direction for a list of directions;
* G: linear between the centres of the G bins, constant beyond the first and last centre;
* colour: the bin containing BP-RP (outer bins extended), NaN -> the colour-blind cells;
* the proper motion is interpolated in galactic components and rotated to ICRS at the
  star's position (``mcsweep.galactic.pm_icrs_from_galactic``).

A colour cell whose mean is NaN (no stars drawn in it) or that has no row takes the
colour-blind mean of the same direction x G (``PriorMeans.n_filled`` counts them); every
colour-blind cell must have a finite mean (a sweep draws stars in each), else the file is
refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import UserInputError
from ..renamed_names import old_names
from .columns import read_run_table
from .sky_grid import check_sky
from .run_record import MEANS_FILE
from ..galactic import icrs_from_galactic, unit_vector

__all__ = ["MEANS_FILE", "MEANS_TABLE_COLUMNS", "PriorMeans"]

#: Columns of ``prior_means.csv`` (module notes).
MEANS_TABLE_COLUMNS = ("l_deg", "b_deg", "g_min", "g_max", "bp_rp_min", "bp_rp_max", "mean_parallax_mas",
                "mean_pml_masyr", "mean_pmb_masyr")
#: A row's direction may differ from the grid's by rounding of the frame transformation
#: (~1e-12 deg); anything beyond 1 arcsec is not one of the sweep's directions.
_DIRECTION_TOL_DEG = 1.0 / 3600.0
_EDGE_ATOL = 1e-9


@dataclass(frozen=True, eq=False)
class PriorMeans:
    """Mean parallax and galactic proper motion per cell, and their interpolation (module notes).

    Attributes
    ----------
    values : ndarray, shape (1 + K, n_g, n_dir, 3)
        (parallax [mas], mu_l* [mas/yr], mu_b [mas/yr]); slot 0 the colour-blind cells,
        slot k + 1 colour bin k.
    g_centres : ndarray, shape (n_g,)
        Centres of the G bins, increasing.
    sky : dict
        ``{"kind": "healpix", "nside", "order", "frame"}`` or ``{"kind": "list",
        "directions_gal": (n_dir, 2) galactic l, b in degrees}``.
    n_filled : int
        Cells whose NaN mean was replaced (module notes).
    """

    values: np.ndarray
    g_centres: np.ndarray
    sky: dict
    n_filled: int = 0

    # -- reading ----------------------------------------------------------------------
    @classmethod
    def read(cls, path, sky_config: dict, colour_edges: Sequence[float] = ()) -> "PriorMeans":
        """The means of ``prior_means.csv`` on the grid of the run's ``config["sky"]``."""
        path = Path(path)
        table = read_run_table(path, MEANS_TABLE_COLUMNS, "with prior_model.mean true", numeric=MEANS_TABLE_COLUMNS)
        t = {c: table[c].to_numpy() for c in MEANS_TABLE_COLUMNS}
        sky = _grid(sky_config, path)
        n_dir = _n_directions(sky)
        direction = _direction_index(sky, t["l_deg"], t["b_deg"], path)
        # G bins: by their centres.
        g_c = 0.5 * (t["g_min"] + t["g_max"])
        if not np.all(np.isfinite(g_c)):
            raise UserInputError(f"{path}: g_min, g_max are not finite in every row; expected the G bins")
        centres, g_index = np.unique(np.round(g_c, 9), return_inverse=True)
        # Colour slot: 0 colour-blind, k + 1 the bin [edges[k], edges[k+1]).
        edges = np.asarray([float(e) for e in colour_edges])
        slot = np.zeros(len(table), dtype=int)
        blind = np.isnan(t["bp_rp_min"]) & np.isnan(t["bp_rp_max"])
        if (~blind).any():
            lo, hi = t["bp_rp_min"][~blind], t["bp_rp_max"][~blind]
            k = np.searchsorted(edges, lo + _EDGE_ATOL, side="right") - 1 if edges.size else np.full(lo.size, -1)
            ok = (k >= 0) & (k < edges.size - 1)
            kk = np.clip(k, 0, max(edges.size - 2, 0))
            ok &= edges.size > 1
            if edges.size > 1:
                ok &= (np.abs(edges[kk] - lo) <= _EDGE_ATOL) & (np.abs(edges[kk + 1] - hi) <= _EDGE_ATOL)
            if not ok.all():
                i = int(np.argmin(ok))
                raise UserInputError(f"{path}: colour bin {lo[i]:g}..{hi[i]:g} is not one of the run's "
                                     f"prior_model.colour_edges {edges.tolist()}; expected those bins or NaN")
            slot[~blind] = kk + 1
        n_slot = max(edges.size, 1)
        shape = (n_slot, centres.size, n_dir)
        flat = np.ravel_multi_index((slot, g_index, direction), shape)
        if np.unique(flat).size != flat.size:
            raise UserInputError(f"{path}: a cell (direction, G bin, colour bin) appears twice; "
                                 "expected one row per cell")
        values = np.full(shape + (3,), np.nan)
        values.reshape(-1, 3)[flat] = np.stack([t["mean_parallax_mas"], t["mean_pml_masyr"],
                                                t["mean_pmb_masyr"]], axis=-1)
        nan = np.isnan(values)
        if nan[0].any():  # a sweep draws stars in every colour-blind cell: a gap is a damaged file
            g_i, d_i = (int(v[0]) for v in np.nonzero(nan[0].any(axis=-1)))
            raise UserInputError(f"{path}: the colour-blind cell at G {centres[g_i]:g}, direction {d_i} of the "
                                 "run's sky has no finite mean; expected one per direction x G bin")
        n_filled = int(nan.any(axis=-1).sum())
        values[1:] = np.where(nan[1:], values[0][None], values[1:])
        values.setflags(write=False)
        return cls(values, centres, sky, n_filled)

    # -- interpolation ----------------------------------------------------------------
    def galactic(self, l_deg, b_deg, G, slot=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(mean parallax [mas], mu_l* [mas/yr], mu_b [mas/yr]) at galactic l, b [deg] and G.

        ``slot``: None (colour-blind) or integer array broadcast with the others, 0 for
        colour-blind and k + 1 for colour bin k (:meth:`ColourBins.index` + 1).
        """
        arrays = [np.asarray(l_deg, float), np.asarray(b_deg, float), np.asarray(G, float)]
        if slot is not None:
            arrays.append(np.asarray(slot))
        arrays = np.broadcast_arrays(*arrays)
        shape = arrays[0].shape
        l_, b_, g = (a.ravel() for a in arrays[:3])
        s = arrays[3].ravel() if slot is not None else np.zeros(l_.size, dtype=int)
        if np.any(np.isnan(g)):
            raise UserInputError("G magnitude NaN is not accepted; expected finite magnitudes")
        pix, w = self._direction_weights(l_, b_)          # (m, N)
        gi, gw = self._g_weights(g)                        # (2, N)
        out = np.zeros((l_.size, 3))
        for j in range(gi.shape[0]):                       # the two G nodes
            for d in range(pix.shape[0]):                  # the 4 (or 1) direction nodes
                out += (gw[j] * w[d])[:, None] * self.values[s, gi[j], pix[d]]
        out = out.reshape(shape + (3,))
        return out[..., 0], out[..., 1], out[..., 2]

    def _g_weights(self, g) -> tuple[np.ndarray, np.ndarray]:
        c = self.g_centres
        if c.size == 1:
            return np.zeros((1, g.size), dtype=int), np.ones((1, g.size))
        i0 = np.clip(np.searchsorted(c, g, side="right") - 1, 0, c.size - 2)
        t = np.clip((g - c[i0]) / (c[i0 + 1] - c[i0]), 0.0, 1.0)
        return np.stack([i0, i0 + 1]), np.stack([1.0 - t, t])

    def _direction_weights(self, l_deg, b_deg) -> tuple[np.ndarray, np.ndarray]:
        if self.sky["kind"] == "healpix":
            import astropy.units as u
            from astropy_healpix import bilinear_interpolation_weights

            lon, lat = (l_deg, b_deg) if self.sky["frame"] == "galactic" else icrs_from_galactic(l_deg, b_deg)
            return bilinear_interpolation_weights(lon * u.deg, lat * u.deg, nside=self.sky["nside"],
                                                  order=self.sky["order"])
        _, idx = _tree(self.sky).query(unit_vector(l_deg, b_deg))
        return np.asarray(idx)[None, :], np.ones((1, l_deg.size))


def _grid(sky_config, path) -> dict:
    sky = check_sky(dict(sky_config or {}), f"{path}: the run's sky")
    if sky["kind"] == "healpix":
        return sky
    d = np.asarray(sky["directions"], dtype=float).reshape(-1, 2)
    if sky["frame"] == "icrs":
        from ..galactic import galactic_from_icrs

        gl, gb = galactic_from_icrs(d[:, 0], d[:, 1])
        d = np.stack([gl, gb], axis=-1)
    return {"kind": "list", "directions_gal": d}


def _n_directions(sky) -> int:
    return 12 * sky["nside"] ** 2 if sky["kind"] == "healpix" else sky["directions_gal"].shape[0]


def _tree(sky):
    from scipy.spatial import cKDTree

    if "tree" not in sky:
        d = sky["directions_gal"]
        sky["tree"] = cKDTree(unit_vector(d[:, 0], d[:, 1]))
    return sky["tree"]


def _direction_index(sky, l_deg, b_deg, path) -> np.ndarray:
    """The grid direction of each row of the means table (its own direction, to rounding)."""
    if sky["kind"] == "healpix":
        import astropy.units as u
        from astropy_healpix import HEALPix

        lon, lat = (l_deg, b_deg) if sky["frame"] == "galactic" else icrs_from_galactic(l_deg, b_deg)
        hp = HEALPix(nside=sky["nside"], order=sky["order"])
        idx = hp.lonlat_to_healpix(lon * u.deg, lat * u.deg)
        c_lon, c_lat = hp.healpix_to_lonlat(idx)
        centre = unit_vector(c_lon.deg, c_lat.deg)
        dist = np.degrees(np.arccos(np.clip(np.sum(centre * unit_vector(lon, lat), axis=-1), -1.0, 1.0)))
    else:
        dist_chord, idx = _tree(sky).query(unit_vector(l_deg, b_deg))
        dist = np.degrees(2.0 * np.arcsin(np.clip(dist_chord / 2.0, 0.0, 1.0)))
    if np.any(dist > _DIRECTION_TOL_DEG):
        i = int(np.argmax(dist))
        raise UserInputError(f"{path}: direction (l, b) = ({l_deg[i]:g}, {b_deg[i]:g}) deg is not one of the run's "
                             "sky directions; expected the sweep's own directions (config['sky'])")
    return np.asarray(idx, dtype=int)


#: ``MEAN_COLUMNS`` was renamed MEANS_TABLE_COLUMNS (three modules had a MEAN_COLUMNS of different columns).
__getattr__ = old_names(__name__, {"MEAN_COLUMNS": "MEANS_TABLE_COLUMNS"})
