"""A small document model rendered to both Markdown and standalone HTML.

The report is built once as a list of blocks (headings, paragraphs, tables, figures,
preformatted text) and rendered twice, so ``report.md`` and ``report.html`` always
say the same thing.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

__all__ = ["Document", "FIG_DIR"]

#: Sub-directory of a run directory holding the report's figures (paths in the document are relative).
FIG_DIR = "figures"


def _fmt(v) -> str:
    if isinstance(v, float):
        if v != v:  # NaN
            return "–"
        return f"{v:.4g}"
    return str(v)


@dataclass
class Document:
    title: str
    blocks: list = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("h", level, text))

    def para(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, df: pd.DataFrame, caption: str | None = None, floatfmt: dict | None = None) -> None:
        df = df.copy()
        for col, fmt in (floatfmt or {}).items():
            if col in df:
                df[col] = [("–" if x != x else format(x, fmt)) if isinstance(x, float) else x for x in df[col]]
        self.blocks.append(("t", df, caption))

    def figure(self, path: str, caption: str) -> None:
        self.blocks.append(("f", path, caption))

    def pre(self, text: str) -> None:
        self.blocks.append(("pre", text))

    def to_markdown(self) -> str:
        out = [f"# {self.title}", ""]
        for b in self.blocks:
            if b[0] == "h":
                out += ["#" * b[1] + " " + b[2], ""]
            elif b[0] == "p":
                out += [b[1], ""]
            elif b[0] == "t":
                df, caption = b[1], b[2]
                if caption:
                    out += [f"*{caption}*", ""]
                cols = list(map(str, df.columns))
                out.append("| " + " | ".join(cols) + " |")
                out.append("|" + "|".join("---" for _ in cols) + "|")
                for row in df.itertuples(index=False):
                    out.append("| " + " | ".join(_fmt(v) for v in row) + " |")
                out.append("")
            elif b[0] == "f":
                out += [f"![{b[2]}]({b[1]})", "", f"*{b[2]}*", ""]
            elif b[0] == "pre":
                out += ["```", b[1], "```", ""]
        return "\n".join(out)

    def to_html(self) -> str:
        e = html.escape
        body = [f"<h1>{e(self.title)}</h1>"]
        for b in self.blocks:
            if b[0] == "h":
                body.append(f"<h{b[1]}>{e(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                body.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "t":
                df, caption = b[1], b[2]
                rows = ["<table>"]
                if caption:
                    rows.append(f"<caption>{e(caption)}</caption>")
                rows.append("<tr>" + "".join(f"<th>{e(str(c))}</th>" for c in df.columns) + "</tr>")
                for row in df.itertuples(index=False):
                    rows.append("<tr>" + "".join(f"<td>{e(_fmt(v))}</td>" for v in row) + "</tr>")
                rows.append("</table>")
                body.append("\n".join(rows))
            elif b[0] == "f":
                body.append(f'<figure><img src="{e(b[1])}" alt="{e(b[2])}">'
                            f"<figcaption>{e(b[2])}</figcaption></figure>")
            elif b[0] == "pre":
                body.append(f"<pre>{e(b[1])}</pre>")
        style = ("body{font-family:sans-serif;max-width:60em;margin:auto;padding:1em}"
                 "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:2px 6px;"
                 "text-align:right}img{max-width:100%}caption,figcaption{font-style:italic}")
        return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{e(self.title)}</title>"
                f"<style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")

    def write(self, directory: Path, stem: str = "report") -> tuple[Path, Path]:
        from ..sweep.store import atomic_write_bytes

        md, ht = Path(directory) / f"{stem}.md", Path(directory) / f"{stem}.html"
        atomic_write_bytes(md, self.to_markdown().encode())
        atomic_write_bytes(ht, self.to_html().encode())
        return md, ht
