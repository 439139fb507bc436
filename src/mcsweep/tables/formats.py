"""Which table format a file is, from its name: the one list of formats and suffixes.

Every table a user gives mcsweep (a catalogue, observations, Gaia epoch astrometry, a
catalogue to annotate) and every table it writes for them is one of these five formats.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import UserInputError

__all__ = ["FORMATS", "ASTROPY_FORMAT", "detect_format"]

#: Accepted formats and the file suffixes that select them (case-insensitive). A ``.gz``
#: suffix is decompressed on reading (CSV and ECSV by their readers, FITS by astropy).
FORMATS = {
    "fits": (".fits", ".fit", ".fits.gz", ".fit.gz", ".fz"),
    "votable": (".vot", ".votable", ".xml", ".vot.gz", ".xml.gz"),
    "ecsv": (".ecsv", ".ecsv.gz"),
    "csv": (".csv", ".csv.gz", ".tsv", ".tsv.gz", ".txt", ".txt.gz"),
    "parquet": (".parquet", ".pq"),
}
#: astropy's name of each format. Always given explicitly: astropy's guessing reads an
#: ECSV file with variable-length array columns (the Gaia archive's epoch astrometry) as
#: one column and fails, while format='ascii.ecsv' reads it.
ASTROPY_FORMAT = {"fits": "fits", "votable": "votable", "ecsv": "ascii.ecsv", "csv": "ascii.csv",
                  "parquet": "parquet"}


def detect_format(path, fmt: str = "auto", *, what: str = "") -> str:
    """The format of ``path``: ``fmt`` itself if not 'auto', else from the file's suffix.

    ``what`` names the file's role in messages ('catalogue', '--sources', ...).
    Raises :class:`~mcsweep.errors.UserInputError` naming the file and the accepted suffixes or formats.
    """
    name = Path(path).name
    label = f"{what} {name}".strip()
    if fmt != "auto":
        if fmt not in FORMATS:
            raise UserInputError(f"{label}: format={fmt!r} is not accepted; expected 'auto' or one of "
                                 f"{sorted(FORMATS)}")
        return fmt
    low = name.lower()
    for f, suffixes in FORMATS.items():
        if low.endswith(suffixes):
            return f
    accepted = sorted(s for v in FORMATS.values() for s in v)
    raise UserInputError(f"{label}: cannot tell the format from the suffix; expected one of {accepted}")
