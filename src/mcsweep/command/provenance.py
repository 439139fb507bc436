"""What a run directory records about how its results were made.

``provenance.json`` holds the resolved config, the hash of its scientific part (every
key except ``execution``, ``resume`` and ``prior_maps``, which do not change the cells, and
the keys the experiment never reads, :func:`~mcsweep.experiments.registry.ignored_keys`), the
package version, the git commit when the package runs from a checkout, the built-in
galaxy model's version, the seeds,
per-stage timings, a manifest (size and SHA-256) of the result files, and how many
cells each code version computed (``cell_code_versions``: a resumed run may mix
versions when the user allows it). The hash also guards a run directory against
mixing the results of two configs.
"""

from __future__ import annotations

import copy
import hashlib
import json
import platform
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from .. import __version__
from ..errors import UserInputError
from ..experiments.global_solution.settings import mission_span_jd
from ..population.galaxy.parameters import MODEL_VERSION as GALAXY_MODEL_VERSION
from ..scanning.timescale import tcb_jd
from ..experiments.registry import hash_defaults_from_before, hash_only_with, ignored_keys, renamed_keys
from .renamed import to_old_names
from ..runtime.store import atomic_write_bytes
from ..runtime.version import git_commit

__all__ = ["config_hash", "git_commit", "Provenance", "PROVENANCE_FILE"]

PROVENANCE_FILE = "provenance.json"
# execution, resume: how, not what; prior_maps: rendering of the fitted prior, no cell depends on it.
_EXCLUDED_KEYS = ("execution", "resume", "prior_maps")


_ANY = object()


def _drop(out: dict, dotted: str, only_if=_ANY) -> None:
    """Remove the dotted key from ``out`` (where it exists, and with ``only_if`` only where
    its value equals that), copying the dicts on its path: the config they came from stays
    whole. A section left empty goes too: a config group whose every key is at its value
    from before the group existed hashes as the configs made before it."""
    *parents, leaf = dotted.split(".")
    node = out
    for k in parents:
        if not isinstance(node.get(k), dict):
            return
        node = node[k]
    if leaf not in node or (only_if is not _ANY and node[leaf] != only_if):
        return
    path, node = [out], out
    for k in parents:
        node[k] = dict(node[k])
        node = node[k]
        path.append(node)
    node.pop(leaf)
    for parent, k, child in zip(reversed(path[:-1]), reversed(parents), reversed(path[1:])):
        if child:
            break
        parent.pop(k)


def _science_part(cfg: dict) -> dict:
    """The keys that can change results: not execution/resume, nor what the experiment ignores;
    renamed keys under their old names (:func:`~mcsweep.command.renamed.to_old_names`)."""
    out = {k: v for k, v in to_old_names(cfg).items() if k not in _EXCLUDED_KEYS}
    name = (cfg.get("experiment") or {}).get("name", "f90_sweep")
    for dotted in ignored_keys(name):
        _drop(out, dotted)
    # Options whose default is the model from before the option existed: left out at that
    # value so run directories made before it keep their hash (and can be resumed).
    for dotted, before in _defaults_from_before().items():
        _drop(out, dotted, only_if=before)
    for dotted, needs in hash_only_with().items():
        if _value(cfg, needs) is None:
            _drop(out, dotted)
    _segments_as_before(out, _observed_span_jd(cfg))
    return out


def _value(cfg: dict, dotted: str):
    """The value at a dotted key, None where it or a section on its path is missing."""
    node = cfg
    for k in dotted.split("."):
        node = node.get(k) if isinstance(node, dict) else None
    return node


#: dotted key -> the value that reproduces the model from before the option existed, for the
#: sections every experiment shares (an experiment's own are in its spec,
#: :attr:`mcsweep.experiments.spec.ExperimentSpec.defaults_from_before`).
_SHARED_DEFAULTS_FROM_BEFORE = {
    "noise.al_floor_mas": 0,
    "noise.model": "published",  # the only noise model before the registry existed
    "population.params.extinction_model": "disc",
    "population.params.giant_thickness_factor": 0.45,  # galaxy model besancon-r03-4
    "population.params.subgiants": False,  # galaxy models before besancon-r03-5
    "population.params.evolved_stars": "wielen",  # galaxy models before besancon-r03-6
    "population.params.young_disc_thickness_factor": 1.0,  # galaxy models before besancon-r03-6
    # prior_model=direction_g, the paper's prior (Sect. 3.4): the model before the group existed.
    "prior_model.name": "direction_g",
    "prior_model.colour_edges": [],
    "prior_model.mean": False,
}


def _defaults_from_before() -> dict:
    return {**_SHARED_DEFAULTS_FROM_BEFORE, **hash_defaults_from_before()}


#: Segments of the flown scanning law whose phases were refitted, by (kind, start_tcb, end_tcb):
#: key -> (value now, value before). The reversed-precession year, refitted to Gaia's
#: observation forecasts (research note scanning-law-history.md): the phases before left
#: nu 0.57 deg off, which put about a third of its transits in the other field of view.
_SEGMENT_PHASES_FROM_BEFORE = {
    ("nsl_reversed", "2019-07-05T00:00:00", "2020-08-01T00:00:00"):
        {"nu_ref_deg": (314.6231, 315.314), "omega_ref_deg": (170.3941, 169.887)},
}


def _observed_span_jd(cfg: dict) -> tuple[float, float] | None:
    """``[start, end)`` (TCB JD) the run takes its transits from: a global experiment's
    mission, else ``observations.start`` / ``end``; None where the config does not say."""
    try:
        conf = OmegaConf.create({k: cfg[k] for k in ("experiment", "observations")})
        name = conf.experiment.get("name", "f90_sweep")
        section = conf.experiment.get(name)
        if section is not None and "mission_start" in section:
            return mission_span_jd(conf, name)
        return (tcb_jd(str(conf.observations.start), "observations.start"),
                tcb_jd(str(conf.observations.end), "observations.end"))
    except (KeyError, AttributeError, TypeError, ValueError, UserInputError, OmegaConfBaseException):
        return None


def _segments_as_before(out: dict, span: tuple[float, float] | None) -> None:
    """Hash a refitted segment that the run never reads at its phases from before the refit
    (:data:`_SEGMENT_PHASES_FROM_BEFORE`), so that runs it cannot change keep their hash and
    resume. A segment is read where it overlaps the span; the first and the last are also
    read outside their bounds (the law is extrapolated there)."""
    segs = _value(out, "scanning.segments")
    if span is None or not isinstance(segs, list):
        return
    new = list(segs)
    for i, seg in enumerate(segs):
        if not isinstance(seg, dict) or i in (0, len(segs) - 1):
            continue
        phases = _SEGMENT_PHASES_FROM_BEFORE.get((seg.get("kind"), seg.get("start_tcb"), seg.get("end_tcb")))
        if phases is None or any(seg.get(k) != now for k, (now, _) in phases.items()):
            continue
        start, end = (tcb_jd(seg[k], f"scanning.segments[{i}].{k}") for k in ("start_tcb", "end_tcb"))
        if span[1] <= start or span[0] >= end:
            new[i] = {**seg, **{k: before for k, (_, before) in phases.items()}}
    if new != segs:
        out["scanning"] = {**out["scanning"], "segments": new}


def config_hash(cfg: dict) -> str:
    """Hash of the config keys that can change results (execution excluded)."""
    blob = json.dumps(_science_part(cfg), sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:16]


def _with_defaults_from_before(science: dict) -> dict:
    """``science`` with the keys that :func:`_defaults_from_before` left out put back at their
    'before' value (where their section is there), so a refusal names both values (e.g.
    ``extinction_model: 'disc' -> 'arenou1992'``) rather than ``None`` for one of them."""
    out = copy.deepcopy(science)
    for dotted, before in _defaults_from_before().items():
        parent, leaf = dotted.rsplit(".", 1)
        node = _value(out, parent)
        if isinstance(node, dict) and leaf not in node:
            node[leaf] = before
    for dotted, needs in hash_only_with().items():  # not where it has no effect (left out of the hash)
        if _value(out, needs) is None:
            _drop(out, dotted)
    return out


def _diff_keys(a: Any, b: Any, prefix: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _diff_keys(a.get(k), b.get(k), f"{prefix}{k}.")
        return out
    if _is_segment_list(a) and _is_segment_list(b) and len(a) == len(b):
        # one scanning-law segment changed: name it, not the whole list
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            span = f"{y.get('kind')} {str(y.get('start_tcb'))[:10]}..{str(y.get('end_tcb'))[:10]}"
            out += _diff_keys(x, y, f"{prefix[:-1]}[{i}] ({span}).")
        return out
    return [] if a == b else [f"{prefix[:-1]}: {a!r} -> {b!r}"]


def _new_name(diff: str) -> str:
    """A line of :func:`_diff_keys` naming a renamed key by its new name, as the user writes it."""
    for old, new in renamed_keys().items():
        if diff.startswith(old + ":"):
            return new + diff[len(old):]
    return diff


def _is_segment_list(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(v, dict) and "kind" in v and "start_tcb" in v for v in value)


class Provenance:
    """Reads, checks and writes a run directory's provenance record."""

    def __init__(self, run_dir: Path, cfg: dict, *, kind: str):
        self.run_dir = Path(run_dir)
        self.cfg = cfg
        self.kind = kind
        self.hash = config_hash(cfg)
        self.timings: dict[str, float] = {}
        self.seeds: dict[str, Any] = {"seed": cfg.get("seed")}
        #: Cells (or chunks) per code version that computed them, filled at aggregation.
        self.cell_versions: dict[str, int] = {}
        #: Values derived from the config that a reader needs (e.g. a resolved reference epoch).
        self.derived: dict[str, Any] = {}

    @property
    def path(self) -> Path:
        return self.run_dir / PROVENANCE_FILE

    def check_compatible(self) -> None:
        """Refuse a run directory that holds results of another config."""
        if not self.path.exists():
            return
        old = json.loads(self.path.read_text())
        if old.get("config_hash") != self.hash:
            diffs = _diff_keys(_with_defaults_from_before(_science_part(old.get("config", {}))),
                               _with_defaults_from_before(_science_part(self.cfg)))
            diffs = [_new_name(d) for d in diffs]
            what = "; ".join(diffs[:3]) + (" ..." if len(diffs) > 3 else "") if diffs else \
                f"same values, hash {old.get('config_hash')} by {old.get('mcsweep_version')} vs {self.hash}"
            raise UserInputError(
                f"run directory {self.run_dir} holds results of a different config ({what}); "
                "expected the same config to resume, or a new hydra.run.dir"
            )
        self.timings = {f"previous:{k}": v for k, v in old.get("timings_s", {}).items()
                        if not k.startswith("previous:")}

    @contextmanager
    def stage(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = round(self.timings.get(name, 0.0) + time.perf_counter() - t0, 3)

    def manifest(self) -> list[dict]:
        files = []
        for p in sorted(self.run_dir.rglob("*")):
            if not p.is_file() or p.name == PROVENANCE_FILE or p.name.startswith(".") \
                    or ".hydra" in p.parts or p.suffix == ".log":
                continue
            files.append({"path": str(p.relative_to(self.run_dir)), "bytes": p.stat().st_size,
                          "sha256": hashlib.sha256(p.read_bytes()).hexdigest()})
        return files

    def write(self, *, extra: dict | None = None, with_manifest: bool = True) -> None:
        record = {
            "kind": self.kind,
            "config_hash": self.hash,
            "config": self.cfg,
            "mcsweep_version": __version__,
            # the built-in model's parameter set (its user values are in config.population)
            "galaxy_model_version": GALAXY_MODEL_VERSION,
            "git_commit": git_commit(),
            "python": platform.python_version(),
            "seeds": self.seeds,
            **({"cell_code_versions": self.cell_versions} if self.cell_versions else {}),
            "derived": self.derived,
            "timings_s": self.timings,
            **(extra or {}),
            "manifest": self.manifest() if with_manifest else [],
        }
        atomic_write_bytes(self.path, json.dumps(record, indent=2, default=str).encode())
