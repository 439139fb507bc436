"""Sphinx configuration of mcsweep's documentation site.

Built offline, warnings as errors:

    sphinx-build -W --keep-going -n -b html docs docs/_build/html

Nothing here reaches the network: no intersphinx, the theme's assets are bundled with it,
and the examples (``examples/*.py``, run by sphinx-gallery) work on built-in data only.
"""

import os
from pathlib import Path

import mcsweep

os.environ.setdefault("MPLBACKEND", "Agg")
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

DOCS = Path(__file__).resolve().parent

project = "mcsweep"
author = "the mcsweep authors"
copyright = "the mcsweep authors"
release = mcsweep.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    # MathJax 3 bundled and copied into the site: the paper's equations render offline
    # (Sphinx's default loads MathJax from a CDN).
    "sphinx-mathjax-offline",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = [
    "_build",
    "scripts",
    "auto_examples/*.ipynb",
    "auto_examples/*.py",
    "auto_examples/*.zip",
    "auto_examples/*.json",
    "auto_examples/*.md5",
    "auto_examples/*.codeobj.json",
    "sg_execution_times.rst",
    # a recorded run's figure with its provenance, included by the experiment pages
    # (docs/scripts/results_figures.py), not a page of its own
    "experiments/figures/*.md",
]

# MyST: anchors for headings down to level 3 so pages can link to a section of another.
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "dollarmath"]

# autodoc + napoleon: the docstrings are numpydoc with Sphinx roles.
autodoc_member_order = "bysource"
# The numpydoc sections carry the types; annotations in signatures or fields would become
# references to private classes.
autodoc_typehints = "none"
# Members are listed by name in api/index.rst: the public API only.
autodoc_default_options = {"show-inheritance": False}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_param = False
napoleon_use_keyword = False
# "Attributes" rendered like "Parameters" (a field list): as attribute directives they would
# duplicate a dataclass's own fields and turn "ndarray, shape (n, 5)" into references.
napoleon_custom_sections = [("Attributes", "params_style")]
# Parameter types stay text ("array, shape (n, 5)", "float, keyword-only"): as references
# they would not resolve, and the names a reader should follow are linked in the prose.
napoleon_preprocess_types = False

# Every cross-reference must resolve (sphinx-build -n). Objects of the packages mcsweep
# builds on cannot resolve: resolving them would need their intersphinx inventories,
# fetched over the network at build time, and the build is offline. These patterns cover
# those external packages only; a broken reference to an mcsweep name still fails.
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|scipy|pandas|pd|astropy|u|healpy|matplotlib|pyarrow)(\..*)?"),
    (r"py:.*", r"(ndarray|array_like|array-like|DataFrame|Series|Quantity|SkyCoord|Time|Table|Generator|Path)"),
    (r"py:.*", r"(optional|default.*|callable|iterable|sequence|mapping|scalar|path-like|os\.PathLike)"),
    (r"py:.*", r"(int|float|str|bool|dict|list|tuple|bytes|None|object|type)"),
]

# sphinx-gallery: every examples/*.py runs at build time; a failing example fails the build.
sphinx_gallery_conf = {
    "examples_dirs": str(DOCS.parent / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"\.py$",
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "download_all_examples": False,
    "remove_config_comments": True,
    # its execution-times page loads jQuery and DataTables from CDNs: the site stays offline
    "write_computation_times": False,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "show_memory": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"mcsweep {release}"
html_theme_options = {
    "navigation_depth": 3,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_static_path = ["_static"]
# code spans in table cells wrap (wide tables of measurements fit the column)
html_css_files = ["mcsweep.css"]


def require_docstrings(app, what, name, obj, options, lines):
    """A public name documented without a docstring fails the build (with ``-W``)."""
    if what in {"function", "method", "class", "property", "classmethod", "staticmethod", "module"}:
        if not any(line.strip() for line in lines):
            from sphinx.util import logging

            logging.getLogger(__name__).warning(
                "public name without a docstring: %s (%s)", name, what, type="mcsweep", subtype="docstring")


#: numpydoc's validation (numpydoc.readthedocs.io, "Validation") of every function, method and
#: class of the API reference: its parameters documented with a type and a description, the
#: Returns (or Yields) section and an Examples section (run as tests:
#: tests/packaging/test_docstring_examples.py). See Also is not required.
NUMPYDOC_CHECKS = ("PR01", "PR02", "PR03", "PR04", "PR06", "PR07", "PR10", "RT01", "RT03", "YD01", "GL08", "EX01")


def validate_numpydoc(app, what, name, obj, options, lines):
    """A public function, method or class whose docstring fails a check of
    :data:`NUMPYDOC_CHECKS` fails the build (with ``-W``)."""
    if what not in {"function", "method", "class", "exception", "classmethod", "staticmethod"}:
        return
    if what == "class" and getattr(obj, "_is_protocol", False):
        return  # a typing.Protocol is never instantiated: its methods are checked, not its signature
    from numpydoc.validate import validate
    from sphinx.util import logging

    for code, message in validate(name)["errors"]:
        if code in NUMPYDOC_CHECKS:
            logging.getLogger(__name__).warning("%s: numpydoc %s: %s", name, code, message, type="mcsweep",
                                                subtype="numpydoc")


def citation_bibtex(cff_path: Path, commit: str) -> str:
    """BibTeX of the paper (CITATION.cff's preferred citation) and of mcsweep (its title,
    version and licence, and the commit the site was built from)."""
    import yaml

    cff = yaml.safe_load(cff_path.read_text())
    paper = cff["preferred-citation"]
    authors = " and ".join(f"{a['family-names']}, {a['given-names']}" for a in paper["authors"])
    return (f"@article{{{paper['authors'][0]['family-names']}{paper['year']},\n"
            f"  author  = {{{authors}}},\n  title   = {{{paper['title']}}},\n"
            f"  journal = {{{paper['journal']}}},\n  year    = {{{paper['year']}}},\n"
            f"  volume  = {{{paper['volume']}}},\n  pages   = {{{paper['start']}}},\n"
            f"  doi     = {{{paper['doi']}}}\n}}\n\n"
            f"@software{{mcsweep,\n  author  = {{{{{cff['authors'][0]['name']}}}}},\n"
            f"  title   = {{{cff['title']}}},\n  version = {{{cff['version']}}},\n"
            f"  note    = {{commit {commit}; licence {cff['license']}}}\n}}\n")


def write_citation(app):
    """docs/citation.bib from CITATION.cff, for the citing page (a build product, not in git)."""
    import subprocess

    try:
        commit = subprocess.run(["git", "-C", str(DOCS), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown (not built from a git checkout)"
    (DOCS / "citation.bib").write_text(citation_bibtex(DOCS.parent / "CITATION.cff", commit))


def setup(app):
    app.connect("builder-inited", write_citation)
    app.connect("autodoc-process-docstring", require_docstrings)
    app.connect("autodoc-process-docstring", validate_numpydoc)
