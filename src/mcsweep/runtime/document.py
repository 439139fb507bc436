"""A small document model rendered to both Markdown and standalone HTML.

The report is built once as a list of blocks (headings, paragraphs, bullet lists,
tables, figures and rows of figures, preformatted text) and rendered twice, so
``report.md`` and ``report.html`` always say the same thing. Text may mark inline code
with Markdown backticks; the HTML renders it as ``<code>``. Table cells and values
passed through :func:`plain` read as a person writes them: yes/no for booleans,
"ok 670, no_crossing 2" for a dict of counts, no Python or numpy reprs.
"""

from __future__ import annotations

import html
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["Document", "FIG_DIR", "plain", "counts_text", "save_png"]

#: Sub-directory of a run directory holding the report's figures (paths in the document are relative).
FIG_DIR = "figures"

_CODE = re.compile(r"`([^`\n]+)`")


def save_png(fig, path: Path, *, trim: bool = False) -> Path:
    """Write a matplotlib figure as PNG atomically and close it: laid out tight, or with
    ``trim`` cut to its drawn extent (for colour bars placed outside the axes grid)."""
    import io

    import matplotlib.pyplot as plt

    from .store import atomic_write_bytes

    buf = io.BytesIO()
    if trim:
        fig.savefig(buf, dpi=110, format="png", bbox_inches="tight")
    else:
        fig.tight_layout()
        fig.savefig(buf, dpi=110, format="png")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return path


def plain(v, float_format: str = ".4g") -> str:
    """``v`` as a person would write it in text or a table cell.

    Booleans become yes/no, NaN an en dash, numpy scalars their Python value, dicts
    "key: value" pairs and sequences comma-separated lists (recursively), so no
    ``True``, ``{'ok': 3}`` or ``np.float64(...)`` reaches a reader.
    """
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "–" if v != v else format(float(v), float_format)
    if isinstance(v, Mapping):
        return "; ".join(f"{k}: {plain(x, float_format)}" for k, x in v.items())
    if isinstance(v, (list, tuple, np.ndarray, pd.Series)):
        return ", ".join(plain(x, float_format) for x in (v.tolist() if hasattr(v, "tolist") else v))
    if v is None:
        return "–"
    return str(v)


def counts_text(counts: Mapping, noun: str) -> str:
    """A dict of counts per label as a phrase: "all 672 cells ok" when there is one label,
    else "670 ok, 2 no_crossing" (largest first)."""
    items = sorted(((str(k), int(n)) for k, n in counts.items() if int(n)), key=lambda kv: (-kv[1], kv[0]))
    if not items:
        return f"no {noun}"
    if len(items) == 1:
        label, n = items[0]
        return f"all {n} {noun} {label}" if n != 1 else f"the 1 {noun.removesuffix('s')} {label}"
    return ", ".join(f"{n} {label}" for label, n in items)


def _inline_html(text: str) -> str:
    """Escape ``text`` for HTML, with `backticked` spans as <code> (escaped inside too)."""
    out, pos = [], 0
    for m in _CODE.finditer(text):
        out.append(html.escape(text[pos:m.start()]))
        out.append(f"<code>{html.escape(m.group(1))}</code>")
        pos = m.end()
    out.append(html.escape(text[pos:]))
    return "".join(out)


def _no_ticks(text: str) -> str:
    """Text for places that hold no markup (alt attributes, the title element)."""
    return _CODE.sub(r"\1", text)


@dataclass
class Document:
    title: str
    blocks: list = field(default_factory=list)
    #: Where :meth:`draw` runs figure calls (a :class:`~mcsweep.runtime.drawing.FigureDrawer`);
    #: None: in line.
    drawer: object = None

    def draw(self, fn, *args, **kwargs) -> None:
        """Draw a figure file with ``fn(*args, **kwargs)``, in line or by :attr:`drawer`; the
        document's :meth:`write` waits for it."""
        if self.drawer is None:
            fn(*args, **kwargs)
        else:
            self.drawer.draw(fn, *args, **kwargs)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("h", level, text))

    def para(self, text: str) -> None:
        self.blocks.append(("p", text))

    def bullets(self, items: list[str]) -> None:
        self.blocks.append(("ul", list(items)))

    def table(self, df: pd.DataFrame, caption: str | None = None, floatfmt: dict | None = None) -> None:
        df = df.copy()
        for col, fmt in (floatfmt or {}).items():
            if col in df:
                df[col] = [plain(x, fmt) if isinstance(x, (float, np.floating)) else x for x in df[col]]
        self.blocks.append(("t", df, caption))

    def figure(self, path: str, caption: str) -> None:
        self.blocks.append(("f", path, caption))

    def figure_row(self, figures: list[tuple[str, str]]) -> None:
        """Figures meant to be seen together (side by side in the HTML); (path, caption) each."""
        self.blocks.append(("fr", list(figures)))

    def pre(self, text: str) -> None:
        self.blocks.append(("pre", text))

    def to_markdown(self) -> str:
        out = [f"# {self.title}", ""]
        for b in self.blocks:
            if b[0] == "h":
                out += ["#" * b[1] + " " + b[2], ""]
            elif b[0] == "p":
                out += [b[1], ""]
            elif b[0] == "ul":
                out += [f"- {item}" for item in b[1]] + [""]
            elif b[0] == "t":
                df, caption = b[1], b[2]
                if caption:
                    out += [f"*{caption}*", ""]
                cols = list(map(str, df.columns))
                out.append("| " + " | ".join(cols) + " |")
                out.append("|" + "|".join("---" for _ in cols) + "|")
                for row in df.itertuples(index=False):
                    out.append("| " + " | ".join(plain(v) for v in row) + " |")
                out.append("")
            elif b[0] in ("f", "fr"):
                for path, caption in ([b[1:]] if b[0] == "f" else b[1]):
                    out += [f"![{_no_ticks(caption)}]({path})", "", f"*{caption}*", ""]
            elif b[0] == "pre":
                out += ["```", b[1], "```", ""]
        return "\n".join(out)

    def to_html(self) -> str:
        e, t = html.escape, _inline_html

        def fig(path: str, caption: str) -> str:
            # The image links to itself: panels in a row are small, the file is full size.
            return (f'<figure><a href="{e(path)}"><img src="{e(path)}" alt="{e(_no_ticks(caption))}"></a>'
                    f"<figcaption>{t(caption)}</figcaption></figure>")

        body = [f"<h1>{t(self.title)}</h1>"]
        for b in self.blocks:
            if b[0] == "h":
                body.append(f"<h{b[1]}>{t(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                body.append(f"<p>{t(b[1])}</p>")
            elif b[0] == "ul":
                body.append("<ul>" + "".join(f"<li>{t(item)}</li>" for item in b[1]) + "</ul>")
            elif b[0] == "t":
                df, caption = b[1], b[2]
                rows = ["<table>"]
                if caption:
                    rows.append(f"<caption>{t(caption)}</caption>")
                rows.append("<tr>" + "".join(f"<th>{t(str(c))}</th>" for c in df.columns) + "</tr>")
                for row in df.itertuples(index=False):
                    rows.append("<tr>" + "".join(f"<td>{t(plain(v))}</td>" for v in row) + "</tr>")
                rows.append("</table>")
                body.append("\n".join(rows))
            elif b[0] == "f":
                body.append(fig(b[1], b[2]))
            elif b[0] == "fr":
                body.append('<div class="row">' + "".join(fig(p, c) for p, c in b[1]) + "</div>")
            elif b[0] == "pre":
                body.append(f"<pre>{e(b[1])}</pre>")
        # A row shares the width equally, so a first screen holds a whole row of panels.
        style = ("body{font-family:sans-serif;max-width:72em;margin:auto;padding:1em}"
                 "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:2px 6px;"
                 "text-align:right}img{max-width:100%}caption,figcaption{font-style:italic}"
                 "figure{margin:0.5em 0}.row{display:flex;gap:1em;align-items:flex-start}"
                 ".row figure{flex:1 1 0;min-width:0}code{background:#f2f2f2;padding:0 2px}")
        return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{e(_no_ticks(self.title))}</title>"
                f"<style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")

    def write(self, directory: Path, stem: str = "report") -> tuple[Path, Path]:
        from .store import atomic_write_bytes

        if self.drawer is not None:
            self.drawer.wait()  # the figures the text refers to exist before it is written
        md, ht = Path(directory) / f"{stem}.md", Path(directory) / f"{stem}.html"
        atomic_write_bytes(md, self.to_markdown().encode())
        atomic_write_bytes(ht, self.to_html().encode())
        return md, ht
