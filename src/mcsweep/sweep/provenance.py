"""What a run directory records about how its results were made.

``provenance.json`` holds the resolved config, the hash of its scientific part (every
key except ``execution``, which must not change results), the package version, the
git commit when the package runs from a checkout, the built-in galaxy model's version, the seeds, per-stage timings and a
manifest (size and SHA-256) of the result files. The hash also guards a run directory
against mixing the results of two configs.
"""

from __future__ import annotations

import hashlib
import json
import platform
import subprocess
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from .. import __version__
from ..errors import UserInputError
from ..population.galaxy.parameters import MODEL_VERSION as GALAXY_MODEL_VERSION
from .store import atomic_write_bytes

__all__ = ["config_hash", "git_commit", "Provenance", "PROVENANCE_FILE"]

PROVENANCE_FILE = "provenance.json"
_EXCLUDED_KEYS = ("execution",)


def _science_part(cfg: dict) -> dict:
    return {k: v for k, v in cfg.items() if k not in _EXCLUDED_KEYS}


def config_hash(cfg: dict) -> str:
    """Hash of the config keys that can change results (execution excluded)."""
    blob = json.dumps(_science_part(cfg), sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:16]


def git_commit() -> str | None:
    """Commit of the checkout the package was imported from, if any (+ '-dirty')."""
    src = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "-C", str(src), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(src), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


def _diff_keys(a: Any, b: Any, prefix: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _diff_keys(a.get(k), b.get(k), f"{prefix}{k}.")
        return out
    return [] if a == b else [f"{prefix[:-1]}: {a!r} -> {b!r}"]


class Provenance:
    """Reads, checks and writes a run directory's provenance record."""

    def __init__(self, run_dir: Path, cfg: dict, *, kind: str):
        self.run_dir = Path(run_dir)
        self.cfg = cfg
        self.kind = kind
        self.hash = config_hash(cfg)
        self.timings: dict[str, float] = {}
        self.seeds: dict[str, Any] = {"seed": cfg.get("seed")}

    @property
    def path(self) -> Path:
        return self.run_dir / PROVENANCE_FILE

    def check_compatible(self) -> None:
        """Refuse a run directory that holds results of another config."""
        if not self.path.exists():
            return
        old = json.loads(self.path.read_text())
        if old.get("config_hash") != self.hash:
            diffs = _diff_keys(_science_part(old.get("config", {})), _science_part(self.cfg))
            what = "; ".join(diffs[:3]) + (" ..." if len(diffs) > 3 else "")
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
            "timings_s": self.timings,
            **(extra or {}),
            "manifest": self.manifest() if with_manifest else [],
        }
        atomic_write_bytes(self.path, json.dumps(record, indent=2, default=str).encode())
