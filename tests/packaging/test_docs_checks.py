"""docs/scripts/check_site.py: what the site's build lets through is caught (and what is
right is not)."""

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _module():
    spec = importlib.util.spec_from_file_location("check_site", ROOT / "docs" / "scripts" / "check_site.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_a_pipe_that_splits_a_row_is_caught(tmp_path, monkeypatch):
    check = _module()
    monkeypatch.setattr(check, "DOCS", tmp_path)
    page = tmp_path / "page.md"
    page.write_text("| a | b |\n|---|---|\n| stars in three |b| bands | 1 |\n| `x|y` | escaped \\| pipe |\n\n"
                    "```\n| not | a | table |\n```\n")
    problems = check.table_problems(page)
    assert len(problems) == 1 and "page.md:3: 4 cells" in problems[0]


def test_raw_roles_and_network_loads_are_caught(tmp_path):
    check = _module()
    site = tmp_path / "site"
    site.mkdir()
    (site / "ok.html").write_text('<script src="_static/mathjax/tex-chtml.js"></script><p><code>x</code></p>')
    (site / "bad.html").write_text('<p>see :func:<code>f</code></p>'
                                   '<script src="https://cdn.example.org/x.js"></script>')
    out = [check.RAW_ROLE.findall((site / n).read_text()) + check.REMOTE.findall((site / n).read_text())
           for n in ("ok.html", "bad.html")]
    assert out[0] == [] and len(out[1]) == 2


def test_a_code_line_wider_than_the_column_is_caught_on_users_pages_only(tmp_path, monkeypatch):
    check = _module()
    monkeypatch.setattr(check, "DOCS", tmp_path / "no_sources")
    site = tmp_path / "site"
    for page in ("guide/running.html", "api/prior.html", "notes/table3/log.html"):
        (site / page).parent.mkdir(parents=True, exist_ok=True)
    wide = "<pre><span>mcsweep</span> " + "x" * (check.CODE_COLUMN - 7) + "</pre>"
    fits = "<pre>mcsweep &amp;&amp; " + "x" * (check.CODE_COLUMN - 20) + "</pre>"
    (site / "guide/running.html").write_text(wide + fits)
    (site / "api/prior.html").write_text(fits)
    (site / "notes/table3/log.html").write_text(wide)  # research notes may hold wide logs
    problems = check.wide_code("guide/running.html", (site / "guide/running.html").read_text())
    assert len(problems) == 1 and f"{check.CODE_COLUMN + 1} characters" in problems[0]
    assert check.main([str(site)]) == 1
    (site / "guide/running.html").write_text(fits)
    assert check.main([str(site)]) == 0


def _conf():
    spec = importlib.util.spec_from_file_location("docs_conf", ROOT / "docs" / "conf.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_numpydoc_validation_warns_on_an_undocumented_parameter(tmp_path, monkeypatch, caplog):
    pytest.importorskip("numpydoc")
    conf = _conf()
    (tmp_path / "planted.py").write_text(
        'def documented(x):\n    """Double it.\n\n    Parameters\n    ----------\n    x : float\n'
        '        A number.\n\n    Returns\n    -------\n    float\n        Twice ``x``.\n\n'
        '    Examples\n    --------\n    >>> documented(1.0)\n    2.0\n    """\n    return 2 * x\n\n\n'
        'def planted(x, y):\n    """Add them.\n\n    Parameters\n    ----------\n    x : float\n'
        '        A number.\n    """\n    return x + y\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    with caplog.at_level("WARNING"):
        conf.validate_numpydoc(None, "function", "planted.documented", None, None, [])
        assert not caplog.records
        conf.validate_numpydoc(None, "function", "planted.planted", None, None, [])
    codes = {r.getMessage().split("numpydoc ")[1][:4] for r in caplog.records}
    assert {"PR01", "RT01", "EX01"} <= codes


def test_the_sites_bibtex_is_made_from_citation_cff_with_the_packages_version():
    import mcsweep

    conf = _conf()
    bib = conf.citation_bibtex(ROOT / "CITATION.cff", "abc1234")
    assert "doi     = {10.1051/0004-6361/201526936}" in bib and "pages   = {A68}" in bib
    assert f"version = {{{mcsweep.__version__}}}" in bib and "commit abc1234" in bib
