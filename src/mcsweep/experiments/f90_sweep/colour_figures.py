"""Figures of the report's colour subsection (PNG): sigma_F90 per Gaia BP-RP bin against G
(the per-colour analogue of Fig. 4 right), the fraction inside at the fitted widths, and
for a mean-centred prior the position errors of stars and of zero-truth sources (quasars).

Every function takes the summaries :func:`.colour_section.bin_stats` made (columns
``colour, g, n, median, p16, p84, min, max``); the colour-blind cells are drawn in black.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.colors import LinearSegmentedColormap  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from ...runtime.document import save_png  # noqa: E402

__all__ = ["bin_colours", "plot_sigma_by_colour", "plot_fraction_by_colour", "plot_mean_errors"]

#: Label of the colour-blind cells (as :data:`.colour_section.COLOUR_BLIND`).
_BLIND = "colour-blind"
#: Blue to red through teal and orange: every bin's colour dark enough to read on white.
_BLUE_TO_RED = LinearSegmentedColormap.from_list("bp_rp", ["#1f4e9c", "#1b9e77", "#e08214", "#b2182b"])


def bin_colours(labels) -> dict:
    """A colour per BP-RP label, blue to red in the order of the bins; black for the colour-blind cells."""
    bins = [lab for lab in dict.fromkeys(labels) if lab != _BLIND]
    out = {lab: _BLUE_TO_RED(i / max(len(bins) - 1, 1)) for i, lab in enumerate(bins)}
    return out | {_BLIND: "k"}


def _errorbars(ax, s: pd.DataFrame, lo: str, hi: str, color, scale: float = 1.0, **kw) -> None:
    """Medians of one label with bars from column ``lo`` to ``hi``, joined by a line."""
    s = s[np.isfinite(s["median"].astype(float))]
    if s.empty:
        return
    y = scale * s["median"].to_numpy(float)
    yerr = np.vstack([np.clip(y - scale * s[lo].to_numpy(float), 0, None),
                      np.clip(scale * s[hi].to_numpy(float) - y, 0, None)])
    ax.errorbar(s["g"].to_numpy(float) + kw.pop("dx", 0.0), y, yerr=yerr, color=color, capsize=2, ms=4, **kw)


def plot_sigma_by_colour(stats: pd.DataFrame, curves: pd.DataFrame, path: Path) -> Path:
    """sigma_F90 against G per BP-RP bin: medians over the directions with their 16-84 %
    spread, and each bin's fitted surface (median over the same directions) as a line."""
    colours = bin_colours(stats["colour"])
    fig, ax = plt.subplots(figsize=(6.5, 5))
    width = float(np.median(np.diff(np.unique(stats["g"])))) if stats["g"].nunique() > 1 else 1.0
    offsets = np.linspace(-0.15, 0.15, max(len(colours), 1)) * width
    for (lab, color), dx in zip(colours.items(), offsets):
        _errorbars(ax, stats[stats["colour"] == lab], "p16", "p84", color, fmt="o", dx=dx,
                   label=f"BP-RP {lab}" if lab != _BLIND else _BLIND)
        c = curves[curves["colour"] == lab]
        if len(c):
            ax.plot(c["g"], c["sigma_mas"], "-", color=color, lw=1, alpha=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("G [mag]")
    ax.set_ylabel(r"$\sigma_{\varpi,F90}$ [mas]")
    ax.set_title("sigma_F90 per BP-RP bin (points: cells, median and 16-84 % over directions;\n"
                 "lines: fitted surfaces, median over directions)", fontsize=9)
    ax.legend(fontsize=7)
    return save_png(fig, path)


def plot_fraction_by_colour(fitted: pd.DataFrame, blind: pd.DataFrame, band: tuple[float, float], p: float,
                            path: Path) -> Path:
    """Per BP-RP bin (one panel each): the fraction inside at the bin's fitted width and at
    the colour-blind width against G, median over the directions with min-max bars, on the
    shaded ``band``."""
    labels = list(dict.fromkeys(fitted["colour"]))
    colours = bin_colours(labels)
    fig, axes = plt.subplots(1, max(len(labels), 1), figsize=(2.6 * max(len(labels), 1) + 1, 3.8), sharey=True,
                             squeeze=False)
    for ax, lab in zip(axes[0], labels):
        ax.axhspan(100 * band[0], 100 * band[1], color="0.85", lw=0)
        ax.axhline(100 * p, color="0.5", lw=0.8)
        _errorbars(ax, blind[blind["colour"] == lab], "min", "max", "0.45", scale=100, fmt="s", dx=0.1)
        _errorbars(ax, fitted[fitted["colour"] == lab], "min", "max", colours[lab], scale=100, fmt="o")
        ax.set_title(f"BP-RP {lab}", fontsize=9)
        ax.set_xlabel("G [mag]")
    axes[0, 0].set_ylabel("% inside the P ellipse")
    axes[0, 0].legend(handles=[Line2D([], [], color="0.2", marker="o", ls="", label="fitted width of the bin"),
                               Line2D([], [], color="0.45", marker="s", ls="", label="colour-blind width")],
                      fontsize=7, loc="lower left")
    return save_png(fig, path)


def plot_mean_errors(star: pd.DataFrame, quasar: pd.DataFrame, quasar_fraction: pd.DataFrame,
                     band: tuple[float, float], p: float, path: Path) -> Path:
    """A mean-centred prior at sigma_F90: left, the P-th percentile position error of the
    stars (solid) and of quasars (dashed) against G, bars 16-84 % over the directions; right,
    the quasars' fraction inside, bars min-max."""
    colours = bin_colours([*star["colour"], *quasar["colour"]])
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    for lab, color in colours.items():
        name = f"BP-RP {lab}" if lab != _BLIND else _BLIND
        _errorbars(left, star[star["colour"] == lab], "p16", "p84", color, fmt="o-", label=f"stars, {name}")
        _errorbars(left, quasar[quasar["colour"] == lab], "p16", "p84", color, fmt="^--", mfc="none", dx=0.1)
        _errorbars(right, quasar_fraction[quasar_fraction["colour"] == lab], "min", "max", color, scale=100,
                   fmt="^--", mfc="none", label=name)
    left.set_yscale("log")
    left.set_ylabel(f"{100 * p:g}th percentile position error [mas]")
    left.set_title("stars (o, solid) and quasars (^, dashed)", fontsize=9)
    right.axhspan(100 * band[0], 100 * band[1], color="0.85", lw=0)
    right.axhline(100 * p, color="0.5", lw=0.8)
    right.set_ylabel("quasars: % inside the P ellipse")
    right.set_title("zero-truth sources with the mean-centred prior", fontsize=9)
    for ax in (left, right):
        ax.set_xlabel("G [mag]")
        ax.legend(fontsize=7)
    return save_png(fig, path)
