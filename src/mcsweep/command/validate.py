"""Turn composed configs into checked objects, and vet command lines before Hydra runs.

Hydra reports a bad override with a multi-line message and exit status 1, after it
has created the run directory. :func:`preflight` composes every job of a command line
first (each combination of a multirun sweep), so a bad value ends the command with one
line and exit status 2 before any output exists.

Only errors a user can cause become that one line: :class:`~mcsweep.errors.UserInputError`
raised by the schema's checks, and Hydra's and OmegaConf's own errors about the
command line or the config (unknown option, unparsable override, wrong type, unknown
key). An error whose root cause is anything else (a ``ZeroDivisionError`` in a
``__post_init__``, a ``KeyError`` in our code) is a bug: it propagates with its
traceback and the command ends with Python's status 1.
"""

from __future__ import annotations

import itertools
import re
from typing import Iterable

from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from ..errors import UserInputError
from ..experiments.registry import ignored_keys
from .renamed import with_new_names
from .schema import Config, register_configs

__all__ = ["to_config", "compose_config", "preflight", "ignored_settings", "CONFIG_MODULE"]

CONFIG_MODULE = "mcsweep.conf"
# Hydra command-line flags that take a value as the next token.
_FLAGS_WITH_VALUE = {"--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd",
                     "--experimental-rerun", "--package", "-p", "--info", "-i"}


_CONFIG_ERRORS = (HydraException, OmegaConfBaseException)


def _is_config_error(exc: BaseException) -> bool:
    """True if ``exc`` and every exception it was raised *from* are Hydra/OmegaConf/user errors.

    Only explicit causes count: OmegaConf converts a user's ``ValueError`` ("abc" is no
    float) into its own error inside an ``except`` block, so implicit context is expected.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if not isinstance(exc, (*_CONFIG_ERRORS, UserInputError)):
            return False
        exc = exc.__cause__
    return True


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    # OmegaConf appends "full_key: ... object_type=..." context: keep the key only.
    m = re.search(r"full_key: ([\w.\[\]]+)", str(exc))
    msg = text.split(" full_key:")[0]
    return f"{msg} (key: {m.group(1)})" if m else msg


def to_config(cfg: DictConfig) -> Config:
    """Typed, range-checked :class:`Config` from a composed Hydra config."""
    try:
        obj = OmegaConf.to_object(cfg)
    except UserInputError:
        raise
    except OmegaConfBaseException as exc:
        cause = exc.__cause__ or exc.__context__
        if isinstance(cause, UserInputError):
            raise cause from None
        if not _is_config_error(exc):
            raise  # a bug behind OmegaConf's wrapper: keep the traceback
        raise UserInputError(f"invalid config: {_one_line(exc)}") from None
    if not isinstance(obj, Config):  # pragma: no cover - base_config missing from defaults
        raise UserInputError("config is not based on base_config; expected conf/config.yaml's defaults")
    return obj


def _unknown_option_message(exc: BaseException) -> str:
    text = str(exc)
    m = re.search(r"Could not find '([^']+)/([^']+)'", text)
    if m:
        group, option = m.groups()
        opts = re.findall(r"^\s+(\S+)\s*$", text.split("Available options", 1)[-1], flags=re.M)
        accepted = ", ".join(opts) if opts else "an option of that group"
        return f"unknown {group} '{option}'; accepted: {accepted}"
    return _one_line(exc)


def compose_config(overrides: Iterable[str] = ()) -> DictConfig:
    """Compose ``conf/config.yaml`` with overrides (as Hydra would), outside a run."""
    from hydra import compose, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    register_configs()
    GlobalHydra.instance().clear()
    overrides, _ = with_new_names(list(overrides))  # the command line warns about old names
    try:
        with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
            return compose(config_name="config", overrides=overrides)
    except UserInputError:
        raise
    except _CONFIG_ERRORS as exc:  # hydra's MissingConfigException, ConfigCompositionException, ...
        cause = exc.__cause__
        if isinstance(cause, UserInputError):
            raise cause from None
        if not _is_config_error(exc):
            raise  # a bug reached through Hydra's composition: keep the traceback
        msg = _unknown_option_message(exc)
        if isinstance(cause, OmegaConfBaseException):
            msg = f"{msg}: {_one_line(cause)}"
        raise UserInputError(msg) from None
    finally:
        GlobalHydra.instance().clear()


def _split_argv(argv: list[str]) -> list[str]:
    overrides, skip = [], False
    for tok in argv:
        if skip:
            skip = False
            continue
        if tok in _FLAGS_WITH_VALUE:
            skip = True
            continue
        if tok.startswith("-"):
            continue
        # hydra.searchpath adds config directories (an experiment's YAML defined outside the
        # package): composition needs it; Hydra's other settings do not change the config.
        if tok.startswith(("hydra.", "hydra/", "+hydra", "~hydra")) and not tok.startswith("hydra.searchpath="):
            continue
        overrides.append(tok)
    return overrides


def _expand_sweeps(overrides: list[str]) -> list[list[str]]:
    """Every job of a multirun command line (cartesian product of sweep overrides)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except _CONFIG_ERRORS as exc:
        raise UserInputError(f"cannot parse overrides {overrides}: {_one_line(exc)}") from None
    choices = []
    for ov in parsed:
        if ov.is_sweep_override():
            key = ov.get_key_element()
            choices.append([f"{key}={v}" for v in ov.sweep_string_iterator()])
        else:
            choices.append([ov.input_line])
    return [list(combo) for combo in itertools.product(*choices)] or [[]]


def _override_key(override: str) -> str:
    return override.split("=", 1)[0].lstrip("+~").split("@", 1)[0]


def ignored_settings(argv: list[str], configs: list[Config]) -> list[str]:
    """One warning line per experiment for command-line settings it never reads.

    ``configs`` are :func:`preflight`'s, one per job of the command line, in order.
    """
    jobs = _expand_sweeps(_split_argv(argv)) if configs else []
    found: dict[str, list[str]] = {}
    for job, config in zip(jobs, configs):
        ignored = ignored_keys(config.experiment.name)
        for ov in job:
            key = _override_key(ov)
            if any(key == k or key.startswith(k + ".") for k in ignored):
                names = found.setdefault(config.experiment.name, [])
                if ov not in names:
                    names.append(ov)
    return [f"experiment={name} ignores {', '.join(ovs)}: they change neither its results nor its config hash"
            for name, ovs in found.items()]


def preflight(argv: list[str]) -> list[Config]:
    """Compose and check every job of a command line; raise UserInputError on the first bad one."""
    if any(a in ("--help", "-h", "--hydra-help", "--cfg", "-c", "--info", "-i", "--shell-completion", "-sc")
           for a in argv):
        return []
    configs = []
    for job in _expand_sweeps(_split_argv(argv)):
        configs.append(to_config(compose_config(job)))
    return configs
