"""Composition of every config option, and bad values rejected with one clear line."""

from pathlib import Path

import pytest

from mcsweep.errors import UserInputError
from mcsweep.command.schema import Config
from mcsweep.command.validate import preflight

CONF = Path(__file__).resolve().parents[2] / "src" / "mcsweep" / "conf"
GROUPS = sorted(p.name for p in CONF.iterdir() if p.is_dir() and not p.name.startswith("_"))


def test_defaults_compose_to_the_paper_setup():
    (cfg,) = preflight([])
    assert isinstance(cfg, Config)
    assert cfg.confidence == 0.9 and cfg.ratio_R == 10.0
    assert cfg.sky.name == "healpix48" and cfg.sky.nside == 2
    assert [float(g) for g in cfg.magnitudes.edges] == [float(g) for g in range(6, 21)]
    assert cfg.prior_grid.n >= 41 and cfg.prior_grid.min_mas == 0.01 and cfg.prior_grid.max_mas == 1000
    assert cfg.observations.f90_case == "two" and cfg.execution.n_jobs == 2


@pytest.mark.parametrize("group,option", [
    (g, p.stem) for g in GROUPS for p in sorted((CONF / g).glob("*.yaml"))
    if not (g == "sky" and p.stem == "custom") and not (g == "population" and p.stem == "catalogue")
])
def test_every_option_of_every_group_composes(group, option):
    (cfg,) = preflight([f"{group}={option}"])
    assert isinstance(cfg, Config)


def test_multirun_expands_every_job():
    cfgs = preflight(["-m", "confidence=0.8,0.9,0.95", "ratio_R=1,10"])
    assert sorted((c.confidence, c.ratio_R) for c in cfgs) == sorted(
        (p, r) for p in (0.8, 0.9, 0.95) for r in (1.0, 10.0))


BAD = [
    (["confidence=1.5"], "confidence"),
    (["confidence=0"], "confidence"),
    (["confidence=abc"], "confidence"),
    (["ratio_R=-1"], "ratio_R"),
    (["seed=-1"], "seed"),
    (["cell.beam_radius_deg=-1"], "beam_radius_deg"),
    (["cell.max_stars=0"], "max_stars"),
    (["cell.min_stars=-5"], "min_stars"),
    (["magnitudes.edges=[15,14]"], "edges"),
    (["magnitudes.edges=[15]"], "edges"),
    (["magnitudes.edges=[19,30]"], "edges"),
    (["magnitudes.edges=[-1,3]"], "edges"),
    (["sky=foo"], "sky"),
    (["sky=custom"], "sky.directions"),
    (["sky=custom", "sky.directions=[[10,95]]"], "sky.directions"),
    (["prior_grid.min_mas=-1"], "min_mas"),
    (["prior_grid.min_mas=0"], "min_mas"),
    (["prior_grid.max_mas=0.001"], "max_mas"),
    (["prior_grid.n=1"], "prior_grid.n"),
    (["execution.backend=spark"], "backend"),
    (["execution.n_jobs=0"], "n_jobs"),
    (["prior_maps.nside=12"], "prior_maps.nside"),
    (["prior_maps.nside=512"], "prior_maps.nside"),
    (["observations.f90_case=three"], "f90_case"),
    (["observations.reference_epoch=median"], "reference_epoch"),
    (["noise.al_scale=0"], "al_scale"),
    (["noise.al_floor_mas=-0.1"], "noise.al_floor_mas"),
    (["noise.al_floor_mas=nan"], "noise.al_floor_mas"),
    (["noise.al_floor_mas=inf"], "noise.al_floor_mas"),
    (["noise.al_floor_mas=abc"], "al_floor_mas"),
    (["experiment=nonsense"], "experiment"),
    (["population=nonsense"], "population"),
    (["unknown_key=3"], "unknown_key"),
    (["-m", "confidence=0.8,1.2"], "confidence"),
]


@pytest.mark.parametrize("argv,needle", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_values_give_one_line_naming_the_value(argv, needle):
    with pytest.raises(UserInputError) as exc:
        preflight(argv)
    msg = str(exc.value)
    assert "\n" not in msg and needle in msg
