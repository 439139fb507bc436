"""Gaia epoch astrometry (DR4): the archive's files read into per-CCD observations.

Gaia DR4 publishes, per source, one row per field-of-view (FoV) transit with per-CCD
arrays (SM, then AF1-AF9). Two column conventions exist: the archive's snake_case
(DataLink products in CSV, ECSV, FITS, VOTable and Parquet) and DPAC's camelCase (Parquet
files of the data processing). The columns used (facts of the files: Gaia Collaboration,
DR4 documentation of ``epoch_astrometry``; ESA's gaiasupdate, which reads the same files):

=================================  ==========  ===================================================
column (snake / camel)             per         meaning
=================================  ==========  ===================================================
source_id / sourceId               transit     Gaia source identifier (int64, kept exact)
obs_time_tcb / obsTimeTcb          CCD         time at Gaia, ns since 2010-01-01T00:00 TCB
obs_time_bary_corr / ...Corr       transit     barycentric correction of that time, ns
scan_pos_angle / scanPosAngle      CCD         scan position angle theta, deg
parallax_factor_al / ...FactorAl   transit     AL parallax factor P_AL (exact, with Gaia's orbit)
centroid_pos_al / centroidPosAl    CCD         AL local-plane coordinate w, mas, relative to the
                                               source's reference position with zero parallax
                                               and proper motion
centroid_pos_error_al / ...        CCD         its standard error, mas
used_by_agis_al / usedByAgisAl     CCD         whether AGIS used the CCD in AL
agis_source_excess_noise / ...     source      AGIS's excess source noise, mas
colour_factor_al / ...             CCD or      AL colour factor (six-parameter model only)
                                   transit
=================================  ==========  ===================================================

The archive's CSV writes the header ``used_by_agis_al`` twice, the second where
``used_by_agis_ac`` belongs: the second is read as ``used_by_agis_ac``. Per-CCD arrays may
arrive as 2-D columns, lists, tuples, variable-length arrays or text
(``mcsweep.tables.as_ragged``).

A CCD observation is kept, as AGIS keeps it, where ``used_by_agis_al`` is true and its
time, barycentric correction, scan angle, centroid and a positive error are all present.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserInputError
from ..tables import Ragged, TableChunk, as_ragged, integer_ids

__all__ = ["COLUMNS", "OPTIONAL_COLUMNS", "CcdObservations", "is_epoch_astrometry", "ccd_observations",
           "TCB_ORIGIN_JD", "fix_archive_header"]

#: Our name -> (archive snake_case, DPAC camelCase), the columns every model needs.
COLUMNS = {
    "source_id": ("source_id", "sourceId"),
    "obs_time_tcb": ("obs_time_tcb", "obsTimeTcb"),
    "obs_time_bary_corr": ("obs_time_bary_corr", "obsTimeBaryCorr"),
    "scan_pos_angle": ("scan_pos_angle", "scanPosAngle"),
    "parallax_factor_al": ("parallax_factor_al", "parallaxFactorAl"),
    "centroid_pos_al": ("centroid_pos_al", "centroidPosAl"),
    "centroid_pos_error_al": ("centroid_pos_error_al", "centroidPosErrorAl"),
    "used_by_agis_al": ("used_by_agis_al", "usedByAgisAl"),
    "agis_source_excess_noise": ("agis_source_excess_noise", "agisSourceExcessNoise"),
}
#: Read when present: the six-parameter model's colour factor.
OPTIONAL_COLUMNS = {"colour_factor_al": ("colour_factor_al", "colourFactorAl")}
#: The origin of ``obs_time_tcb``: 2010-01-01T00:00:00 TCB as a Julian date (TCB), the
#: TIMESYS origin of the DR4 epoch-astrometry files.
TCB_ORIGIN_JD = 2455197.5
_NS_PER_DAY = 86400e9
#: Days after the TCB origin that any Gaia observation falls between: launch (2013-12-19)
#: and the end of the extended mission's table (2031), with margin. An epoch outside means
#: the time column is not ns since 2010.0 TCB (days, another origin).
_MISSION_DAYS = (1300.0, 7700.0)
#: Units the files may state for the columns read (the archive writes 'ns', 'deg', 'mas').
_UNITS = {"obs_time_tcb": ("ns",), "obs_time_bary_corr": ("ns",), "scan_pos_angle": ("deg",),
          "centroid_pos_al": ("mas",), "centroid_pos_error_al": ("mas",), "agis_source_excess_noise": ("mas",)}


def _check_units(chunk: TableChunk, names: dict, source: str) -> None:
    """Refuse a column whose stated unit is not the convention's (a file without units passes)."""
    for ours, accepted in _UNITS.items():
        unit = chunk.unit(names.get(ours)) if names.get(ours) else None
        if unit and str(unit).replace(" ", "") not in accepted:
            raise UserInputError(f"{source}: column {names[ours]} is in {unit}; expected {accepted[0]} (the Gaia "
                                 "DR4 epoch-astrometry convention)")


@dataclass(frozen=True)
class CcdObservations:
    """The kept AL CCD observations of a batch of transits, grouped by source_id (increasing),
    in file order within a source (a transit's CCDs together).

    Arrays are per CCD observation (length m) unless named per transit.

    Parameters
    ----------
    source_id : int64 (m,)
        Gaia source identifier, exact.
    tcb_jd : float (m,)
        Barycentric time of the observation, ``obs_time_tcb + obs_time_bary_corr``, as a
        TCB Julian date: the time argument of the proper motion in AGIS's model.
    scan_angle_deg, parallax_factor_al, centroid_al_mas, sigma_al_mas : float (m,)
        Scan position angle theta [deg], AL parallax factor, AL centroid w relative to
        the reference position [mas] and its standard error [mas].
    excess_noise_mas : float (m,)
        The source's AGIS excess noise (the same on all its observations).
    colour_factor_al : float (m,) or None
        None when the file has no colour factor.
    transit : int64 (m,)
        Index of the observation's FoV transit (row of the file) within the batch.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import read_table
    >>> from mcsweep.astrometry.epoch_astrometry import ccd_observations
    >>> table = read_table(data / 'sample_epoch_astrometry.parquet')
    >>> obs = ccd_observations(table)
    >>> type(obs).__name__, int(obs.transit.max()) + 1  # FoV transits
    ('CcdObservations', 980)
    """

    source_id: np.ndarray
    tcb_jd: np.ndarray
    scan_angle_deg: np.ndarray
    parallax_factor_al: np.ndarray
    centroid_al_mas: np.ndarray
    sigma_al_mas: np.ndarray
    excess_noise_mas: np.ndarray
    colour_factor_al: np.ndarray | None
    transit: np.ndarray

    def __len__(self) -> int:
        return int(self.source_id.size)

    def take(self, idx) -> "CcdObservations":
        """The observations ``idx`` (indices or mask)."""
        return CcdObservations(**{k: (None if v is None else v[idx]) for k, v in self.__dict__.items()})


def _names(chunk: TableChunk) -> dict[str, str]:
    """Our name -> the file's column, for the columns the file has (either convention)."""
    found = {}
    for ours, (snake, camel) in {**COLUMNS, **OPTIONAL_COLUMNS}.items():
        name = chunk.find(snake, camel)
        if name is not None:
            found[ours] = name
    return found


def fix_archive_header(chunk: TableChunk) -> None:
    """The archive CSV's repeated ``used_by_agis_al`` header, in place.

    pandas reads the second as ``used_by_agis_al.1``, astropy as ``used_by_agis_al_1``. It
    stands where ``used_by_agis_ac`` belongs, so it is renamed ``used_by_agis_ac``; but in
    the archive's DR4 CSV seen so far its values repeat the AL flags row for row (the other
    five formats of the same source have different AC flags), so where they are identical
    the column is dropped: AC flags that are a copy of AL's are not AC flags. Only the AL
    flags enter the AL solution.
    """
    for dup in ("used_by_agis_al.1", "used_by_agis_al_1"):
        if dup not in chunk.columns or chunk.find("used_by_agis_ac") is not None:
            continue
        first = chunk.find("used_by_agis_al")
        copy = first is not None and np.array_equal(np.asarray(chunk[first]).astype(str),
                                                    np.asarray(chunk[dup]).astype(str))
        cols, units = {}, {}
        for k, v in chunk.columns.items():
            if k == dup and copy:
                continue
            key = "used_by_agis_ac" if k == dup else k
            cols[key], units[key] = v, chunk.units.get(k)
        chunk.columns, chunk.units = cols, units


def is_epoch_astrometry(chunk: TableChunk) -> bool:
    """Whether the table looks like epoch astrometry (has an AL centroid column in either convention)."""
    return chunk.find("centroid_pos_al", "centroidPosAl") is not None


def _per_transit(values, n: int, name: str, source: str) -> np.ndarray:
    v = np.asarray(values)
    if v.ndim != 1 or v.dtype.kind == "O":
        raise UserInputError(f"{source}: column {name} has an array per row; expected one value per FoV transit")
    return v.astype(float)


def _per_ccd(chunk: TableChunk, name: str, source: str, lengths=None) -> Ragged:
    """A per-CCD column aligned with the times' ``lengths``. A null array in a transit (stored
    as an empty array, or as one empty or NaN value in text) becomes NaN for each of that
    transit's CCDs, so the transit is not used; a transit without times has no CCDs."""
    r = as_ragged(chunk[name], name=name, source=source)
    if lengths is None or np.array_equal(r.lengths, lengths):
        return r
    first = r.values[np.minimum(r.starts, max(r.values.size - 1, 0))] if r.values.size else np.zeros(r.lengths.size)
    null = (r.lengths == 0) | ((r.lengths == 1) & _isnan(first))
    fits = (r.lengths == lengths) | (lengths == 0) | null
    if not fits.all():
        row = int(np.argmax(~fits))
        raise UserInputError(f"{source}: column {name} has {int(r.lengths[row])} elements in row "
                             f"{chunk.first_row + row}, where the times have {int(lengths[row])}; expected one "
                             "element per CCD in every per-CCD column")
    same = r.lengths == lengths
    aligned = Ragged(np.full(int(lengths.sum()), np.nan), np.asarray(lengths, dtype=np.int64))
    rows = np.flatnonzero(same & (lengths > 0))
    aligned.values[aligned.element_index(rows)] = np.asarray(r.values, dtype=float)[r.element_index(rows)]
    return aligned


def _isnan(values) -> np.ndarray:
    try:
        return np.isnan(np.asarray(values, dtype=float))
    except (TypeError, ValueError):
        return np.zeros(np.shape(values), dtype=bool)


def ccd_observations(chunk: TableChunk, *, need_colour: bool = False) -> CcdObservations:
    """The AL CCD observations AGIS used, from a batch of an epoch-astrometry table (module notes).

    Parameters
    ----------
    chunk : mcsweep.tables.TableChunk
        A batch of an epoch-astrometry file, one row per FoV transit
        (:func:`mcsweep.tables.iter_tables`), in either column convention.
    need_colour : bool, keyword-only
        Require the AL colour factor (the six-parameter model).

    Returns
    -------
    CcdObservations
        The CCD observations with ``used_by_agis_al`` set and finite values, grouped by
        source.

    Raises
    ------
    mcsweep.errors.UserInputError
        Naming the file and column, when a needed column is missing (in both
        conventions) or holds something else than described above.

    Examples
    --------
    >>> from importlib.resources import files
    >>> data = files('mcsweep') / 'data' / 'epoch_astrometry'
    >>> from mcsweep.tables import read_table
    >>> from mcsweep.astrometry.epoch_astrometry import ccd_observations
    >>> table = read_table(data / 'sample_epoch_astrometry.parquet')
    >>> obs = ccd_observations(table)
    >>> # CCD observations AGIS used, and sources
    >>> obs.source_id.size, len(set(obs.source_id))
    (7800, 10)
    """
    source = chunk.source
    fix_archive_header(chunk)
    names = _names(chunk)
    missing = [f"{COLUMNS[k][0]} (or {COLUMNS[k][1]})" for k in COLUMNS if k not in names]
    if missing:
        raise UserInputError(f"{source}: not Gaia epoch astrometry, lacks {', '.join(missing)}; expected the "
                             "columns of the archive's epoch_astrometry (snake_case) or DPAC's (camelCase)")
    if need_colour and "colour_factor_al" not in names:
        raise UserInputError(f"{source}: has no colour_factor_al (or colourFactorAl); expected it for the "
                             "six-parameter model (or use --model 5p)")
    n = len(chunk)
    _check_units(chunk, names, source)
    ids = integer_ids(chunk[names["source_id"]], names["source_id"], source)
    time = _per_ccd(chunk, names["obs_time_tcb"], source)
    lengths = time.lengths
    f64 = {k: np.asarray(_per_ccd(chunk, names[k], source, lengths).values, dtype=float)
           for k in ("scan_pos_angle", "centroid_pos_al", "centroid_pos_error_al")}
    used = _per_ccd(chunk, names["used_by_agis_al"], source, lengths).values
    t_ns = np.asarray(time.values, dtype=float)
    row = {k: _per_transit(chunk[names[k]], n, names[k], source)
           for k in ("obs_time_bary_corr", "parallax_factor_al", "agis_source_excess_noise")}
    transit = np.repeat(np.arange(n, dtype=np.int64), lengths)
    row_ok = np.isfinite(row["obs_time_bary_corr"]) & np.isfinite(row["parallax_factor_al"])
    keep = ((used == 1) & np.isfinite(t_ns) & np.isfinite(f64["scan_pos_angle"])
            & np.isfinite(f64["centroid_pos_al"]) & (f64["centroid_pos_error_al"] > 0) & row_ok[transit])
    colour = None
    if "colour_factor_al" in names:
        c = chunk[names["colour_factor_al"]]
        if isinstance(c, Ragged) or np.asarray(c).ndim == 2 or np.asarray(c).dtype.kind in "OUS":
            colour = np.asarray(_per_ccd(chunk, names["colour_factor_al"], source, lengths).values, dtype=float)
        else:
            # Some files hold one colour factor per transit: the same for its CCDs.
            colour = np.asarray(c, dtype=float)[transit]
        if need_colour:
            keep &= np.isfinite(colour)
    rows = transit[keep]
    # Barycentric time in days from the TCB origin; summed in ns first (both ~1e17 and 1e11 ns).
    days = (t_ns[keep] + row["obs_time_bary_corr"][rows]) / _NS_PER_DAY
    if days.size and not ((days.min() > _MISSION_DAYS[0]) and (days.max() < _MISSION_DAYS[1])):
        bad = days[(days <= _MISSION_DAYS[0]) | (days >= _MISSION_DAYS[1])][0]
        raise UserInputError(f"{source}: column {names['obs_time_tcb']} gives an epoch {bad:.1f} days after "
                             "2010-01-01 TCB, outside Gaia's mission; expected nanoseconds since "
                             "2010-01-01T00:00:00 TCB (the DR4 epoch-astrometry convention)")
    excess = row["agis_source_excess_noise"]
    excess = np.where(np.isfinite(excess), excess, 0.0)[rows]
    out = CcdObservations(
        source_id=ids[rows], tcb_jd=TCB_ORIGIN_JD + days, scan_angle_deg=f64["scan_pos_angle"][keep],
        parallax_factor_al=row["parallax_factor_al"][rows], centroid_al_mas=f64["centroid_pos_al"][keep],
        sigma_al_mas=f64["centroid_pos_error_al"][keep], excess_noise_mas=excess,
        colour_factor_al=None if colour is None else colour[keep], transit=rows)
    if ids.size and np.all(ids[1:] >= ids[:-1]):
        return out  # the archive's files: already grouped by source
    # int64 keys: numpy's stable sort is a radix sort, linear in the observations.
    return out.take(np.argsort(out.source_id, kind="stable"))
