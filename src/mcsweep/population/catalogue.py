"""Stars from a table file (FITS, VOTable, ECSV, CSV or Parquet) as a population source.

Typical inputs are an extract of the ESA Gaia archive's GUMS table
(``gaia_universe_model``: ``ra, dec, barycentric_distance`` [pc], ``pmra, pmdec``,
``mag_g``) or of ``gaia_source`` (``ra, dec, l, b, parallax, pmra, pmdec,
phot_g_mean_mag``). Column names are matched case-insensitively against the aliases in
:data:`ALIASES`, or set explicitly with ``columns={ours: theirs}``. Units stored in the
file (FITS, VOTable, ECSV) are converted; plain CSV/Parquet columns are taken in our
units unless ``units={ours: unit}`` says otherwise.

The whole table is checked when the source is created, so a bad catalogue fails with one
:class:`~mcsweep.errors.UserInputError` line (naming the file, the column and what was
expected) before any result is written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from astropy import units as u

from ..errors import UserInputError
from ..tables import FORMATS, detect_format
from . import sky
from .query import COLUMNS, ConeQuery

__all__ = ["CatalogueSource", "ALIASES", "UNITS", "FORMATS"]

#: Column names recognised for each of our columns (first match wins, case-insensitive).
ALIASES = {
    "ra": ("ra", "ra_icrs", "raj2000"),
    "dec": ("dec", "de_icrs", "dej2000", "decl"),
    "l": ("l", "glon"),
    "b": ("b", "glat"),
    "parallax": ("parallax", "plx"),
    "pmra": ("pmra", "pm_ra_cosdec", "pmra_cosdec"),
    "pmdec": ("pmdec", "pmde", "pm_dec"),
    "phot_g_mean_mag": ("phot_g_mean_mag", "mag_g", "gmag", "g_mag"),
    "distance_pc": ("distance_pc", "barycentric_distance", "distance", "dist"),
    "population": ("population", "pop"),
}
#: Our unit of each numeric column and how it is described in messages.
UNITS = {
    "ra": (u.deg, "deg"), "dec": (u.deg, "deg"), "l": (u.deg, "deg"), "b": (u.deg, "deg"),
    "parallax": (u.mas, "mas"), "pmra": (u.mas / u.yr, "mas/yr"),
    "pmdec": (u.mas / u.yr, "mas/yr"), "phot_g_mean_mag": (u.mag, "mag"),
    "distance_pc": (u.pc, "pc"),
}
def _read(path, fmt):
    """Read the file with the one table reader: dict name -> (values, astropy unit or None)."""
    from ..tables import read_table

    try:
        t = read_table(path, fmt=fmt, what="catalogue")
    except UserInputError as exc:
        if not path.is_file():
            raise UserInputError(f"catalogue {path.name}: file not found at {path}") from None
        raise exc
    return {str(n): (np.asarray(t[n]), u.Unit(t.unit(n), parse_strict="silent") if t.unit(n) else None) for n in t.names
            if getattr(t[n], "ndim", 2) == 1}


class CatalogueSource:
    """Population source backed by a star table.

    Parameters
    ----------
    path : str or path-like
        The table file.
    format : str
        'auto' (from the suffix), 'fits', 'votable', 'ecsv', 'csv' or 'parquet'.
    columns : mapping, optional
        Our column name -> the file's column name, overriding :data:`ALIASES`.
    units : mapping, optional
        Our column name -> unit string of that column in the file (overrides the file's).
    on_missing : {'error', 'drop'}
        What to do with rows whose needed values are NaN: raise, or drop them (the number
        dropped is in ``n_dropped``).

    Raises
    ------
    mcsweep.errors.UserInputError
        If the file cannot be read or a needed column is missing, non-numeric, NaN,
        in the wrong unit or out of range.
    """

    def __init__(self, path, format="auto", columns=None, units=None, on_missing="error"):
        self.path = Path(path)
        if on_missing not in ("error", "drop"):
            raise UserInputError(f"catalogue {self.path.name}: on_missing={on_missing!r} is not "
                                 "accepted; expected 'error' or 'drop'")
        self.format = detect_format(self.path, format, what="catalogue")
        if not self.path.is_file():
            raise UserInputError(f"catalogue {self.path.name}: file not found at {self.path}")
        raw = _read(self.path, self.format)
        self.n_dropped = 0
        self.table = self._standardise(raw, dict(columns or {}), dict(units or {}), on_missing)

    def __repr__(self):
        return f"CatalogueSource({str(self.path)!r}, {len(self.table)} stars)"

    # ----------------------------------------------------------------- checks
    def _err(self, msg):
        return UserInputError(f"catalogue {self.path.name}: {msg}")

    def _find(self, raw, ours, mapping):
        lower = {k.lower(): k for k in raw}
        if ours in mapping:
            theirs = mapping[ours]
            if theirs not in raw and str(theirs).lower() not in lower:
                raise self._err(f"column {theirs!r} (mapped to {ours!r}) is missing; "
                                f"expected one of the file's columns {sorted(raw)[:12]}")
            return lower.get(str(theirs).lower(), theirs)
        for alias in ALIASES[ours]:
            if alias in lower:
                return lower[alias]
        return None

    def _numeric(self, raw, name, ours, units):
        values, unit = raw[name]
        target, desc = UNITS[ours]
        if ours in units:
            try:
                unit = u.Unit(units[ours])
            except ValueError:
                raise self._err(f"units.{ours}={units[ours]!r} is not a unit; expected e.g. "
                                f"{desc!r}") from None
        if values.dtype.kind not in "fiu":
            conv = pd.to_numeric(pd.Series(values), errors="coerce").to_numpy(float)
            bad = np.isnan(conv) & ~pd.isna(pd.Series(values)).to_numpy()
            if bad.any():
                first = values[np.argmax(bad)]
                raise self._err(f"column {name!r} has {int(bad.sum())} non-numeric values "
                                f"(first: {first!r}); expected numbers in {desc}")
            values = conv
        values = np.asarray(values, float)
        if unit is not None and unit != u.dimensionless_unscaled:
            try:
                values = (values * u.Unit(unit)).to_value(target)
            except (u.UnitsError, ValueError, TypeError):
                raise self._err(f"column {name!r} has unit {str(unit)!r}; expected "
                                f"{desc}") from None
        return values

    def _standardise(self, raw, mapping, units, on_missing):
        unknown = sorted(set(mapping) - set(ALIASES)) + sorted(set(units) - set(UNITS))
        if unknown:
            raise self._err(f"columns/units key(s) {unknown} are not accepted; expected some of "
                            f"{sorted(ALIASES)}")
        found = {ours: self._find(raw, ours, mapping) for ours in ALIASES}
        need = [("phot_g_mean_mag", "G magnitude (phot_g_mean_mag or mag_g) in mag"),
                ("pmra", "proper motion in RA*cos(dec) (pmra) in mas/yr"),
                ("pmdec", "proper motion in Dec (pmdec) in mas/yr")]
        for ours, what in need:
            if found[ours] is None:
                raise self._err(f"no column for {ours!r}; expected {what} "
                                f"(or map one with population.columns.{ours}=NAME)")
        if not ((found["ra"] and found["dec"]) or (found["l"] and found["b"])):
            raise self._err("no column for 'ra'/'dec' (or 'l'/'b'); expected positions in deg "
                            "(or map them with population.columns.ra=NAME ...)")
        if not (found["parallax"] or found["distance_pc"]):
            raise self._err("no column for 'parallax' (or 'distance_pc'/'barycentric_distance');"
                            " expected parallaxes in mas or distances in pc")
        cols = {ours: self._numeric(raw, name, ours, units)
                for ours, name in found.items() if name is not None and ours != "population"}
        needed = [c for c in cols if c != "distance_pc" or "parallax" not in cols]
        nan_rows = np.zeros(len(next(iter(cols.values()))), dtype=bool)
        for c in needed:
            bad = ~np.isfinite(cols[c])
            if bad.any() and on_missing == "error":
                raise self._err(f"column {found[c]!r} has {int(bad.sum())} NaN values; expected "
                                f"finite numbers in {UNITS[c][1]} (or population.on_missing=drop)")
            nan_rows |= bad
        keep = ~nan_rows
        self.n_dropped = int(nan_rows.sum())
        cols = {k: v[keep] for k, v in cols.items()}
        pop_raw = raw[found["population"]][0][keep] if found["population"] else None
        self._check_ranges(cols, found)
        return self._complete(cols, pop_raw)

    def _check_ranges(self, cols, found):
        checks = [("ra", 0.0, 360.0, "0..360 deg"), ("dec", -90.0, 90.0, "-90..90 deg"),
                  ("l", -360.0, 360.0, "0..360 deg"), ("b", -90.0, 90.0, "-90..90 deg"),
                  ("phot_g_mean_mag", -2.0, 30.0, "G magnitudes within -2..30 mag")]
        for c, lo, hi, what in checks:
            if c in cols and cols[c].size and ((cols[c] < lo) | (cols[c] > hi)).any():
                n = int(((cols[c] < lo) | (cols[c] > hi)).sum())
                raise self._err(f"column {found[c]!r} has {n} values outside {what}; expected {what}"
                                " (check the unit)")
        if "distance_pc" in cols and "parallax" not in cols and (cols["distance_pc"] <= 0).any():
            n = int((cols["distance_pc"] <= 0).sum())
            raise self._err(f"column {found['distance_pc']!r} has {n} values <= 0; expected "
                            "positive distances in pc")

    @staticmethod
    def _complete(cols, pop_raw):
        n = len(next(iter(cols.values())))
        if "ra" not in cols or "l" not in cols:
            # Only for a catalogue missing one frame: astropy.coordinates costs 0.15 s of every
            # process's start, the galaxy model's sweep workers included.
            from astropy.coordinates import ICRS, Galactic, SkyCoord
        if "ra" not in cols:
            c = SkyCoord(l=cols["l"] * u.deg, b=cols["b"] * u.deg, frame=Galactic()).icrs
            cols["ra"], cols["dec"] = c.ra.deg, c.dec.deg
        if "l" not in cols:
            c = SkyCoord(ra=cols["ra"] * u.deg, dec=cols["dec"] * u.deg, frame=ICRS()).galactic
            cols["l"], cols["b"] = c.l.deg, c.b.deg
        if "parallax" not in cols:
            cols["parallax"] = 1000.0 / cols["distance_pc"]
        if "distance_pc" not in cols:
            plx = cols["parallax"]
            cols["distance_pc"] = np.where(plx > 0, 1000.0 / np.where(plx > 0, plx, 1.0), np.nan)
        if pop_raw is None:
            pop = pd.Categorical(np.full(n, "catalogue"))
        else:
            pop = pd.Categorical(pd.Series(pop_raw).astype(str).str.strip().to_numpy())
        data = {c: np.asarray(cols[c], float) for c in COLUMNS[:-1]}
        data["l"] = data["l"] % 360.0
        data["population"] = pop
        return pd.DataFrame(data, columns=list(COLUMNS), copy=False)

    # ----------------------------------------------------------------- queries
    def _select(self, q):
        t = self.table
        g = t["phot_g_mean_mag"].to_numpy()
        sel = (g >= q.g_min) & (g < q.g_max)
        sel &= sky.in_cone(t["l"].to_numpy(), t["b"].to_numpy(), q.l_deg, q.b_deg, q.radius_deg)
        return np.flatnonzero(sel)

    def expected_count(self, l_deg, b_deg, radius_deg, g_min, g_max):
        """Number of catalogue stars in the cone and G range (a catalogue is one realisation)."""
        return float(self._select(ConeQuery.make(l_deg, b_deg, radius_deg, g_min, g_max)).size)

    def sample_cone(self, l_deg, b_deg, radius_deg, g_min, g_max, rng, max_stars=None):
        """Catalogue stars in a cone and G range (same contract as the galaxy model).

        Raises
        ------
        mcsweep.errors.UserInputError
            If the selection is empty.
        """
        q = ConeQuery.make(l_deg, b_deg, radius_deg, g_min, g_max, max_stars)
        idx = self._select(q)
        if idx.size == 0:
            where = ("the whole sky" if q.radius_deg >= sky.WHOLE_SKY_DEG else
                     f"{q.radius_deg:g} deg of (l, b) = ({q.l_deg:g}, {q.b_deg:g})")
            g = self.table["phot_g_mean_mag"]
            span = f"{g.min():.2f}..{g.max():.2f}" if len(g) else "none"
            raise self._err(f"no star within {where} with {q.g_min:g} <= phot_g_mean_mag < "
                            f"{q.g_max:g}; expected at least one (file: {len(g)} stars, G {span})")
        n_in = idx.size
        if q.max_stars is not None and n_in > q.max_stars:
            if not isinstance(rng, np.random.Generator):
                raise UserInputError(f"rng={rng!r} is not accepted; expected a "
                                     "numpy.random.Generator")
            idx = np.sort(rng.choice(idx, size=q.max_stars, replace=False))
        df = self.table.iloc[idx].reset_index(drop=True)
        df.attrs["n_in_cone"] = int(n_in)
        df.attrs["expected_count"] = float(n_in)
        return df

    def sample_sky(self, g_min, g_max, rng, max_stars=None):
        """Catalogue stars of the whole sky in a G range."""
        return self.sample_cone(0.0, 90.0, sky.WHOLE_SKY_DEG, g_min, g_max, rng, max_stars)
