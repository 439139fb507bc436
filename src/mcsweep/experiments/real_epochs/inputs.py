"""The experiment's inputs: a Gaia DR4 epoch-astrometry file and its sources table, checked.

The epoch file is read whole (:func:`mcsweep.tables.read_table`) into the AL CCD observations
AGIS used (:func:`mcsweep.astrometry.epoch_astrometry.ccd_observations`: either column
convention, any table format). The sources table is an extract of ``gaia_source`` with
``source_id``, ``ra``, ``dec`` [deg] and ``phot_g_mean_mag``: the direction and G at which
the prior's sigma_F90 is taken (Eqs. 14-17). Every source of the epoch file needs a row;
rows of other sources are not used. Both default to the vendored sample
(``mcsweep/data/epoch_astrometry``, PROVENANCE.md there), whose sources table holds
directions recovered from the parallax factors (:mod:`mcsweep.astrometry.direction`,
~0.1 deg) because the files carry no position.

Every problem is a :class:`~mcsweep.errors.UserInputError` of one line naming the setting and
the file, raised before the run writes anything.
"""

from __future__ import annotations

import hashlib
from contextlib import ExitStack
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ...astrometry.epoch_astrometry import CcdObservations, ccd_observations
from ...errors import UserInputError
from ...galactic import galactic_from_icrs
from ...prior.epoch_solve import read_sources
from ...tables import read_table

__all__ = ["SAMPLE_EPOCH_FILE", "SAMPLE_SOURCES_FILE", "SAMPLE_NOTE", "Sources", "Inputs", "read_inputs",
           "file_digest"]

_SAMPLE_DIR = ("data", "epoch_astrometry")
#: The vendored sample (PROVENANCE.md beside it): ESA gaiasupdate's test data, 10 sources.
SAMPLE_EPOCH_FILE = "sample_epoch_astrometry.parquet"
SAMPLE_SOURCES_FILE = "sample_sources.csv"
#: What the report says of the vendored sample's selection and directions.
SAMPLE_NOTE = ("the Gaia DR4-format epoch astrometry vendored from ESA's gaiasupdate (its test data, "
               "tests/test_data/heaviside_weighting; not a random sample of the sky); the files carry no "
               "position, so the directions at which sigma_F90 is taken were recovered from the parallax "
               "factors (mcsweep.astrometry.direction, ~0.1 deg) and G is AGIS's gMag")


@dataclass(frozen=True)
class Sources:
    """One row per source of the epoch file, sorted by ``source_id`` (int64, exact)."""

    source_id: np.ndarray
    ra_deg: np.ndarray
    dec_deg: np.ndarray
    l_deg: np.ndarray
    b_deg: np.ndarray
    g_mag: np.ndarray


@dataclass(frozen=True)
class Inputs:
    """The checked inputs of a run."""

    #: Kept AL CCD observations, sorted by (source_id, time).
    obs: CcdObservations
    #: The sources of ``obs``, in the order of their ids.
    sources: Sources
    #: The paths as the user gave them (file names of the sample for the vendored one).
    epoch_file: str
    sources_file: str
    #: True for the vendored sample.
    sample: bool
    #: SHA-256 of each file: a resumed run must read the same bytes.
    digests: dict


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes, read in 1 MiB pieces (flat memory)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _read_sources(path: Path, ids_needed: np.ndarray) -> Sources:
    """The rows of ``ids_needed`` (sorted, unique) of the sources table at ``path``, read and
    checked as ``mcsweep-prior solve`` reads it (:func:`mcsweep.prior.epoch_solve.read_sources`)."""
    table = read_sources(path).subset(ids_needed, "the epoch file")
    l_deg, b_deg = galactic_from_icrs(table.ra, table.dec)
    return Sources(ids_needed, table.ra, table.dec, l_deg, b_deg, table.phot_g_mean_mag)


def read_inputs(epoch_file: str | None, sources_file: str | None) -> Inputs:
    """The checked inputs (module notes); ``None`` for both: the vendored sample."""
    sample = epoch_file is None
    with ExitStack() as stack:
        if sample:
            folder = resources.files("mcsweep").joinpath(*_SAMPLE_DIR)
            epoch_path = stack.enter_context(resources.as_file(folder.joinpath(SAMPLE_EPOCH_FILE)))
            sources_path = stack.enter_context(resources.as_file(folder.joinpath(SAMPLE_SOURCES_FILE)))
            shown = (SAMPLE_EPOCH_FILE, SAMPLE_SOURCES_FILE)
        else:
            epoch_path, sources_path = Path(epoch_file).expanduser(), Path(sources_file).expanduser()
            shown = (str(epoch_file), str(sources_file))
        obs = ccd_observations(read_table(epoch_path, what="experiment.real_epochs.epoch_file"))
        if len(obs) == 0:
            raise UserInputError(f"experiment.real_epochs.epoch_file: {Path(epoch_path).name} has no usable AL CCD "
                                 "observation (used_by_agis_al true with time, barycentric correction, scan angle, "
                                 "centroid and a positive error); expected Gaia DR4 epoch astrometry")
        if np.any(obs.source_id < 0):
            raise UserInputError(f"experiment.real_epochs.epoch_file: {Path(epoch_path).name} has source_id "
                                 f"{int(obs.source_id[obs.source_id < 0][0])}; expected Gaia source identifiers "
                                 "(non-negative integers)")
        ids = np.unique(obs.source_id)
        sources = _read_sources(Path(sources_path), ids)
        digests = {"epoch_file": file_digest(Path(epoch_path)), "sources_file": file_digest(Path(sources_path))}
    return Inputs(obs=obs, sources=sources, epoch_file=shown[0], sources_file=shown[1], sample=sample,
                  digests=digests)
