"""docs/scripts/check_site.py: what the site's build lets through is caught (and what is
right is not)."""

import importlib.util
from pathlib import Path

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
