"""Noise models are chosen by name (noise.model) through one registry: a new model is one
class and one register call, and every experiment then builds it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mcsweep.astrometry import noise_models
from mcsweep.astrometry.noise import NoiseModel
from mcsweep.command.validate import compose_config, to_config
from mcsweep.errors import UserInputError

BIN = Path(sys.executable).parent


class ConstantNoise:
    """A minimal third-party model: the same AL and AC precision at every G."""

    use_ac = True

    def __init__(self, sigma_mas: float):
        self.sigma = sigma_mas

    @classmethod
    def from_config(cls, section):
        return cls(float(section.al_floor_mas) or 1.0)

    def sigma_al_mas(self, G):
        return np.full(np.shape(G), self.sigma)

    def sigma_ac_mas(self, G):
        return np.full(np.shape(G), 3.0 * self.sigma)

    def design_sigmas(self, G):
        g = np.atleast_1d(np.asarray(G, float))[:, None]
        return self.sigma_al_mas(g), self.sigma_ac_mas(g)


@pytest.fixture
def constant_noise(monkeypatch):
    monkeypatch.setitem(noise_models.NOISE_MODELS, "constant", ConstantNoise)
    return "constant"


def test_the_default_model_is_the_published_one():
    model = noise_models.noise_model(to_config(compose_config([])).noise)
    assert type(model) is NoiseModel
    # Perryman et al. (2014), Eqs. 1-3: 0.034 mas per FoV transit at G <= 12 (module notes of noise)
    assert model.sigma_al_mas(np.array([10.0]))[0] == pytest.approx(0.0342, abs=5e-4)
    assert isinstance(model, noise_models.NoiseModelLike)


def test_a_registered_model_is_what_every_experiment_builds(constant_noise):
    from mcsweep.experiments.f90_sweep.runner import build_settings as sweep_settings
    from mcsweep.experiments.global_solution.settings import global_fields
    from mcsweep.experiments.real_sky.experiment import build_settings as real_sky_settings

    over = [f"noise.model={constant_noise}", "noise.al_floor_mas=0.5"]
    cfg = to_config(compose_config(over))
    assert isinstance(sweep_settings(cfg).noise, ConstantNoise)
    assert isinstance(real_sky_settings(to_config(compose_config(["experiment=real_sky", *over]))).noise,
                      ConstantNoise)
    primary = to_config(compose_config(["experiment=primary", *over]))
    noise = global_fields(primary, "primary")["noise"]
    assert isinstance(noise, ConstantNoise) and noise.sigma_al_mas(np.array([7.0, 19.0])).tolist() == [0.5, 0.5]


def test_an_unknown_model_is_one_line_naming_the_registered_ones():
    with pytest.raises(UserInputError, match=r"^noise\.model='nope' is not accepted; expected one of \['published'\]$"):
        to_config(compose_config(["noise.model=nope"]))


def test_the_command_refuses_an_unknown_model_with_status_2_and_no_output(tmp_path):
    r = subprocess.run([str(BIN / "mcsweep"), "noise.model=nope", f"hydra.run.dir={tmp_path / 'run'}"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and not (tmp_path / "run").exists()
    assert r.stderr.strip().splitlines()[-1] == ("mcsweep: error: noise.model='nope' is not accepted; "
                                                 "expected one of ['published']")


def test_a_bad_setting_of_the_model_names_its_noise_key():
    with pytest.raises(UserInputError, match=r"^noise\.al_scale=-1\.0 is not accepted"):
        to_config(compose_config(["noise.al_scale=-1"]))
