"""What a sigma_F90 sweep's run directory holds, for whoever writes or reads its prior.

One owner for a sweep run's files: their names, the coefficient schema of Eqs. 15-17 and
the run's record parsed from ``provenance.json`` (:class:`SweepRecord`). The sweep writes
with these names (:mod:`mcsweep.experiments.f90_sweep`), and every reader goes through
here: :meth:`mcsweep.prior.Prior.from_run`, the report's colour section and the real-sky
experiment's colour priors. A reader given a directory that is not a finished sweep gets one
line saying what is missing.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from ..errors import UserInputError

__all__ = ["PROVENANCE_FILE", "COEFFICIENTS_FILE", "COLOUR_COEFFICIENTS_FILE", "COLOUR_TERMS_FILE", "MEANS_FILE",
           "POLY_DEGREES", "N_COEFFICIENTS", "SweepRecord", "read_record", "coefficients_from_terms",
           "read_coefficients"]

#: The run's record: resolved config, its hash, versions, timings (:mod:`mcsweep.command.provenance`).
PROVENANCE_FILE = "provenance.json"
#: The fitted coefficients of Eqs. 15-17, rows ``s0_c0`` ... ``s2_c1`` (``term``, ``fitted``, ...).
COEFFICIENTS_FILE = "coefficients.csv"
#: The same per BP-RP bin (a run with a colour axis, ``prior_model.colour_edges``).
COLOUR_COEFFICIENTS_FILE = "colour_coefficients.csv"
#: Eq. 14's terms per BP-RP bin and G bin (the colour prior's form where present).
COLOUR_TERMS_FILE = "colour_terms.csv"
#: The prior's centre per cell (a mean-centred prior, ``prior_model.mean``).
MEANS_FILE = "prior_means.csv"
#: Degree of the polynomial in G of each term of Eq. 14: s0 (Eq. 15), s1 (Eq. 16), s2 (Eq. 17).
POLY_DEGREES = {"s0": 2, "s1": 3, "s2": 1}
#: Number of coefficients of each term (degree + 1): the rows ``s0_c0`` ... of the coefficient files.
N_COEFFICIENTS = {name: degree + 1 for name, degree in POLY_DEGREES.items()}


@dataclass(frozen=True)
class SweepRecord:
    """A sweep run's record, parsed from its ``provenance.json``.

    Attributes
    ----------
    run_dir : Path
        The run directory.
    kind : str
        The experiment that made the run (``"f90_sweep"`` for a sweep).
    config : dict
        The resolved config the run was made with.
    """

    run_dir: Path
    kind: str
    config: dict

    @classmethod
    def from_provenance(cls, run_dir, prov: dict) -> "SweepRecord":
        """The record of an already read ``provenance.json`` (a dict)."""
        cfg = prov.get("config") if isinstance(prov, dict) else None
        return cls(Path(run_dir), str(prov.get("kind", "f90_sweep")), cfg if isinstance(cfg, dict) else {})

    @property
    def prior_model(self) -> dict:
        """``config["prior_model"]``; ``{}`` for a run made before the group existed (the
        paper's colour-blind, zero-centred prior)."""
        model = self.config.get("prior_model")
        return dict(model) if isinstance(model, dict) else {}

    @property
    def prior_model_name(self) -> str:
        return str(self.prior_model.get("name") or "direction_g")

    @property
    def colour_edges(self) -> list:
        """BP-RP bin edges of the colour axis (empty: none)."""
        return list(self.prior_model.get("colour_edges") or [])

    @property
    def mean(self) -> bool:
        """Whether the prior is centred on the galaxy model's mean per cell."""
        return bool(self.prior_model.get("mean", False))

    @property
    def g_edges(self) -> list:
        """The magnitude bins' edges (``config["magnitudes"]["edges"]``; empty if none)."""
        return list((self.config.get("magnitudes") or {}).get("edges") or [])

    @property
    def confidence(self) -> float | None:
        value = self.config.get("confidence")
        return None if value is None else float(value)

    @property
    def ratio_R(self) -> float | None:
        value = self.config.get("ratio_R")
        return None if value is None else float(value)

    @property
    def sky(self):
        """``config["sky"]`` (the sweep's directions)."""
        return self.config.get("sky")

    @property
    def f90_case(self) -> str:
        return str((self.config.get("observations") or {}).get("f90_case", "two"))


def read_record(run_dir, needed_for: str = "expected the directory of a finished mcsweep sigma_F90 sweep"
                ) -> SweepRecord:
    """The :class:`SweepRecord` of ``run_dir``'s ``provenance.json``.

    Raises
    ------
    mcsweep.errors.UserInputError
        In one line naming the directory and ``needed_for``, when the file is missing, not
        JSON or not a sweep's.
    """
    path = Path(run_dir) / PROVENANCE_FILE
    try:
        prov = json.loads(path.read_text())
    except FileNotFoundError:
        raise UserInputError(f"run directory {run_dir} has no {PROVENANCE_FILE}; {needed_for}") from None
    except (OSError, ValueError) as exc:
        raise UserInputError(f"run directory {run_dir}: cannot read {PROVENANCE_FILE} ({type(exc).__name__}); "
                             f"{needed_for}") from None
    if not isinstance(prov, dict):
        raise UserInputError(f"run directory {run_dir}: {PROVENANCE_FILE} is not a run record; {needed_for}")
    record = SweepRecord.from_provenance(run_dir, prov)
    if record.kind != "f90_sweep":
        raise UserInputError(f"run directory {run_dir} is a {record.kind!r} run; {needed_for}")
    if not record.g_edges:
        raise UserInputError(f"run directory {run_dir}: its {PROVENANCE_FILE} records no magnitudes.edges; "
                             f"{needed_for}")
    return record


def coefficients_from_terms(fitted, source: str) -> dict[str, tuple[float, ...]]:
    """``{"s0": (..), "s1": (..), "s2": (..)}`` from values keyed ``s0_c0`` ... ``s2_c1``
    (:data:`N_COEFFICIENTS`); ``source`` names them in the one-line error when one is absent."""
    out = {}
    for name, n in N_COEFFICIENTS.items():
        terms = [f"{name}_c{k}" for k in range(n)]
        absent = [t for t in terms if t not in fitted]
        if absent:
            raise UserInputError(f"{source} lacks the terms {absent}; expected "
                                 + ", ".join(f"{k}_c0..{k}_c{m - 1}" for k, m in N_COEFFICIENTS.items()))
        out[name] = tuple(float(fitted[t]) for t in terms)
    return out


def read_coefficients(path) -> dict[str, tuple[float, ...]]:
    """The ``fitted`` coefficients of a :data:`COEFFICIENTS_FILE` (rows named by ``term``).

    Raises
    ------
    mcsweep.errors.UserInputError
        In one line, when the file cannot be read, lacks the columns or a term.
    """
    import pandas as pd  # the readers that need a table

    path = Path(path)
    try:
        table = pd.read_csv(path)
    except (ValueError, OSError) as exc:
        raise UserInputError(f"cannot read {path} ({type(exc).__name__}); expected a finished sweep's "
                             f"{COEFFICIENTS_FILE}") from None
    if not {"term", "fitted"} <= set(table.columns):
        raise UserInputError(f"{path} has columns {list(table.columns)}; expected 'term' and 'fitted'")
    try:
        fitted = dict(zip(table["term"].astype(str), table["fitted"].astype(float)))
    except ValueError:
        raise UserInputError(f"{path}: column 'fitted' is not numeric; expected the fitted coefficients") from None
    return coefficients_from_terms(fitted, str(path))
