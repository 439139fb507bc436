"""The sweep report's subsection on the prior per colour and its mean.

The run directories are written by the sweep's own aggregation (``write_fit``) from a
synthetic ``cells.parquet``: cells whose fraction inside rises with the prior as
1 / (1 + (sigma / sigma_F90)^-3 / 9) (0.9 at the cell's sigma_F90), sigma_F90 from the
paper's Eqs. 14-17 scaled per colour with scatter, and known quasar columns. The tests
recompute the subsection's numbers from the CSV files independently (pandas and
scipy's beta distribution for the Clopper-Pearson intervals).
"""

import itertools
import json
import re

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from mcsweep.experiments.f90_sweep.fit import PAPER_COEFFICIENTS, evaluate_formula
from mcsweep.experiments.f90_sweep.runner import write_fit
from mcsweep.experiments.f90_sweep.section import sweep_section
from mcsweep.runtime.document import Document

DIRECTIONS = [(0.0, 5.0), (60.0, 30.0), (120.0, -45.0), (180.0, 70.0), (240.0, -10.0), (300.0, 20.0)]
G_EDGES = [8.0, 10.0, 12.0, 14.0, 16.0]
#: BP-RP bins and the factor on the paper's sigma_F90 of each (None: the colour-blind cells).
COLOURS = [(None, 1.0), ((-1.0, 0.56), 0.6), ((0.56, 1.23), 1.7)]
GRID = np.logspace(-2, 3, 21)
N_VALID = 1000
CASES = ("one", "two")
HEADING = "### The prior per colour"


def _cell_rows(cid, l, b, g0, g1, colour, sigma, rng, mean):
    base = dict(cell_id=cid, l_deg=l, b_deg=b, ra_deg=l, dec_deg=b, g_min=g0, g_max=g1, n_stars=N_VALID,
                n_in_cone=N_VALID, radius_deg=1.0, n_groups=10, sigma_f90_mas=sigma,
                f90_flag="ok" if np.isfinite(sigma) else "few_stars", sigma_f90_lo_mas=0.98 * sigma,
                sigma_f90_hi_mas=1.02 * sigma, ill_determined=False,
                bp_rp_min=np.nan if colour is None else colour[0], bp_rp_max=np.nan if colour is None else colour[1])
    if mean:
        base |= dict(mean_parallax_mas=rng.normal(2, 1), mean_pml_masyr=rng.normal(-4, 2),
                     mean_pmb_masyr=rng.normal(1, 1), mean_pmra_masyr=0.0, mean_pmdec_masyr=0.0,
                     n_mean_stars=N_VALID, quasar_fraction_inside=rng.uniform(0.5, 0.97), quasar_n_valid=N_VALID,
                     quasar_p_error_mas=sigma * rng.uniform(0.8, 2.0) if np.isfinite(sigma) else np.nan)
    rows = []
    for case in CASES:
        for s, at in [*((s, False) for s in GRID), *(((sigma, True),) if np.isfinite(sigma) else ())]:
            frac = 1.0 / (1.0 + (s / sigma) ** -3 / 9.0) if np.isfinite(sigma) else 1.0
            n_in = int(round(frac * N_VALID))
            p_err = (sigma * rng.uniform(0.5, 1.5) if case == "two" else 1e3) if at else np.nan
            rows.append(base | dict(case=case, sigma_prior_mas=s, at_f90=at, fraction_inside=n_in / N_VALID,
                                    n_inside=n_in, n_valid=N_VALID, p_error_mas=p_err, median_semi_major_mas=np.nan))
    return rows


def _cells(colour_axis=True, mean=True, seed=3):
    rng = np.random.default_rng(seed)
    rows = []
    for (l, b), (g0, g1), (colour, factor) in itertools.product(DIRECTIONS, zip(G_EDGES, G_EDGES[1:]), COLOURS):
        if colour is not None and not colour_axis:
            continue
        sigma = factor * float(evaluate_formula(PAPER_COEFFICIENTS, l, b, 0.5 * (g0 + g1))) * rng.lognormal(0, 0.1)
        if colour == (0.56, 1.23) and (l, g0) == (300.0, 14.0):
            sigma = np.nan  # a colour cell without sigma_F90 (few stars)
        tag = "" if colour is None else f"_c{colour[0]:g}-{colour[1]:g}"
        rows += _cell_rows(f"cell_l{l:g}_b{b:g}_g{g0:g}{tag}", l, b, g0, g1, colour, sigma, rng, mean)
    cells = pd.DataFrame(rows)
    if not colour_axis:
        cells = cells.drop(columns=["bp_rp_min", "bp_rp_max"])
    return cells


def _report(run_dir, cells, prior_model):
    run_dir.mkdir()
    # The sweep writes its provenance before it fits (the run's prior is read back from it).
    prov = {"kind": "f90_sweep", "config": {
        "confidence": 0.9, "ratio_R": 10.0, "observations": {"f90_case": "two", "cases": {c: [0] for c in CASES}},
        "magnitudes": {"edges": G_EDGES}, "prior_model": prior_model,
        "sky": {"kind": "list", "frame": "galactic", "directions": [list(d) for d in DIRECTIONS]}}, "derived": {}}
    (run_dir / "provenance.json").write_text(json.dumps(prov))
    write_fit(run_dir, cells, nside=1, f90_case="two")
    cells.to_parquet(run_dir / "cells.parquet", index=False)
    doc = Document("t")
    sweep_section(doc, run_dir, prov)
    return doc.to_markdown()


@pytest.fixture(scope="module")
def mean_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("colour") / "run"
    md = _report(run_dir, _cells(), {"name": "colour_mean", "colour_edges": [-1.0, 0.56, 1.23], "mean": True})
    return run_dir, md


def _table(md: str, first_column: str) -> pd.DataFrame:
    """The Markdown table whose header starts with ``| first_column |``, as strings."""
    lines = md.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"| {first_column} |"))
    header = [c.strip() for c in lines[start].strip("|").split("|")]
    body = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        body.append([c.strip() for c in line.strip("|").split("|")])
    return pd.DataFrame(body, columns=header)


def _section(md: str) -> str:
    start = md.index(HEADING)
    return md[start:md.index("### Coefficients", start)]


def _cp(k: int, n: int, level=0.68) -> tuple[float, float]:
    a = 0.5 * (1 - level)
    return stats.beta.ppf(a, k, n - k + 1), stats.beta.ppf(1 - a, k + 1, n - k)


def test_the_subsection_names_the_prior_model_and_bins_and_sits_before_the_long_tables(mean_run):
    run_dir, md = mean_run
    sec = _section(md)
    assert "### The prior per colour and its mean" in md
    assert md.index(HEADING) < md.index("### Coefficients, per-bin numbers and cells")
    assert "Prior model `colour_mean`" in sec and "bins -1..0.56, 0.56..1.23" in sec
    for name in ("colour_sigma_f90.png", "colour_fraction.png", "colour_mean_quasars.png"):
        assert (run_dir / "figures" / name).is_file() and f"(figures/{name})" in sec


def test_the_forms_table_is_colour_fit_forms_csv(mean_run):
    run_dir, md = mean_run
    forms = pd.read_csv(run_dir / "colour_fit_forms.csv")
    table = _table(_section(md), "form").set_index("form")
    assert list(table.index) == list(dict.fromkeys(forms["form"]))
    for r in forms.itertuples(index=False):
        shown = table.loc[r.form, r.colour_bin]
        assert shown == ("–" if not np.isfinite(r.rms_dex) else f"{r.rms_dex:.3f}"), (r.form, r.colour_bin)
        assert int(table.loc[r.form, "n parameters"]) == r.n_parameters
    total = forms[forms["colour_bin"] == "all"].set_index("form")["rms_dex"]
    assert (f"Over all the colour cells its RMS is {total['per_bin_g']:.3f} dex" in md
            and f"against {total['colour_blind']:.3f} dex about the colour-blind surface" in md)


def test_the_fraction_table_recomputes_from_f90_colour_cells(mean_run):
    run_dir, md = mean_run
    cells = pd.read_csv(run_dir / "f90_colour_cells.csv")
    ok = cells[cells["f90_flag"] == "ok"]
    table = _table(_section(md), "BP-RP")
    assert len(table) == ok.groupby(["bp_rp_min", "g_min"]).ngroups
    for row in table.itertuples(index=False):
        lo, hi = (float(x) for x in row[0].split(".."))
        g0 = float(row[1].split("-")[0])
        grp = ok[(ok["bp_rp_min"] == lo) & (ok["bp_rp_max"] == hi) & (ok["g_min"] == g0)]
        assert int(row[2]) == len(grp)
        for col, name in (("fraction_at_fitted", "fitted"), ("fraction_at_colour_blind", "colour-blind")):
            v = 100 * grp[col]
            got = dict(zip(table.columns, row))
            assert got[f"{name} median"] == f"{v.median():.1f}"
            assert got[f"{name} min-max"] == f"{v.min():.1f}-{v.max():.1f}"
            assert got[f"{name} in 88-92 %"] == f"{int(v.between(88, 92).sum())} of {len(v)}"


def test_the_extreme_cell_is_quoted_with_its_clopper_pearson_interval(mean_run):
    run_dir, md = mean_run
    cells = pd.read_csv(run_dir / "f90_colour_cells.csv")
    ok = cells[(cells["f90_flag"] == "ok") & cells["fraction_at_fitted"].notna()]
    low = ok.loc[ok["fraction_at_fitted"].idxmin()]
    lo, hi = _cp(int(round(low["fraction_at_fitted"] * N_VALID)), N_VALID)
    assert (f"Lowest at the fitted width {100 * low['fraction_at_fitted']:.1f} [{100 * lo:.1f}-{100 * hi:.1f}] % "
            f"(BP-RP {low['bp_rp_min']:g}..{low['bp_rp_max']:g}, G {low['g_min']:g}-{low['g_max']:g}") in md
    n_band = int(ok["fraction_at_fitted"].between(0.88, 0.92).sum())
    assert f"At the fitted width of their BP-RP bin {n_band} of {len(ok)} colour cells" in md


def test_the_mean_table_recomputes_from_the_cells_at_sigma_f90(mean_run):
    run_dir, md = mean_run
    parquet = pd.read_parquet(run_dir / "cells.parquet")
    at = parquet[parquet["at_f90"] & (parquet["case"] == "two")].set_index("cell_id")
    colour = pd.read_csv(run_dir / "f90_colour_cells.csv")
    blind = pd.read_csv(run_dir / "f90_cells.csv")
    cells = pd.concat([colour, blind[blind["bp_rp_min"].isna()]])
    cells = cells[cells["f90_flag"] == "ok"]
    table = _table(_section(md)[_section(md).index("| BP-RP | G | cells | stars p90"):], "BP-RP")
    assert len(table) == cells.groupby(["bp_rp_min", "g_min"], dropna=False).ngroups
    for row in table.to_dict("records"):
        g0 = float(row["G"].split("-")[0])
        if row["BP-RP"] == "colour-blind":
            grp = cells[cells["bp_rp_min"].isna() & (cells["g_min"] == g0)]
        else:
            lo = float(row["BP-RP"].split("..")[0])
            grp = cells[(cells["bp_rp_min"] == lo) & (cells["g_min"] == g0)]
        star = at.loc[grp["cell_id"], "p_error_mas"]
        assert row["stars p90 [mas]"] == format(star.median(), ".3g")
        assert row["quasars inside [%]"] == f"{100 * grp['quasar_fraction_inside'].median():.1f}"
        assert row["quasars p90 [mas]"] == format(grp["quasar_p_error_mas"].median(), ".3g")
        ratio = grp["quasar_p_error_mas"].to_numpy() / star.to_numpy()
        assert row["quasars / stars p90"] == f"{np.median(ratio):.2f}"


def test_the_quasar_sentence_quotes_the_runs_numbers(mean_run):
    run_dir, md = mean_run
    colour = pd.read_csv(run_dir / "f90_colour_cells.csv")
    q = colour[colour["f90_flag"] == "ok"]
    frac = q["quasar_fraction_inside"]
    k = np.rint(frac * q["quasar_n_valid"]).sum()
    lo, hi = _cp(int(k), int(q["quasar_n_valid"].sum()))
    assert "Zero-truth sources (quasars" in md
    assert (f"{int((frac < 0.88).sum())} of {len(q)} colour cells keep fewer than 88 % of them inside (median "
            f"{100 * frac.median():.1f} %, pooled {100 * k / q['quasar_n_valid'].sum():.1f} "
            f"[{100 * lo:.1f}-{100 * hi:.1f}] %") in md
    low = q.loc[frac.idxmin()]
    lo, hi = _cp(int(round(low["quasar_fraction_inside"] * N_VALID)), N_VALID)
    assert f"lowest {100 * low['quasar_fraction_inside']:.1f} [{100 * lo:.1f}-{100 * hi:.1f}] %" in md


def test_a_colour_run_without_a_mean_has_no_quasar_part(tmp_path):
    md = _report(tmp_path / "run", _cells(mean=False), {"name": "colour", "colour_edges": [-1.0, 0.56, 1.23],
                                                        "mean": False})
    sec = _section(md)
    assert sec.startswith("### The prior per colour\n") and "Prior model `colour`" in sec
    assert "Zero-truth" not in md and not (tmp_path / "run" / "figures" / "colour_mean_quasars.png").exists()


def test_a_default_run_has_no_colour_subsection(tmp_path):
    md = _report(tmp_path / "run", _cells(colour_axis=False, mean=False), {"name": "direction_g",
                                                                          "colour_edges": [], "mean": False})
    assert HEADING not in md and "BP-RP" not in md
    assert not list((tmp_path / "run" / "figures").glob("colour_*"))
    assert not re.search(r"quasar", md, re.I)


def test_the_fit_of_the_rows_it_reads_is_the_fit_of_the_whole_table(tmp_path):
    # The sweep's aggregate fits only the rows write_fit uses (runner.fit_rows); every file
    # must be the one the whole cells.parquet gives.
    import filecmp
    import io

    from astropy.io import fits

    from mcsweep.experiments.f90_sweep.runner import fit_rows

    cells = _cells()
    _report(tmp_path / "whole", cells, {"name": "colour_mean", "colour_edges": [-1.0, 0.56, 1.23], "mean": True})
    part = tmp_path / "part"
    part.mkdir()
    (part / "provenance.json").write_bytes((tmp_path / "whole" / "provenance.json").read_bytes())
    buf = io.BytesIO()
    cells.to_parquet(buf, index=False)
    rows = fit_rows(buf.getvalue(), "two")
    assert len(rows) < len(cells)
    write_fit(part, rows, nside=1, f90_case="two")
    written = sorted(p.name for p in part.iterdir() if p.name != "provenance.json")
    assert "f90_colour_cells.csv" in written and "prior_maps.fits" in written
    for name in written:
        if name.endswith(".fits"):  # the same maps; the header names the run directory (PRIORSRC)
            diff = fits.FITSDiff(str(part / name), str(tmp_path / "whole" / name), ignore_keywords=["PRIORSRC"])
            assert diff.identical, diff.report()
        else:
            assert filecmp.cmp(part / name, tmp_path / "whole" / name, shallow=False), name
