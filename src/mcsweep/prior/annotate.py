"""Add the prior to a star catalogue: ``sigma_f90_parallax`` [mas] and ``sigma_f90_pm`` [mas/yr].

Input columns use Gaia archive names (matched case-insensitively): ``ra, dec`` (ICRS)
or ``l, b`` (galactic), in degrees, and ``phot_g_mean_mag``. Every other column is kept
with its unit.

For a prior with a colour axis (:attr:`~mcsweep.prior.Prior.has_colour`) the star's BP-RP comes from a
``bp_rp`` column or, without one, from ``phot_bp_mean_mag - phot_rp_mean_mag``; empty or
NaN values (and a catalogue without these columns) get the colour-blind prior of the
same run. The column ``prior_colour_bin`` says which prior each row got: the bin as
``'lo..hi'`` (mag) or ``'colour_blind'``. For a mean-centred prior (:attr:`~mcsweep.prior.Prior.has_mean`)
the prior's centre is added too: ``prior_mean_parallax_mas``, ``prior_mean_pmra_mas_yr`` and
``prior_mean_pmdec_mas_yr`` (ICRS, pmra = mu_alpha* as in the Gaia archive), the names
``mcsweep-prior solve`` gives them; ``old_mean_columns`` writes them under their former names
``prior_mean_parallax``, ``prior_mean_pmra`` and ``prior_mean_pmdec`` (deprecated). For the
paper's prior and a plain run's the output is the two sigma columns only.

Formats: FITS, VOTable, ECSV, CSV and Parquet (by suffix). Parquet to
Parquet and CSV to CSV are streamed in batches (pyarrow / pandas), so memory stays flat
whatever the number of rows; the other formats are read whole with astropy.

The functions here write to the path they are given; the ``mcsweep-prior`` command
gives them a temporary name and moves the file into place only when it is complete.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import UserInputError
from ..tables import FORMATS, detect_format
from ..tables.formats import ASTROPY_FORMAT
from ..tables.read import arrow_batches, astropy_table, csv_batches
from .columns import PRIOR_MEAN_COLUMNS, finite_column, unit_scale
from ..galactic import galactic_from_icrs
from ..renamed_names import old_names
from .model import Prior

__all__ = ["FORMATS", "PARALLAX_COLUMN", "PM_COLUMN", "COLOUR_BIN_COLUMN", "PRIOR_MEAN_COLUMNS",
           "OLD_PRIOR_MEAN_COLUMNS", "detect_format", "output_columns", "annotate_file"]

PARALLAX_COLUMN = "sigma_f90_parallax"
PM_COLUMN = "sigma_f90_pm"
#: Which prior a row got (a prior with a colour axis): the BP-RP bin 'lo..hi' or 'colour_blind'.
COLOUR_BIN_COLUMN = "prior_colour_bin"
#: The former names of the prior's centre (:data:`mcsweep.prior.columns.PRIOR_MEAN_COLUMNS`), written with ``old_mean_columns`` (deprecated).
OLD_PRIOR_MEAN_COLUMNS = ("prior_mean_parallax", "prior_mean_pmra", "prior_mean_pmdec")
#: Units of the added columns (None: a string column).
_UNITS = {PARALLAX_COLUMN: "mas", PM_COLUMN: "mas / yr", COLOUR_BIN_COLUMN: None}
for _names in (PRIOR_MEAN_COLUMNS, OLD_PRIOR_MEAN_COLUMNS):
    _UNITS.update(zip(_names, ("mas", "mas / yr", "mas / yr")))
#: Rows per batch when streaming (about 25 MB of float64 columns at 12 columns).
BATCH_ROWS = 262_144


def _find(names, wanted: str):
    low = {str(n).lower(): n for n in names}
    return low.get(wanted)


def output_columns(prior: Prior, *, old_mean_columns: bool = False) -> list[str]:
    """Names of the columns ``annotate`` adds for this prior, in order (``old_mean_columns``:
    the prior's centre under its former, deprecated names)."""
    means = OLD_PRIOR_MEAN_COLUMNS if old_mean_columns else PRIOR_MEAN_COLUMNS
    return [PARALLAX_COLUMN, PM_COLUMN] + ([COLOUR_BIN_COLUMN] if prior.has_colour else []) \
        + (list(means) if prior.has_mean else [])


def _renamed(old_mean_columns: bool) -> dict[str, str]:
    """Current -> written name of the added columns."""
    return dict(zip(PRIOR_MEAN_COLUMNS, OLD_PRIOR_MEAN_COLUMNS)) if old_mean_columns else {}


def _colour_columns(names) -> tuple[str, ...]:
    """``('bp_rp',)``, ``(bp, rp)`` magnitude columns, or () when the catalogue has no colour."""
    c = _find(names, "bp_rp")
    if c is not None:
        return (c,)
    bp, rp = _find(names, "phot_bp_mean_mag"), _find(names, "phot_rp_mean_mag")
    return (bp, rp) if bp is not None and rp is not None else ()


def _columns(names, source: str, added=(PARALLAX_COLUMN, PM_COLUMN)) -> tuple[str, tuple[str, str], str]:
    """('icrs' or 'galactic', (lon, lat) column names, G column name)."""
    g = _find(names, "phot_g_mean_mag")
    ra, dec, l_, b_ = (_find(names, k) for k in ("ra", "dec", "l", "b"))
    if ra is not None and dec is not None:
        kind, pos = "icrs", (ra, dec)
    elif l_ is not None and b_ is not None:
        kind, pos = "galactic", (l_, b_)
    else:
        kind, pos = None, None
    if pos is None or g is None:
        raise UserInputError(f"{source}: columns {list(names)[:12]} lack {'ra, dec (or l, b)' if pos is None else ''}"
                             f"{' and ' if pos is None and g is None else ''}{'phot_g_mean_mag' if g is None else ''}; "
                             "expected Gaia archive names ra, dec or l, b [deg] and phot_g_mean_mag")
    for existing in added:
        if _find(names, existing) is not None:
            raise UserInputError(f"{source}: already has a column {existing!r}; expected a catalogue without "
                                 f"{', '.join(added)}")
    return kind, pos, g


def _values(col, name: str, source: str, unit, angle: bool) -> np.ndarray:
    """Float values of a column in degrees (angle) or magnitudes, checked finite."""
    factor = unit_scale(unit, "angle" if angle else "mag", f"{source}: column {name}")
    v = finite_column(col, name, source, where=" of its batch")
    return v * factor if factor != 1.0 else v


def _colour(get, cols, source, units) -> np.ndarray | None:
    """BP-RP per row from ``cols`` (:func:`_colour_columns`); NaN where empty; None without columns."""
    if not cols:
        return None
    vals = []
    for c in cols:
        factor = unit_scale(units.get(c), "mag", f"{source}: column {c}")
        try:
            v = np.asarray(get(c), dtype=float)
        except (TypeError, ValueError):
            raise UserInputError(f"{source}: column {c} has non-numeric values; expected magnitudes "
                                 "(empty or NaN where unknown)") from None
        vals.append(v * factor if factor != 1.0 else v)
    return vals[0] if len(vals) == 1 else vals[0] - vals[1]


def _all_columns(prior: Prior, kind: str, lon, lat, g, bp_rp) -> dict[str, np.ndarray]:
    """Every added column (:func:`output_columns`) for arrays of stars."""
    l_deg, b_deg = galactic_from_icrs(lon, lat) if kind == "icrs" else (lon, lat)
    sig = prior.sigma_parallax_mas(l_deg, b_deg, g, bp_rp)
    out = {PARALLAX_COLUMN: sig, PM_COLUMN: prior.ratio_R * sig}
    if prior.has_colour:
        out[COLOUR_BIN_COLUMN] = prior.colour_bin_label(np.full(sig.shape, np.nan) if bp_rp is None else bp_rp)
    if prior.has_mean:
        out[PRIOR_MEAN_COLUMNS[0]] = prior.mean_parallax_mas(l_deg, b_deg, g, bp_rp)
        out[PRIOR_MEAN_COLUMNS[1]], out[PRIOR_MEAN_COLUMNS[2]] = prior.mean_pm_masyr(l_deg, b_deg, g, bp_rp)
    return out


def _prior_of_table(prior, kind, pos, gcol, get, units, source, colour_cols=(), rename=None):
    lon = _values(get(pos[0]), pos[0], source, units.get(pos[0]), True)
    lat = _values(get(pos[1]), pos[1], source, units.get(pos[1]), True)
    g = _values(get(gcol), gcol, source, units.get(gcol), False)
    if np.any(np.abs(lat) > 90.0):
        raise UserInputError(f"{source}: column {pos[1]} has values beyond +-90 deg; expected latitudes in degrees")
    bp_rp = _colour(get, colour_cols, source, units) if prior.has_colour else None
    return {(rename or {}).get(k, k): v for k, v in _all_columns(prior, kind, lon, lat, g, bp_rp).items()}


def annotate_file(src: Path, dst: Path, prior: Prior, *, out_format: str | None = None,
                  batch_rows: int = BATCH_ROWS, old_mean_columns: bool = False) -> int:
    """Write ``src`` with the prior's columns (module notes) added to ``dst``.

    Parameters
    ----------
    src : path-like
        The catalogue: FITS, VOTable, ECSV, CSV or Parquet with Gaia archive column names.
    dst : path-like
        The output file (it may be a temporary name without a suffix).
    prior : Prior
        The prior to add.
    out_format : str, optional, keyword-only
        Format of ``dst``; default from its suffix.
    batch_rows : int, keyword-only
        Rows per batch when Parquet or CSV is streamed.
    old_mean_columns : bool, keyword-only
        The prior's centre under its former names (``OLD_PRIOR_MEAN_COLUMNS``; deprecated).

    Returns
    -------
    int
        The number of rows written.

    Raises
    ------
    mcsweep.errors.UserInputError
        For unreadable files, missing columns, wrong units and non-finite values.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import pandas as pd
    >>> from mcsweep.prior import Prior
    >>> from mcsweep.prior.annotate import annotate_file
    >>> tmp = Path(tempfile.mkdtemp())
    >>> stars = pd.DataFrame({'ra': [10.68], 'dec': [41.27],
    ...                       'phot_g_mean_mag': [15.0]})
    >>> stars.to_csv(tmp / 'stars.csv', index=False)
    >>> annotate_file(tmp / 'stars.csv', tmp / 'out.csv', Prior.paper())
    1
    >>> list(pd.read_csv(tmp / 'out.csv').columns)
    ['ra', 'dec', 'phot_g_mean_mag', 'sigma_f90_parallax', 'sigma_f90_pm']
    """
    src, dst = Path(src), Path(dst)
    fmt_in = detect_format(src)
    fmt_out = out_format or detect_format(dst)
    if not src.is_file():
        raise UserInputError(f"catalogue {src} does not exist; expected a readable file")
    source = src.name
    rename = _renamed(old_mean_columns)
    if fmt_in == fmt_out == "parquet":
        return _parquet_stream(src, dst, prior, source, batch_rows, rename)
    if fmt_in == fmt_out == "csv":
        return _csv_stream(src, dst, prior, source, batch_rows, rename)
    return _astropy_whole(src, dst, prior, source, fmt_in, fmt_out, rename)


def _parquet_stream(src, dst, prior, source, batch_rows, rename) -> int:
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema_in, batches = arrow_batches(src, batch_rows, what="catalogue")
    names = schema_in.names
    added = output_columns(prior, old_mean_columns=bool(rename))
    kind, pos, gcol = _columns(names, source, added)
    colour_cols = _colour_columns(names)
    # Units a writer may have stored as field metadata (astropy, our own files) are honoured.
    units = {}
    for f in schema_in:
        meta = f.metadata or {}
        if b"unit" in meta:
            units[f.name] = meta[b"unit"].decode()
    schema = schema_in
    for name in added:
        unit = _UNITS[name]
        schema = schema.append(pa.field(name, pa.float64(), metadata={"unit": unit}) if unit
                               else pa.field(name, pa.string()))
    n = 0
    with pq.ParquetWriter(dst, schema) as writer:
        for batch in batches:
            cols = _prior_of_table(prior, kind, pos, gcol, lambda c: batch.column(c).to_numpy(zero_copy_only=False),
                                   units, source, colour_cols, rename)
            out = pa.RecordBatch.from_arrays([*batch.columns, *(pa.array(cols[c]) for c in added)], schema=schema)
            writer.write_batch(out)
            n += batch.num_rows
    return n


def _csv_stream(src, dst, prior, source, batch_rows, rename) -> int:
    n = 0
    added = output_columns(prior, old_mean_columns=bool(rename))
    with open(dst, "w", newline="") as f:
        for i, chunk in enumerate(csv_batches(src, batch_rows, what="catalogue")):
            frame = chunk.frame()
            kind, pos, gcol = _columns(frame.columns, source, added)
            cols = _prior_of_table(prior, kind, pos, gcol, lambda c: frame[c].to_numpy(), {}, source,
                                   _colour_columns(frame.columns), rename)
            for name in added:
                frame[name] = cols[name]
            frame.to_csv(f, index=False, header=(i == 0))
            n += len(frame)
    return n


def _astropy_whole(src, dst, prior, source, fmt_in, fmt_out, rename) -> int:
    from astropy import units as u

    t = astropy_table(src, fmt_in, what="catalogue")
    added = output_columns(prior, old_mean_columns=bool(rename))
    kind, pos, gcol = _columns(t.colnames, source, added)

    def get(c):
        col = t[c]
        return col.filled(np.nan) if hasattr(col, "filled") and col.dtype.kind in "fiu" else col

    cols = _prior_of_table(prior, kind, pos, gcol, get, {c: t[c].unit for c in t.colnames}, source,
                           _colour_columns(t.colnames), rename)
    for name in added:
        t[name] = cols[name] * u.Unit(_UNITS[name]) if _UNITS[name] else cols[name]
    t[PARALLAX_COLUMN].description = f"parallax prior sigma_F90 (Michalik et al. 2015 Eqs. 14-17; {prior.origin})"
    t[PM_COLUMN].description = f"proper-motion prior R sigma_F90, R = {prior.ratio_R:g}/yr (Eq. 18)"
    if prior.has_colour:
        t[COLOUR_BIN_COLUMN].description = "BP-RP bin of the prior used (mag), or colour_blind"
    if prior.has_mean:
        par, pmra, pmdec = (rename.get(c, c) for c in PRIOR_MEAN_COLUMNS)
        t[par].description = "centre of the parallax prior (galaxy model's cell mean)"
        t[pmra].description = "centre of the pmra* prior (ICRS, galaxy model's cell mean)"
        t[pmdec].description = "centre of the pmdec prior (ICRS, galaxy model's cell mean)"
    # dst is the command's own temporary file (created empty by mkstemp), so overwrite it.
    # astropy's Parquet writer keeps the units in the file's table metadata by itself.
    t.write(dst, format=ASTROPY_FORMAT[fmt_out], overwrite=True)
    return len(t)


#: ``MEAN_COLUMNS`` was renamed PRIOR_MEAN_COLUMNS (three modules had a MEAN_COLUMNS of different columns).
__getattr__ = old_names(__name__, {"MEAN_COLUMNS": "PRIOR_MEAN_COLUMNS"})
