"""The report as a person reads it: headline before the long tables, no Python reprs,
inline code rendered, key numbers that match the run's own result files."""

import html
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mcsweep.runtime.document import Document, counts_text

BIN = Path(sys.executable).parent
#: The smallest run that still fits Eqs. 15-17 (s1 is cubic: 4 G bins) with bootstrap
#: intervals, and writes the showcase beam.
TINY = [
    "sky=custom", "sky.directions=[[245.7,46.5],[30,-20],[120,5],[300,60]]",
    "magnitudes.edges=[12,14,16,18,20]", "prior_grid.n=9",
    "cell.max_stars=100", "cell.min_stars=50", "execution.progress=false", "execution.n_jobs=1",
]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "sweep"
    r = subprocess.run([str(BIN / "mcsweep"), f"hydra.run.dir={out}", *TINY], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def _visible_text(page: str) -> str:
    """What a browser shows outside preformatted blocks (the config JSON is meant literally)."""
    page = re.sub(r"<pre>.*?</pre>", "", page, flags=re.S)
    page = re.sub(r"<(style|title)>.*?</\1>", "", page, flags=re.S)
    return html.unescape(re.sub(r"<[^>]+>", " ", page))


@pytest.mark.slow
def test_headline_figures_and_numbers_come_before_the_first_table(tiny_run):
    md = (tiny_run / "report.md").read_text()
    page = (tiny_run / "report.html").read_text()
    first_table_md = re.search(r"^\| ", md, flags=re.M).start()
    assert md.index("![") < first_table_md
    assert md.index("](figures/fig4_") < first_table_md and re.search(r"^- ", md, flags=re.M).start() < first_table_md
    assert page.index("<img") < page.index("<ul>") < page.index("<table>")
    assert 'src="figures/fig4_latitude.png"' in page[:page.index("<table>")]
    if (tiny_run / "figures" / "prior_maps.png").exists():
        assert 'src="figures/prior_maps.png"' in page[:page.index("<table>")]


@pytest.mark.slow
def test_html_text_has_no_python_reprs_or_raw_backticks(tiny_run):
    text = _visible_text((tiny_run / "report.html").read_text())
    for bad in ("{'", "'}", "True", "False", "`", "np.", "array("):
        assert bad not in text, (bad, text[max(0, text.find(bad) - 100):text.find(bad) + 100])
    assert not re.search(r"\bnan\b", text, flags=re.I)
    md = (tiny_run / "report.md").read_text()
    md = re.sub(r"```.*?```", "", md, flags=re.S)
    for bad in ("{'", "True", "False", "np."):
        assert bad not in md, bad
    # The cells' outcomes as counts, from the run's own per-cell table.
    flags = pd.read_csv(tiny_run / "f90_cells.csv")["f90_flag"].value_counts()
    phrase = (f"all {flags.iloc[0]} cells {flags.index[0]}" if len(flags) == 1
              else f"{flags.iloc[0]} {flags.index[0]}")
    assert phrase in text


@pytest.mark.slow
def test_inline_code_in_the_report_renders_as_code(tiny_run):
    md = (tiny_run / "report.md").read_text()
    page = (tiny_run / "report.html").read_text()
    spans = set(re.findall(r"`([^`\n]+)`", re.sub(r"```.*?```", "", md, flags=re.S)))
    assert spans, "the report names no setting or file in code"
    for span in spans:
        assert f"<code>{html.escape(span)}</code>" in page, span


@pytest.mark.slow
def test_key_numbers_quote_the_coefficients_and_intervals_of_coefficients_csv(tiny_run):
    coef = pd.read_csv(tiny_run / "coefficients.csv").set_index("term")
    md = (tiny_run / "report.md").read_text()
    headline = md[:re.search(r"^\| ", md, flags=re.M).start()]
    for name in ("s0", "s1", "s2"):
        line = next(ln for ln in headline.splitlines() if ln.startswith(f"- {name} "))
        quoted = re.findall(r"c(\d) (\S+) \[(\S+), (\S+)\] \(paper (\S+)\)", line)
        assert len(quoted) == int(coef.index.str.startswith(f"{name}_").sum()), line
        for power, value, lo, hi, paper in quoted:
            row = coef.loc[f"{name}_c{power}"]
            # Printed to the decimals of the interval: agree to half a unit of the last one.
            tol = 0.5 * 10.0 ** -len(lo.split(".")[1]) if "." in lo else 0.5
            for printed, exact in ((value, row["fitted"]), (lo, row["fitted_lo"]), (hi, row["fitted_hi"])):
                assert abs(float(printed) - exact) <= tol * (1 + 1e-9), (name, power, printed, exact)
            assert float(paper) == pytest.approx(row["paper"], rel=1e-3)


@pytest.mark.slow
def test_the_difference_sentence_names_the_g_bin_that_differs_most(tiny_run):
    cells = pd.read_csv(tiny_run / "f90_cells.csv")
    ok = cells[(cells["f90_flag"] == "ok") & np.isfinite(cells["diff_dex"])]
    mean = ok.groupby(["g_min", "g_max"])["diff_dex"].mean()
    (g0, g1), worst = mean.abs().idxmax(), mean.loc[mean.abs().idxmax()]
    md = (tiny_run / "report.md").read_text()
    sentence = next(ln for ln in md.splitlines() if "differs most" in ln)
    assert f"G = {g0:g}-{g1:g}, by {worst:+.3f} dex" in sentence
    assert md.index(sentence) < re.search(r"^\| ", md, flags=re.M).start()


def test_inline_code_is_escaped_and_unpaired_backticks_are_left_as_text():
    doc = Document("t")
    doc.para("compare `a<b & c` with `x`; a lone ` stays")
    page = doc.to_html()
    assert "<code>a&lt;b &amp; c</code>" in page and "<code>x</code>" in page
    assert "a lone ` stays" in page
    assert "`a<b & c`" in doc.to_markdown()


def test_booleans_dicts_and_numpy_scalars_in_tables_read_as_words():
    doc = Document("t")
    doc.table(pd.DataFrame({"term": ["a", "b"], "inside": [True, False], "n": np.array([3, 4], dtype=np.int64),
                            "x": [np.float64(0.123456), np.nan], "counts": [{"ok": 3}, {"ok": 1, "bad": 2}]}))
    md, page = doc.to_markdown(), doc.to_html()
    assert "| a | yes | 3 | 0.1235 | ok: 3 |" in md and "| b | no | 4 | – | ok: 1; bad: 2 |" in md
    assert "<td>yes</td>" in page and "<td>no</td>" in page
    assert not re.search(r"True|False|\{'|np\.", md + page)


def test_counts_read_as_a_person_writes_them():
    assert counts_text({"ok": 672}, "cells") == "all 672 cells ok"
    assert counts_text({"no_crossing": 2, "ok": 670}, "cells") == "670 ok, 2 no_crossing"


#: What the sweep writes when it aggregates its cells: the report reads them and never writes them.
SCIENCE_FILES = ("cells.parquet", "f90_cells.csv", "coefficients.csv", "rms_dex.csv", "eq14_terms.csv",
                 "prior_maps.fits")


def _state(run_dir: Path) -> dict:
    return {n: ((run_dir / n).read_bytes(), (run_dir / n).stat().st_mtime_ns) for n in SCIENCE_FILES
            if (run_dir / n).exists()}


@pytest.mark.slow
def test_rebuilding_a_finished_sweeps_report_leaves_its_science_files_untouched(tiny_run, tmp_path):
    run_dir = tmp_path / tiny_run.name  # the report names its directory
    shutil.copytree(tiny_run, run_dir)
    before = _state(run_dir)
    assert set(before) == set(SCIENCE_FILES)
    (run_dir / "report.md").unlink()
    r = subprocess.run([str(BIN / "mcsweep-report"), str(run_dir)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert _state(run_dir) == before  # same bytes, not even rewritten
    # Built from the files alone: the same science sections as the report the run wrote (the
    # provenance section now also lists the report stage's time and files).
    def science(md: str) -> str:
        return md[:md.index("\n## Provenance\n")]

    assert science((run_dir / "report.md").read_text()) == science((tiny_run / "report.md").read_text())


@pytest.mark.slow
@pytest.mark.parametrize("missing", SCIENCE_FILES[1:])
def test_a_sweep_without_a_result_file_is_refused_in_one_line_and_nothing_is_written(tiny_run, tmp_path, missing):
    from mcsweep.errors import UserInputError
    from mcsweep.report.build import build_report

    run_dir = tmp_path / tiny_run.name  # the report names its directory
    shutil.copytree(tiny_run, run_dir)
    (run_dir / missing).unlink()
    listing = {p.relative_to(run_dir).as_posix(): p.stat().st_mtime_ns for p in run_dir.rglob("*")}
    with pytest.raises(UserInputError, match=missing.replace(".", r"\.")):
        build_report(run_dir)
    if missing == "coefficients.csv":  # and the command says so in one line, exit status 2
        r = subprocess.run([str(BIN / "mcsweep-report"), str(run_dir)], capture_output=True, text=True,
                           timeout=300)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 2 and len(lines) == 1 and missing in lines[0], r.stderr[-2000:]
    assert not (run_dir / missing).exists()
    assert {p.relative_to(run_dir).as_posix(): p.stat().st_mtime_ns for p in run_dir.rglob("*")} == listing
