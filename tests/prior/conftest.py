"""Synthetic sweep run directories with a colour axis and a prior mean (the files of a
colour / colour_mean sweep, written here by hand with known coefficients and means)."""

import json

import numpy as np
import pandas as pd
import pytest
from astropy.coordinates import ICRS, Galactic
from astropy_healpix import HEALPix

#: Colour-blind coefficients (coefficients.csv) and one set per BP-RP bin (colour_coefficients.csv).
BLIND = {"s0": (2.1, -0.25, 0.0065), "s1": (0.1, -0.05, 0.013, -0.0005), "s2": (0.03, -0.006)}
COLOUR_EDGES = [-1.0, 0.56, 1.23, 6.0]
PER_BIN = [
    {"s0": (1.9, -0.25, 0.0065), "s1": (0.12, -0.05, 0.013, -0.0005), "s2": (0.02, -0.006)},
    {"s0": (2.4, -0.26, 0.0066), "s1": (0.08, -0.05, 0.013, -0.0005), "s2": (0.04, -0.006)},
    {"s0": (1.7, -0.24, 0.0064), "s1": (0.15, -0.05, 0.013, -0.0005), "s2": (0.01, -0.005)},
]
G_EDGES = [6.0, 8.0, 10.0, 12.0]
#: The mean field: linear in the galactic unit vector n and in G, an offset per colour slot
#: (slot 0 colour-blind, k + 1 bin k).
A_PLX, A_PML, A_PMB = np.array([2.0, -1.0, 0.5]), np.array([-3.0, 4.0, 1.0]), np.array([1.5, 0.5, -2.0])
SLOT_OFFSET = np.array([0.0, -0.7, 1.1, -1.9])


def terms(coefficients):
    return [(f"{k}_c{i}", v) for k in ("s0", "s1", "s2") for i, v in enumerate(coefficients[k])]


def unit_gal(l_deg, b_deg):
    lr, br = np.radians(l_deg), np.radians(b_deg)
    return np.stack([np.cos(br) * np.cos(lr), np.cos(br) * np.sin(lr), np.sin(br)], axis=-1)


def mean_field(l_deg, b_deg, g, slot):
    """(parallax, mu_l*, mu_b) of the synthetic model at galactic l, b, G and colour slot."""
    n = unit_gal(l_deg, b_deg)
    scale = 1.0 + 0.1 * (12.0 - np.asarray(g, float))
    off = SLOT_OFFSET[np.asarray(slot)]
    return (scale * (3.0 + n @ A_PLX) + off, scale * (n @ A_PML) + off, n @ A_PMB - off)


def sky_directions_gal(sky):
    if sky["kind"] == "healpix":
        frame = Galactic() if sky["frame"] == "galactic" else ICRS()
        hp = HEALPix(nside=sky["nside"], order=sky["order"], frame=frame)
        c = hp.healpix_to_skycoord(np.arange(hp.npix)).galactic
        return c.l.deg, c.b.deg
    d = np.asarray(sky["directions"], float)
    if sky["frame"] == "galactic":
        return d[:, 0], d[:, 1]
    from astropy.coordinates import SkyCoord
    import astropy.units as u

    c = SkyCoord(d[:, 0] * u.deg, d[:, 1] * u.deg, frame="icrs").galactic
    return c.l.deg, c.b.deg


def write_run(run_dir, *, colour=True, mean=True, sky=None, nan_cells=()):
    """A run directory of the contract's files; returns its config."""
    sky = sky or {"name": "healpix48", "kind": "healpix", "nside": 2, "order": "nested", "frame": "galactic",
                  "directions": []}
    run_dir.mkdir()
    pd.DataFrame(terms(BLIND), columns=["term", "fitted"]).assign(fitted_lo=0.0, fitted_hi=0.0) \
        .to_csv(run_dir / "coefficients.csv", index=False)
    edges = COLOUR_EDGES if colour else []
    if colour:
        rows = [(lo, hi, t, v, v - 0.01, v + 0.01) for lo, hi, c in zip(edges, edges[1:], PER_BIN)
                for t, v in terms(c)]
        pd.DataFrame(rows, columns=["bp_rp_min", "bp_rp_max", "term", "fitted", "fitted_lo", "fitted_hi"]) \
            .to_csv(run_dir / "colour_coefficients.csv", index=False)
    if mean:
        l_deg, b_deg = sky_directions_gal(sky)
        colours = [(np.nan, np.nan)] + list(zip(edges, edges[1:]))
        rows = []
        for i in range(l_deg.size):
            for g0, g1 in zip(G_EDGES, G_EDGES[1:]):
                for slot, (c0, c1) in enumerate(colours):
                    plx, pml, pmb = mean_field(l_deg[i], b_deg[i], 0.5 * (g0 + g1), slot)
                    rows.append((l_deg[i], b_deg[i], g0, g1, c0, c1, plx, pml, pmb))
        table = pd.DataFrame(rows, columns=["l_deg", "b_deg", "g_min", "g_max", "bp_rp_min", "bp_rp_max",
                                            "mean_parallax_mas", "mean_pml_masyr", "mean_pmb_masyr"])
        for i in nan_cells:
            table.loc[i, ["mean_parallax_mas", "mean_pml_masyr", "mean_pmb_masyr"]] = np.nan
        table.to_csv(run_dir / "prior_means.csv", index=False)
    name = "colour_mean" if colour and mean else "colour" if colour else "mean" if mean else "direction_g"
    cfg = {"sky": sky, "magnitudes": {"edges": G_EDGES}, "confidence": 0.9, "ratio_R": 10.0,
           "prior_model": {"name": name, "colour_edges": edges, "mean": mean}}
    (run_dir / "provenance.json").write_text(json.dumps({"kind": "f90_sweep", "config": cfg}))
    return cfg


def source_normal_equations(grp, s):
    """One source's normal equations (Eqs. 2-3) from its rows of an observation table, straight
    from the library's astrometry stage (design matrix, normal equations), at the mean epoch of
    its transits: (N0, b0, epoch), the reference the ``solve`` command is checked against."""
    from mcsweep.astrometry.design import design_matrix, reference_epoch, years_since
    from mcsweep.astrometry.solve import normal_equations

    tcb = grp["tcb_jd"].to_numpy()[None, :]
    ep = reference_epoch(tcb)
    A = design_matrix([s["ra"]], [s["dec"]], years_since(tcb, ep), grp["scan_angle_deg"].to_numpy()[None],
                      grp[["obs_x_au", "obs_y_au", "obs_z_au"]].to_numpy()[None],
                      sigma_al_mas=grp["al_sigma_mas"].to_numpy()[None],
                      sigma_ac_mas=grp["ac_sigma_mas"].to_numpy()[None])
    h = np.concatenate([grp["al_residual_mas"] / grp["al_sigma_mas"],
                        grp["ac_residual_mas"] / grp["ac_sigma_mas"]])[None]
    N0, b0 = normal_equations(A, h)
    return N0, b0, ep


@pytest.fixture
def colour_mean_run(tmp_path):
    d = tmp_path / "colour_mean"
    write_run(d)
    return d


@pytest.fixture
def colour_run(tmp_path):
    d = tmp_path / "colour"
    write_run(d, mean=False)
    return d


@pytest.fixture
def synth():
    """The helpers and constants above (test modules cannot import conftest under
    --import-mode=importlib)."""
    import sys

    return sys.modules[__name__]
