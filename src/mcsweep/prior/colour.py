"""The colour axis of the prior: Eqs. 14-17 fitted separately per Gaia BP-RP bin.

The paper's prior depends on direction and G only; its Sect. 3.4 names the next step,
priors that "take into account photometric ... information. For example, blue stars
have on average smaller parallaxes than red stars". A sweep with a colour axis fits
the form of Eqs. 14-17 once per BP-RP bin and writes the coefficients, one block of
rows per bin, to ``colour_coefficients.csv`` (columns ``bp_rp_min, bp_rp_max, term,
fitted``; other columns are ignored). ``ColourBins`` holds them and picks the bin
of each star:

* bins are half-open, ``bp_rp_min <= BP-RP < bp_rp_max``, contiguous and sorted;
* a colour below the first edge uses the first bin, above the last edge the last bin;
* NaN (unknown colour) selects no bin: the colour-blind prior of the same run
  (index -1, label ``COLOUR_BLIND``);
* a bin whose coefficients are not determined (NaN: none of its cells had enough stars)
  also gives the colour-blind prior (index -1);
* where the run wrote ``colour_terms.csv`` (Eq. 14 per colour bin and G bin, the first of
  Sect. 3.4's two least-squares steps), the prior interpolates those terms linearly in G
  between the G bins' centres, constant beyond the outer ones
  (``mcsweep.prior.formula.sigma_from_nodes``): a colour bin's mix of giants and dwarfs
  changes with G faster than the polynomials of Eqs. 15-17 follow (docs/prior_colour.md);
* otherwise a bin's polynomials hold over the G range of the cells that determined them
  (columns ``g_fit_min``, ``g_fit_max`` when present): fainter than ``g_fit_max`` the
  value at ``g_fit_max`` (the paper's rule at its faint end, Sect. 3.4), brighter than a
  ``g_fit_min`` above the run's own G range the value at ``g_fit_min`` (the polynomial is
  unconstrained there); otherwise the prior's rules (:mod:`mcsweep.prior.formula`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np
from astropy import units as u

from ..errors import UserInputError
from .columns import read_run_table, unit_scale
from .formula import sigma_from_coefficients, sigma_from_nodes
from .run_record import COLOUR_TERMS_FILE, N_COEFFICIENTS, coefficients_from_terms

__all__ = ["COLOUR_BLIND", "TERMS", "ColourBins", "colour_values", "bin_label"]

#: Label of the colour-blind prior (a star without BP-RP, or a prior without colour axis).
COLOUR_BLIND = "colour_blind"
#: Number of polynomial coefficients of s0, s1, s2 (Eqs. 15-17; :data:`.run_record.N_COEFFICIENTS`).
TERMS = N_COEFFICIENTS
#: Two edges closer than this (mag) are the same edge (the CSV's bins against the config's).
_EDGE_ATOL = 1e-9


def colour_values(bp_rp, what: str = "bp_rp") -> np.ndarray:
    """BP-RP as float64 (a Quantity in mag or plain numbers); NaN stays NaN (unknown colour)."""
    if isinstance(bp_rp, u.Quantity):
        return bp_rp.value * unit_scale(bp_rp.unit, "mag", what)
    try:
        return np.asarray(bp_rp, dtype=float)
    except (TypeError, ValueError):
        raise UserInputError(f"{what} has non-numeric values; expected BP-RP colours in mag "
                             "(NaN where unknown)") from None


def bin_label(lo: float, hi: float) -> str:
    """The name of the BP-RP bin [lo, hi) (mag): ``'lo..hi'``, as every table and figure of
    a colour prior names it (``prior_colour_bin``, the colour sweep's report)."""
    return f"{lo:g}..{hi:g}"


@dataclass(frozen=True, eq=False)
class ColourBins:
    """Coefficients of Eqs. 14-17 per BP-RP bin.

    Parameters
    ----------
    edges : sequence of float
        K + 1 increasing bin edges in mag.
    coefficients : sequence of mappings or None
        K mappings ``{"s0": (..), "s1": (..), "s2": (..)}`` (as :class:`mcsweep.prior.Prior`);
        None for a bin whose fit is undetermined (its stars get the colour-blind prior).
    g_ranges : sequence of (float, float), optional
        Per bin, the G range of the cells that determined its fit (NaN: not recorded).
    """

    edges: tuple[float, ...]
    coefficients: tuple[Mapping[str, tuple[float, ...]] | None, ...]
    g_ranges: tuple[tuple[float, float], ...] | None = None
    #: Per bin, the Eq. 14 terms per G bin (rows g, s0, s1, s2; ``colour_terms.csv``), which the
    #: prior uses instead of the polynomials where present (``sigma_from_nodes``).
    nodes: tuple[np.ndarray | None, ...] | None = None

    def __post_init__(self):
        edges = tuple(float(e) for e in self.edges)
        if len(edges) < 2 or not all(map(math.isfinite, edges)) or any(b <= a for a, b in zip(edges, edges[1:])):
            raise UserInputError(f"colour edges {list(edges)} are not accepted; expected at least two "
                                 "increasing finite BP-RP values in mag")
        if len(self.coefficients) != len(edges) - 1:
            raise UserInputError(f"{len(self.coefficients)} coefficient sets for {len(edges) - 1} colour bins; "
                                 "expected one per bin")
        frozen = []
        for c, lab in zip(self.coefficients, self.labels_of(edges)):
            if c is None:
                frozen.append(None)
                continue
            missing = [k for k in TERMS if k not in c]
            if missing:
                raise UserInputError(f"coefficients of colour bin {lab} lack {missing}; expected s0, s1, s2")
            f = MappingProxyType({k: tuple(float(v) for v in c[k]) for k in TERMS})
            if not all(math.isfinite(v) for k in TERMS for v in f[k]):
                raise UserInputError(f"coefficients of colour bin {lab} are not finite numbers; expected a "
                                     "fitted prior for every colour bin")
            frozen.append(f)
        ranges = self.g_ranges if self.g_ranges is not None else [(np.nan, np.nan)] * len(frozen)
        if len(ranges) != len(frozen):
            raise UserInputError(f"{len(ranges)} G ranges for {len(frozen)} colour bins; expected one per bin")
        nodes = self.nodes if self.nodes is not None else [None] * len(frozen)
        if len(nodes) != len(frozen):
            raise UserInputError(f"{len(nodes)} sets of G-bin terms for {len(frozen)} colour bins; expected one per bin")
        object.__setattr__(self, "nodes", tuple(None if n is None or len(n) == 0 else np.asarray(n, float)
                                                for n in nodes))
        object.__setattr__(self, "edges", edges)
        object.__setattr__(self, "coefficients", tuple(frozen))
        object.__setattr__(self, "g_ranges", tuple((float(a), float(b)) for a, b in ranges))

    @staticmethod
    def labels_of(edges: Sequence[float]) -> tuple[str, ...]:
        return tuple(bin_label(a, b) for a, b in zip(edges, edges[1:]))

    @property
    def labels(self) -> tuple[str, ...]:
        """One label per bin, ``'lo..hi'`` in mag (e.g. ``'0.56..1.23'``)."""
        return self.labels_of(self.edges)

    @property
    def n_bins(self) -> int:
        return len(self.edges) - 1

    def index(self, bp_rp) -> np.ndarray:
        """Bin of each colour (0 .. K-1; outer bins extended), -1 where NaN or the bin's fit is
        undetermined (colour-blind)."""
        c = colour_values(bp_rp)
        idx = np.searchsorted(np.asarray(self.edges[1:-1]), c, side="right")
        determined = np.array([c is not None or n is not None for c, n in zip(self.coefficients, self.nodes)])
        return np.where(np.isnan(c) | ~determined[idx], -1, idx)

    def sigma_mas(self, k: int, l_deg, b_deg, g, g_min: float, g_max: float, bright: str) -> np.ndarray:
        """sigma_F90 [mas] of colour bin ``k``: from its G-bin terms where the run wrote them,
        else from its Eqs. 15-17 polynomials within :meth:`g_limits`."""
        if self.nodes[k] is not None:
            n = self.nodes[k]
            return sigma_from_nodes(l_deg, b_deg, g, n[:, 0], n[:, 1:4])
        g_low, g_high = self.g_limits(k, g_min, g_max, bright)
        return sigma_from_coefficients(l_deg, b_deg, g, self.coefficients[k], g_min=g_low, g_max=g_high)

    def g_limits(self, k: int, g_min: float, g_max: float, bright: str) -> tuple[float | None, float]:
        """(lower, upper) G clamp of bin ``k`` for a prior fitted over ``g_min``-``g_max`` (module notes)."""
        lo, hi = self.g_ranges[k]
        upper = min(g_max, hi) if math.isfinite(hi) else g_max
        if math.isfinite(lo) and lo > g_min:
            return lo, upper
        return (g_min if bright == "clamp" else None), upper

    def label(self, index) -> np.ndarray:
        """Labels of bin indices from :meth:`index` (``COLOUR_BLIND`` for -1), str array."""
        names = np.array(self.labels + (COLOUR_BLIND,), dtype=object)
        return np.asarray(names[np.asarray(index)]).astype(str)

    @classmethod
    def read(cls, path, edges: Sequence[float]) -> "ColourBins":
        """The bins of ``colour_coefficients.csv``, checked against the config's ``colour_edges``."""
        path = Path(path)
        table = read_run_table(path, ("bp_rp_min", "bp_rp_max", "term", "fitted"),
                               "with a colour axis (prior_model.colour_edges not empty)")
        edges = [float(e) for e in edges]
        blocks, ranges = [], []
        for lo, hi in zip(edges, edges[1:]):
            sel = np.isclose(table["bp_rp_min"].astype(float), lo, rtol=0, atol=_EDGE_ATOL) \
                & np.isclose(table["bp_rp_max"].astype(float), hi, rtol=0, atol=_EDGE_ATOL)
            rows = table[sel]
            if rows["term"].duplicated().any():
                raise UserInputError(f"{path}: colour bin {bin_label(lo, hi)} names a term twice; expected one "
                                     "row per term and bin")
            fitted = dict(zip(rows["term"].astype(str), rows["fitted"].astype(float)))
            c = coefficients_from_terms(fitted, f"{path} (colour bin {bin_label(lo, hi)})")
            # One undetermined polynomial (too few G bins for its degree) leaves the bin's
            # Eqs. 15-17 undetermined; its G-bin terms (colour_terms.csv) may still give it a width.
            undetermined = any(math.isnan(v) for v in fitted.values())
            blocks.append(None if undetermined else c)
            ranges.append(tuple(float(rows[col].iloc[0]) if col in rows and len(rows) else np.nan
                                for col in ("g_fit_min", "g_fit_max")))
        bins = set(zip(table["bp_rp_min"].astype(float), table["bp_rp_max"].astype(float)))
        unknown = [b for b in bins if not any(abs(b[0] - lo) <= _EDGE_ATOL and abs(b[1] - hi) <= _EDGE_ATOL
                                              for lo, hi in zip(edges, edges[1:]))]
        if unknown:
            raise UserInputError(f"{path}: colour bin {bin_label(*sorted(unknown)[0])} is not one of the run's "
                                 f"prior_model.colour_edges {edges}; expected contiguous bins between those edges")
        return cls(tuple(edges), tuple(blocks), tuple(ranges), _read_nodes(path.parent / COLOUR_TERMS_FILE, edges))


def _read_nodes(path: Path, edges: list[float]) -> tuple[np.ndarray | None, ...] | None:
    """Per colour bin, the determined rows (g, s0, s1, s2) of ``colour_terms.csv``, sorted by
    G; None when the run has no such file (the polynomials of ``colour_coefficients.csv``)."""
    if not path.is_file():
        return None
    names = ("bp_rp_min", "bp_rp_max", "g", "s0", "s1", "s2")
    table = read_run_table(path, names, "with a colour axis (prior_model.colour_edges not empty)", numeric=names)
    cols = {c: table[c].to_numpy() for c in names}
    out = []
    for lo, hi in zip(edges, edges[1:]):
        sel = (np.isclose(cols["bp_rp_min"], lo, rtol=0, atol=_EDGE_ATOL)
               & np.isclose(cols["bp_rp_max"], hi, rtol=0, atol=_EDGE_ATOL))
        rows = np.column_stack([cols[c][sel] for c in ("g", "s0", "s1", "s2")])
        rows = rows[np.all(np.isfinite(rows), axis=1)]
        out.append(rows[np.argsort(rows[:, 0])] if len(rows) else None)
    return tuple(out)
