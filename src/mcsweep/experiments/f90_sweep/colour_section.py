"""The report's subsection on a prior per colour and, with ``prior_model.mean``, centred on
the galaxy model's mean parallax and proper motion (the paper's next step, Sect. 3.4: "more
sophisticated priors ... which take into account photometric ... information").

Only for a run that wrote the colour files (:data:`~.colour_fit.COLOUR_FILES`; the mean part
also :data:`~.colour_fit.MEANS_FILE`); a run without them gets no subsection. Reads the
tables :mod:`.colour_fit` wrote and the rows at sigma_F90 of ``cells.parquet``, and computes
only summaries of them: medians and ranges over the directions, and Clopper-Pearson
intervals (Clopper & Pearson 1934) of a single cell's fraction inside from its counts.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...prior import Prior
from ...prior.colour import bin_label
from ...prior.run_record import MEANS_FILE, SweepRecord
from ...runtime.document import FIG_DIR, Document, counts_text
from ..global_solution.table import FRACTION_INTERVAL, fraction_from_counts
from . import colour_figures
from .colour_fit import COLOUR_FILES
from .fit import read_fit

__all__ = ["colour_section", "read_colour_run", "ColourRun", "COLOUR_BLIND", "TARGET_BAND", "bin_stats",
           "forms_table", "fraction_table", "mean_table", "fitted_curves", "intro_sentence", "forms_sentence",
           "fraction_sentence", "quasar_sentence"]

#: Label of the colour-blind cells (no BP-RP bin) in the tables and figures.
COLOUR_BLIND = "colour-blind"
#: The band of fractions inside that counts as honest at P = 0.9: 2 points either side
#: (the binomial standard error of one cell's fraction at 1000 stars is 1 point).
TARGET_BAND = (0.88, 0.92)
_AT_COLUMNS = ["cell_id", "case", "at_f90", "p_error_mas", "n_inside", "n_valid"]


@dataclass(frozen=True)
class ColourRun:
    """What the subsection reads: ``cells`` holds every colour cell and every colour-blind
    cell (column ``colour``: the bin label or :data:`COLOUR_BLIND`) with the stars' row at
    sigma_F90 of the F90 case (``star_p_error_mas``, ``n_inside``, ``n_valid``)."""

    model: dict
    labels: list
    cells: pd.DataFrame
    forms: pd.DataFrame
    case: str
    confidence: float
    mean: bool
    #: The run's prior (:meth:`mcsweep.prior.Prior.from_run`): what a user of the run gets.
    prior: object = None


def _read_csv(path: Path) -> pd.DataFrame:
    """A CSV the sweep wrote; empty (no columns) when it wrote an empty table."""
    try:
        return pd.read_csv(path)
    except pd.errors.EmptyDataError:
        return pd.DataFrame()


def _at_f90(run_dir: Path, case: str) -> pd.DataFrame:
    """Each cell's row at its sigma_F90 in the F90 case (empty without ``cells.parquet``)."""
    path = run_dir / "cells.parquet"
    if not path.exists():
        return pd.DataFrame(columns=["cell_id", "star_p_error_mas", "n_inside", "n_valid"])
    rows = pd.read_parquet(path, columns=_AT_COLUMNS)
    rows = rows[rows["at_f90"].astype(bool) & (rows["case"] == case)]
    return rows.drop(columns=["case", "at_f90"]).rename(columns={"p_error_mas": "star_p_error_mas"})


def read_colour_run(run_dir: Path, prov: dict) -> ColourRun | None:
    """The colour run in ``run_dir``, or None when it wrote no colour files."""
    run_dir = Path(run_dir)
    if not all((run_dir / name).exists() for name in COLOUR_FILES):
        return None
    record = SweepRecord.from_provenance(run_dir, prov)
    case = record.f90_case
    colour = _read_csv(run_dir / "f90_colour_cells.csv")
    if colour.empty:  # no colour cell at all: nothing per colour to report
        return None
    colour["colour"] = [bin_label(a, b) for a, b in zip(colour["bp_rp_min"], colour["bp_rp_max"])]
    labels = [bin_label(a, b) for a, b in sorted(set(zip(colour["bp_rp_min"], colour["bp_rp_max"])))]
    fit = read_fit(run_dir)
    blind = fit.compared
    if "bp_rp_min" in blind:
        blind = blind[blind["bp_rp_min"].isna()]
    blind = blind.assign(colour=COLOUR_BLIND, colour_blind_sigma_f90_mas=blind["fitted_sigma_f90_mas"])
    cells = pd.concat([colour, blind], ignore_index=True).merge(_at_f90(run_dir, case), on="cell_id", how="left")
    for column in ("fraction_at_fitted", "fraction_at_colour_blind"):
        if column not in cells:  # a run whose cell curves were not at hand when it fitted the colours
            cells[column] = np.nan
    mean = (run_dir / MEANS_FILE).exists() and "quasar_fraction_inside" in cells
    confidence = 0.9 if record.confidence is None else record.confidence
    return ColourRun(record.prior_model, labels, cells, _read_csv(run_dir / "colour_fit_forms.csv"),
                     case, confidence, bool(mean), Prior.from_run(run_dir))


def colour_section(doc: Document, run_dir: Path, prov: dict, figdir: Path) -> None:
    """The subsection "The prior per colour (and its mean)"; nothing for a run without colour files."""
    run = read_colour_run(run_dir, prov)
    if run is None:
        return
    doc.heading("The prior per colour" + (" and its mean" if run.mean else ""), level=3)
    doc.para(intro_sentence(run))
    forms = forms_table(run.forms)
    if len(forms):
        doc.table(forms, "Residual RMS [dex] of the colour cells' log10 sigma_F90 about each "
                  "candidate form of the colour term, per BP-RP bin (– : the form has no fit in that bin), "
                  "and the form's number of parameters", {c: ".3f" for c in ["all", *run.labels]})
    doc.para(forms_sentence(run))
    ok = _ok(run.cells)
    stats = bin_stats(ok, "sigma_f90_mas", [*run.labels, COLOUR_BLIND])
    doc.draw(colour_figures.plot_sigma_by_colour, stats, fitted_curves(run), figdir / "colour_sigma_f90.png")
    frac, frac_blind = _fraction_stats(run)
    doc.draw(colour_figures.plot_fraction_by_colour, frac, frac_blind, TARGET_BAND, run.confidence,
             figdir / "colour_fraction.png")
    doc.figure_row([(f"{FIG_DIR}/colour_sigma_f90.png", "sigma_F90 against G per BP-RP bin: median over the "
                     "directions of the cells with a sigma_F90, bars 16-84 % across directions; black: the "
                     "colour-blind cells; lines: the run's prior per bin (per_bin_g form) and colour-blind, median "
                     "over the same directions, over each bin's fitted G range"),
                    (f"{FIG_DIR}/colour_fraction.png", "Fraction inside the P ellipse per BP-RP bin and G bin at "
                     "the bin's fitted width (colour) and at the colour-blind fitted width (grey), median over "
                     f"the directions, bars min-max; shaded {100 * TARGET_BAND[0]:g}-{100 * TARGET_BAND[1]:g} %")])
    table = fraction_table(ok)
    if len(table):
        doc.table(table, "Fraction inside [%] at the fitted width of each cell's BP-RP bin and at the "
                  "colour-blind fitted width, the same cells (those with a sigma_F90), over the directions",
                  {"fitted median": ".1f", "colour-blind median": ".1f"})
    doc.para(fraction_sentence(run))
    if run.mean:
        _mean_part(doc, run, figdir)


def _ok(cells: pd.DataFrame) -> pd.DataFrame:
    return cells[(cells["f90_flag"] == "ok") & np.isfinite(cells["sigma_f90_mas"].astype(float))]


def _fraction_stats(run: ColourRun) -> tuple[pd.DataFrame, pd.DataFrame]:
    colour = _ok(run.cells)
    colour = colour[colour["colour"] != COLOUR_BLIND]
    return (bin_stats(colour, "fraction_at_fitted", run.labels),
            bin_stats(colour, "fraction_at_colour_blind", run.labels))


def bin_stats(cells: pd.DataFrame, column: str, labels: list) -> pd.DataFrame:
    """Per colour label x G bin, over the directions: the number of finite values of
    ``column`` and their median, 16th / 84th percentiles, minimum and maximum."""
    rows = []
    for (colour, g0, g1), grp in cells.groupby(["colour", "g_min", "g_max"], sort=False):
        v = grp[column].to_numpy(float)
        v = v[np.isfinite(v)]
        stats = (np.median(v), *np.percentile(v, [16, 84]), v.min(), v.max()) if len(v) else (np.nan,) * 5
        rows.append(dict(zip(["colour", "g_min", "g_max", "g", "n", "median", "p16", "p84", "min", "max"],
                             (colour, g0, g1, 0.5 * (g0 + g1), len(v), *stats))))
    out = pd.DataFrame(rows, columns=["colour", "g_min", "g_max", "g", "n", "median", "p16", "p84", "min", "max"])
    out = out[out["colour"].isin(labels)]
    order = {c: i for i, c in enumerate(labels)}
    return out.sort_values(["colour", "g_min"], key=lambda s: s.map(order) if s.name == "colour" else s,
                           ignore_index=True)


def _g_ranges(run: ColourRun) -> dict[str, tuple[float, float]]:
    """Per BP-RP label: the G range of the cells that determined the bin's prior (NaN: not
    recorded), as the run's prior holds it."""
    return dict(zip(run.prior.colour.labels, run.prior.colour.g_ranges))


def fitted_curves(run: ColourRun, n_g: int = 60) -> pd.DataFrame:
    """The run's prior against G (colour, g, sigma_mas): each BP-RP bin's own (queried with the
    bin's mid colour, over its fitted G range where recorded) and the colour-blind one, each the
    median over the run's directions; no row for a bin whose prior is the colour-blind one."""
    cells = run.cells
    dirs = cells[["l_deg", "b_deg"]].drop_duplicates().to_numpy(float)
    g_lo, g_hi = float(cells["g_min"].min()), float(cells["g_max"].max())
    ranges = _g_ranges(run)
    rows = []
    for colour, mid in [(lab, _mid(lab)) for lab in run.labels if _determined(run).get(lab)] + [(COLOUR_BLIND, None)]:
        g0, g1 = ranges.get(colour, (np.nan, np.nan))
        g = np.linspace(g0 if np.isfinite(g0) else g_lo, g1 if np.isfinite(g1) else g_hi, n_g)
        sigma = run.prior.sigma_parallax_mas(dirs[:, :1], dirs[:, 1:], g[None, :],
                                             bp_rp=None if mid is None else np.full((1, n_g), mid))
        rows.append(pd.DataFrame({"colour": colour, "g": g, "sigma_mas": np.median(sigma, axis=0)}))
    return pd.concat(rows, ignore_index=True)


def _mid(label: str) -> float:
    lo, hi = (float(v) for v in label.split(".."))
    return (lo + hi) / 2


def _determined(run: ColourRun) -> dict[str, bool]:
    """Per BP-RP label: whether the run's prior has a width of its own for the bin (else a star
    of that colour gets the colour-blind prior)."""
    return {lab: bool(run.prior.colour_bin(_mid(lab)) >= 0) for lab in run.labels}


def intro_sentence(run: ColourRun) -> str:
    """The prior model, its colour bins, the colour cells' flags and which bins have a fit."""
    colour = run.cells[run.cells["colour"] != COLOUR_BLIND]
    edges = run.model.get("colour_edges") or sorted({*colour["bp_rp_min"], *colour["bp_rp_max"]})
    text = (f"Prior model `{run.model.get('name', '?')}` (provenance config[\"prior_model\"]): sigma_F90 is found "
            f"again per direction x G bin x Gaia BP-RP bin by the same criterion (Sect. 3.3, the '{run.case}' "
            f"case), BP-RP edges {', '.join(f'{float(e):g}' for e in edges)} mag (bins {', '.join(run.labels)}; "
            "a colour below the first edge takes the first bin, above the last edge the last); "
            f"{len(colour)} colour cells: {counts_text(colour['f90_flag'].value_counts().to_dict(), 'cells')}.")
    if run.mean:
        text += (" Each prior is centred on the galaxy model's mean parallax and proper motion of its cell "
                 f"(`{MEANS_FILE}`), and the width is the width around that mean; the paper's prior is "
                 "always centred on zero (Sect. 5).")
    ranges = _g_ranges(run)
    done = [lab for lab, ok in _determined(run).items() if ok]
    missing = [lab for lab, ok in _determined(run).items() if not ok]
    if done:
        text += " Eq. 14 fitted per bin and G bin (interpolated in G) for " + ", ".join(
            lab + (f" (G {ranges[lab][0]:g}-{ranges[lab][1]:g})" if np.all(np.isfinite(ranges[lab])) else "")
            for lab in done) + "."
    if missing:
        text += (f" Not determined for {', '.join(missing)} (no G bin with an Eq. 14 fit): stars of such a "
                 "bin get this run's colour-blind prior.")
    return text


def forms_table(forms: pd.DataFrame) -> pd.DataFrame:
    """``colour_fit_forms.csv`` as form x BP-RP bin (and ``all``) RMS [dex], with the form's
    number of parameters."""
    if forms.empty:
        return pd.DataFrame(columns=["form", "n parameters"])
    names, bins = list(dict.fromkeys(forms["form"])), list(dict.fromkeys(forms["colour_bin"]))
    table = forms.pivot(index="form", columns="colour_bin", values="rms_dex").reindex(index=names, columns=bins)
    n_par = forms.drop_duplicates("form").set_index("form")["n_parameters"].reindex(names)
    table.insert(0, "n parameters", n_par.astype(int).to_numpy())
    table.columns.name = None
    return table.reset_index()


def _noise_dex(cells: pd.DataFrame) -> float:
    """Median half-width [dex] of the cells' 16-84 % bootstrap interval of sigma_F90."""
    if not {"sigma_f90_lo_mas", "sigma_f90_hi_mas"} <= set(cells.columns):
        return float("nan")
    with np.errstate(divide="ignore", invalid="ignore"):
        half = 0.5 * np.log10(cells["sigma_f90_hi_mas"].to_numpy(float) / cells["sigma_f90_lo_mas"].to_numpy(float))
    half = half[np.isfinite(half)]
    return float(np.median(half)) if len(half) else float("nan")


def forms_sentence(run: ColourRun) -> str:
    """Which form the prior uses and what the forms' RMS say, against the cells' own noise."""
    if run.forms.empty:
        return "No colour cell has a sigma_F90, so no form of the colour term could be judged."
    total = run.forms[run.forms["colour_bin"] == "all"].set_index("form")
    rms, n_par = total["rms_dex"], total["n_parameters"]
    if rms.dropna().empty:
        return "No colour cell has a sigma_F90, so no form of the colour term could be judged."
    best = rms.idxmin()
    text = ("The prior uses the per_bin_g form: Eq. 14 fitted to each BP-RP bin's cells per G bin (the first of "
            "Sect. 3.4's two steps), the terms interpolated linearly in G; with per_bin (Eqs. 14-17 per bin) "
            "the only forms whose direction terms s1, s2 differ between colours.")
    if "per_bin_g" in rms and np.isfinite(rms["per_bin_g"]):
        text += (f" Over all the colour cells its RMS is {rms['per_bin_g']:.3f} dex ({int(n_par['per_bin_g'])} "
                 "parameters; over the bins it fits)")
        if "colour_blind" in rms:
            text += f", against {rms['colour_blind']:.3f} dex about the colour-blind surface (0 parameters)"
        text += "; " + ("it has the lowest RMS of the forms" if best == "per_bin_g" else
                        f"the lowest RMS, {rms[best]:.3f} dex, is the '{best}' form's ({int(n_par[best])} parameters)")
    ok = _ok(run.cells)
    noise = _noise_dex(ok[ok["colour"] != COLOUR_BLIND])
    if np.isfinite(noise):
        text += (f". A colour cell's own Monte Carlo noise is {noise:.3f} dex (median half-width of its 16-84 % "
                 "bootstrap interval), so RMS well above it are differences between the cells the form misses")
    return text + "."


def _range(v: np.ndarray, scale: float = 100.0, fmt: str = ".1f") -> str:
    v = v[np.isfinite(v)]
    return f"{format(scale * v.min(), fmt)}-{format(scale * v.max(), fmt)}" if len(v) else "–"


def _in_band(v: np.ndarray) -> str:
    v = v[np.isfinite(v)]
    if not len(v):
        return "–"
    return f"{int(np.count_nonzero((v >= TARGET_BAND[0]) & (v <= TARGET_BAND[1])))} of {len(v)}"


def fraction_table(ok: pd.DataFrame) -> pd.DataFrame:
    """Per BP-RP bin x G bin over the directions (colour cells with a sigma_F90): the fraction
    inside [%] at the bin's fitted width and at the colour-blind one (median, min-max, cells
    in :data:`TARGET_BAND`)."""
    band = f"{100 * TARGET_BAND[0]:g}-{100 * TARGET_BAND[1]:g} %"
    rows = []
    for (colour, g0, g1), grp in ok[ok["colour"] != COLOUR_BLIND].groupby(["colour", "g_min", "g_max"], sort=False):
        row = {"BP-RP": colour, "G": f"{g0:g}-{g1:g}", "cells": len(grp)}
        for width, name in (("fitted", "fitted"), ("colour_blind", "colour-blind")):
            v = grp[f"fraction_at_{width}"].to_numpy(float)
            row |= {f"{name} median": 100 * np.median(v[np.isfinite(v)]) if np.isfinite(v).any() else np.nan,
                    f"{name} min-max": _range(v), f"{name} in {band}": _in_band(v)}
        rows.append(row)
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    order = {c: float(c.split("..")[0]) for c in out["BP-RP"]}
    return out.assign(_c=out["BP-RP"].map(order), _g=[float(g.split("-")[0]) for g in out["G"]]) \
        .sort_values(["_c", "_g"]).drop(columns=["_c", "_g"]).reset_index(drop=True)


def _cell_with_interval(row, fraction: float, n_valid: float) -> str:
    """One cell's fraction inside with its Clopper-Pearson interval from the counts, and where."""
    n = int(n_valid) if np.isfinite(n_valid) else 0
    f, lo, hi = fraction_from_counts(int(round(fraction * n)), n) if n else (fraction, np.nan, np.nan)
    iv = f" [{100 * lo:.1f}-{100 * hi:.1f}]" if np.isfinite(lo) else ""
    where = COLOUR_BLIND if row["colour"] == COLOUR_BLIND else f"BP-RP {row['colour']}"
    return (f"{100 * fraction:.1f}{iv} % ({where}, G {row['g_min']:g}-{row['g_max']:g}, "
            f"(l, b) = ({row['l_deg']:.1f}, {row['b_deg']:.1f}) deg, {n} stars)")


def fraction_sentence(run: ColourRun) -> str:
    """How many colour cells are honest at the fitted width and at the colour-blind width,
    and the extreme cells with their binomial intervals."""
    ok = _ok(run.cells)
    ok = ok[ok["colour"] != COLOUR_BLIND]
    fitted = ok[np.isfinite(ok["fraction_at_fitted"].astype(float))]
    lo_pct, hi_pct = (f"{100 * x:g}" for x in TARGET_BAND)
    if fitted.empty:
        return "No colour cell has a fraction inside at a fitted width of its bin."
    f, b = fitted["fraction_at_fitted"].to_numpy(float), fitted["fraction_at_colour_blind"].to_numpy(float)
    low, high = fitted.loc[fitted["fraction_at_fitted"].idxmin()], fitted.loc[fitted["fraction_at_fitted"].idxmax()]
    text = (f"At the fitted width of their BP-RP bin {_in_band(f)} colour cells keep {lo_pct}-{hi_pct} % of the "
            f"stars inside the P = {run.confidence:g} ellipse, at the colour-blind width {_in_band(b)} of the "
            f"same cells (median {100 * np.median(f):.1f} % and {100 * np.nanmedian(b):.1f} %). Lowest at the "
            f"fitted width {_cell_with_interval(low, low['fraction_at_fitted'], low['n_valid'])}; highest "
            f"{_cell_with_interval(high, high['fraction_at_fitted'], high['n_valid'])} "
            f"({100 * FRACTION_INTERVAL:g} % Clopper-Pearson intervals from the counts at the fitted width).")
    rest = ok[~ok["colour"].isin(fitted["colour"])]
    if len(rest):
        text += (f" The bins without a fit ({', '.join(dict.fromkeys(rest['colour']))}) use the colour-blind "
                 f"width: {_in_band(rest['fraction_at_colour_blind'].to_numpy(float))} of their cells in "
                 f"{lo_pct}-{hi_pct} %.")
    return text


def mean_table(ok: pd.DataFrame, labels: list, p: float = 0.9) -> pd.DataFrame:
    """Per BP-RP bin (and the colour-blind cells) x G bin, medians over the directions of the
    cells with a sigma_F90: the stars' P-th percentile position error at sigma_F90 (a
    mean-centred prior), the quasars' fraction inside (median, min) and percentile error,
    and the quasars' error over the stars' per cell."""
    pct, rows = f"p{100 * p:g}", []
    for (colour, g0, g1), grp in ok.groupby(["colour", "g_min", "g_max"], sort=False):
        star, qso = grp["star_p_error_mas"].to_numpy(float), grp["quasar_p_error_mas"].to_numpy(float)
        frac = grp["quasar_fraction_inside"].to_numpy(float)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = qso / star
        rows.append({"BP-RP": colour, "G": f"{g0:g}-{g1:g}", "cells": len(grp),
                     f"stars {pct} [mas]": np.nanmedian(star) if np.isfinite(star).any() else np.nan,
                     "quasars inside [%]": 100 * np.nanmedian(frac) if np.isfinite(frac).any() else np.nan,
                     "quasars inside min-max [%]": _range(frac),
                     f"quasars {pct} [mas]": np.nanmedian(qso) if np.isfinite(qso).any() else np.nan,
                     f"quasars / stars {pct}": np.nanmedian(ratio) if np.isfinite(ratio).any() else np.nan})
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    order = {c: i for i, c in enumerate(labels)}
    return out.assign(_c=out["BP-RP"].map(order), _g=[float(g.split("-")[0]) for g in out["G"]]) \
        .sort_values(["_c", "_g"]).drop(columns=["_c", "_g"]).reset_index(drop=True)


def _quasar_clause(q: pd.DataFrame, what: str) -> str:
    """How many of the cells ``q`` keep fewer than the band's lower edge of quasars inside,
    their median and pooled fraction (Clopper-Pearson from the summed counts) and the lowest cell."""
    frac = q["quasar_fraction_inside"].to_numpy(float)
    n_valid = q["quasar_n_valid"].to_numpy(float)
    pooled, lo, hi = fraction_from_counts(int(np.rint(frac * n_valid).sum()), int(n_valid.sum()))
    low = q.loc[q["quasar_fraction_inside"].idxmin()]
    return (f"{int(np.count_nonzero(frac < TARGET_BAND[0]))} of {len(q)} {what} keep fewer than "
            f"{100 * TARGET_BAND[0]:g} % of them inside (median {100 * np.median(frac):.1f} %, pooled "
            f"{100 * pooled:.1f} [{100 * lo:.1f}-{100 * hi:.1f}] %; lowest "
            f"{_cell_with_interval(low, low['quasar_fraction_inside'], low['quasar_n_valid'])})")


def quasar_sentence(run: ColourRun) -> str:
    """What a mean-centred prior does to sources with zero parallax and proper motion, in
    this run's numbers: per kind of cell (colour, colour-blind) the fraction inside, and the
    quasars' percentile error over the stars'."""
    ok = _ok(run.cells)
    q = ok[np.isfinite(ok["quasar_fraction_inside"].astype(float)) & (ok["quasar_n_valid"].fillna(0) > 0)]
    if q.empty:
        return "No cell has quasars solved at its sigma_F90."
    parts = [_quasar_clause(grp, what) for grp, what in ((q[q["colour"] != COLOUR_BLIND], "colour cells"),
                                                          (q[q["colour"] == COLOUR_BLIND], "colour-blind cells"))
             if len(grp)]
    text = ("Zero-truth sources (quasars: zero parallax and proper motion, solved through the same cells at the "
            "stars' G) can fall outside the ellipses of a prior centred on the stars' mean, which pulls their "
            "solutions towards a motion they do not have (the paper keeps zero, conservative for quasars, Sect. 5). "
            f"At each cell's sigma_F90, {'; '.join(parts)}.")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (q["quasar_p_error_mas"] / q["star_p_error_mas"]).to_numpy(float)
    ratio = ratio[np.isfinite(ratio)]
    if len(ratio):
        text += (f" Their {100 * run.confidence:g}th-percentile position error is {np.median(ratio):.2f} x the "
                 f"stars' at the same prior (median over the cells, {ratio.min():.2f}-{ratio.max():.2f}; "
                 f"{100 * FRACTION_INTERVAL:g} % Clopper-Pearson intervals above).")
    return text


def _mean_part(doc: Document, run: ColourRun, figdir: Path) -> None:
    ok = _ok(run.cells)
    labels = [*run.labels, COLOUR_BLIND]
    doc.draw(colour_figures.plot_mean_errors, bin_stats(ok, "star_p_error_mas", labels),
             bin_stats(ok, "quasar_p_error_mas", labels), bin_stats(ok, "quasar_fraction_inside", labels),
             TARGET_BAND, run.confidence, figdir / "colour_mean_quasars.png")
    doc.figure(f"{FIG_DIR}/colour_mean_quasars.png", f"Mean-centred prior at each cell's sigma_F90 ('{run.case}' "
               f"case): left, the {100 * run.confidence:g}th-percentile position error of the stars (solid) and of "
               "zero-truth sources, quasars (dashed), per BP-RP bin and for the colour-blind cells (black); right, "
               "the quasars' fraction inside; medians over the directions, bars 16-84 % (errors) and min-max "
               "(fraction)")
    pct, table = f"p{100 * run.confidence:g}", mean_table(ok, labels, run.confidence)
    if len(table):
        doc.table(table, f"Mean-centred prior at sigma_F90 ('{run.case}' case), per BP-RP bin and G bin, medians "
                  f"over the directions: the {100 * run.confidence:g}th-percentile position error of the stars and "
                  "of quasars, the quasars' fraction inside (median, min-max) and the quasars' error over the "
                  "stars' per cell",
                  {f"stars {pct} [mas]": ".3g", "quasars inside [%]": ".1f", f"quasars {pct} [mas]": ".3g",
                   f"quasars / stars {pct}": ".2f"})
    doc.para(quasar_sentence(run))
