"""Figures of the primary solution's report (PNG): its attitude error and its convergence."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ...runtime.document import save_png  # noqa: E402

__all__ = ["plot_primary_attitude_error", "plot_primary_convergence"]


def plot_primary_attitude_error(series: pd.DataFrame, path: Path) -> Path:
    """Attitude error (estimated - true, after the frame correction) against time, one panel per
    axis, one line per prior (column ``prior``), with each prior's RMS over the plotted epochs."""
    fig, axes = plt.subplots(3, 1, figsize=(8.0, 6.5), sharex=True)
    t0 = float(series["tcb_jd"].min())
    for ax, col, name in zip(axes, ("x_uas", "y_uas", "z_uas"), "xyz"):
        for prior, df in series.groupby("prior", sort=False):
            # dead intervals hold no data: break the line there instead of joining across
            t = df["tcb_jd"].to_numpy() - t0
            y = df[col].to_numpy(dtype=float)
            gap = np.r_[False, np.diff(t) > 1.5 * np.median(np.diff(t))] if t.size > 1 else np.zeros(t.size, bool)
            t_plot = np.insert(t, np.flatnonzero(gap), np.nan)
            y_plot = np.insert(y, np.flatnonzero(gap), np.nan)
            rms = float(np.sqrt(np.mean(y ** 2))) if y.size else float("nan")
            ax.plot(t_plot, y_plot, lw=0.4, alpha=0.8, label=f"{prior}: RMS {rms:.1f} uas")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{name} axis [uas]")
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel(f"days since TCB JD {t0:.2f}")
    axes[0].set_title("Attitude error after the frame correction (live time)")
    return save_png(fig, path)


def plot_primary_convergence(history: pd.DataFrame, path: Path) -> Path:
    """PCG convergence per prior: relative residual of the normal equations, the largest
    update [uas] and, where logged, the estimated error of the energy criterion (in units of
    the formal uncertainties) against the iteration (logarithmic)."""
    energy = "error_estimate" in history and bool(np.isfinite(history["error_estimate"]).any())
    fig, axes = plt.subplots(1, 3 if energy else 2, figsize=(13.0 if energy else 9.0, 3.6))
    for prior, df in history.groupby("prior", sort=False):
        axes[0].semilogy(df["iteration"], df["relative_residual"], label=str(prior))
        axes[1].semilogy(df["iteration"], df["update_max_uas"], label=str(prior))
        if energy:
            axes[2].semilogy(df["iteration"], df["error_estimate"].replace(np.inf, np.nan), label=str(prior))
    for ax, label in zip(axes, ("|b - N x| / |b|", "largest update [uas]", "|x - x*|_N (estimate)")):
        ax.set_xlabel("iteration")
        ax.set_ylabel(label)
    axes[0].legend(fontsize=7)
    return save_png(fig, path)
