"""Undo exactly what a refused job wrote into its run directory, and nothing else.

A user error (:class:`~mcsweep.errors.UserInputError`) must leave no partial output,
but the run directory may be the user's own folder (``hydra.run.dir=.``) or an earlier
run being resumed: only the paths this command created may go. Hydra creates the run
directory, writes ``.hydra/{config,hydra,overrides}.yaml`` and appends to ``<job>.log``
*before* the job starts, so the record of what was there is taken earlier, by a Hydra
callback (:class:`RunDirGuard`, listed under ``hydra.callbacks`` in ``conf/config.yaml``)
at ``on_run_start`` / ``on_multirun_start``.

The record (:class:`Snapshot`) lists every path under the directory, keeps the bytes of
the files Hydra or a resumed job rewrite in place (``.hydra/*``, ``multirun.yaml``,
``provenance.json``), the size of every log (Hydra appends to them) and the times of
every file and directory. :meth:`Snapshot.undo` removes the paths absent from the
record, puts the recorded files back byte for byte with their times, and removes the
directory itself (and any parent it had to create) only if it did not exist before.

When no record was taken before Hydra wrote (a job started by a remote launcher such as
SLURM), :func:`snapshot_for` takes one at the start of the job: Hydra's files then count
as pre-existing and stay, which errs on the side of keeping.
"""

from __future__ import annotations

import logging
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

__all__ = ["Snapshot", "RunDirGuard", "snapshot_for", "release", "undo_unstarted", "MAX_ENTRIES"]

#: A directory with more entries than this is not listed in full (a run pointed at a
#: home directory by mistake): its undo then removes only new names directly under it.
MAX_ENTRIES = 200_000
#: Files rewritten in place whose bytes are kept so they can be put back.
_KEEP_BYTES = {"config.yaml", "hydra.yaml", "overrides.yaml", "multirun.yaml", "provenance.json"}
_KEEP_BYTES_LIMIT = 16 * 2**20

_log = logging.getLogger(__name__)
_SNAPSHOTS: dict[Path, "Snapshot"] = {}


def _times(st: os.stat_result) -> tuple[int, int]:
    return (st.st_atime_ns, st.st_mtime_ns)


@dataclass
class Snapshot:
    """What existed under ``root`` before this command wrote anything."""

    root: Path
    existed: bool
    #: Nearest existing ancestor when ``root`` had to be created (removed up to it on undo).
    anchor: Path | None = None
    #: Relative paths (POSIX form) of every file, directory and link; None if too many.
    paths: set[str] | None = field(default_factory=set)
    #: Names directly under ``root`` (always complete: a new one is wholly this command's).
    top: set[str] = field(default_factory=set)
    dir_times: dict[str, tuple[int, int]] = field(default_factory=dict)
    file_bytes: dict[str, tuple[bytes, int, tuple[int, int]]] = field(default_factory=dict)
    log_sizes: dict[str, tuple[int, tuple[int, int]]] = field(default_factory=dict)

    @classmethod
    def take(cls, root) -> "Snapshot":
        """Record ``root`` (which may not exist yet)."""
        root = Path(os.path.abspath(root))
        if not root.exists():
            anchor = root.parent
            while not anchor.exists() and anchor != anchor.parent:
                anchor = anchor.parent
            return cls(root, existed=False, anchor=anchor)
        snap = cls(root, existed=True, top=set(os.listdir(root)))
        snap.dir_times[""] = _times(root.stat())
        n = 0
        for dirpath, dirnames, filenames in os.walk(root):
            rel_dir = Path(dirpath).relative_to(root)
            for name in dirnames + filenames:
                n += 1
                if n > MAX_ENTRIES:
                    snap.paths = None
                    break
                p = Path(dirpath) / name
                rel = (rel_dir / name).as_posix()
                snap.paths.add(rel)
                try:
                    st = p.lstat()
                except OSError:
                    continue
                snap._keep(rel, p, st)
            if snap.paths is None:
                break
            dirnames[:] = [d for d in dirnames if not (Path(dirpath) / d).is_symlink()]
        # Hydra's own files, whatever the walk reached before MAX_ENTRIES.
        for p in [*root.glob("*"), *root.glob(".hydra/*")]:
            try:
                snap._keep(p.relative_to(root).as_posix(), p, p.lstat())
            except OSError:
                continue
        return snap

    def _keep(self, rel: str, p: Path, st: os.stat_result) -> None:
        """Record what is needed to put ``p`` back: times, a log's size, a rewritten file's bytes."""
        if p.is_symlink():
            return
        if p.is_dir():
            self.dir_times[rel] = _times(st)
        elif p.name.endswith(".log"):
            self.log_sizes[rel] = (st.st_size, _times(st))
        elif p.name in _KEEP_BYTES and st.st_size <= _KEEP_BYTES_LIMIT:
            self.file_bytes[rel] = (p.read_bytes(), st.st_mode & 0o7777, _times(st))

    def _is_old(self, rel: str) -> bool:
        if self.paths is None:  # too many to list: only new top-level names are known to be new
            return "/" in rel or rel in self.top
        return rel in self.paths

    def undo(self, scope=None) -> None:
        """Remove what is new under ``scope`` (default: the whole root) and restore the rest."""
        for h in logging.getLogger().handlers:  # nothing buffered may land after the undo
            try:
                h.flush()
            except ValueError:  # its stream is closed: nothing of it can land
                pass
        scope = Path(os.path.abspath(scope)) if scope is not None else self.root
        if not scope.exists():
            return
        if not self.existed:
            if scope == self.root:
                shutil.rmtree(self.root, ignore_errors=True)
                self._remove_created_parents()
            else:
                shutil.rmtree(scope, ignore_errors=True)
            return
        base = scope.relative_to(self.root).as_posix()
        base = "" if base == "." else base
        if base and not self._is_old(base):
            shutil.rmtree(scope, ignore_errors=True)
            return
        for dirpath, dirnames, filenames in os.walk(scope, topdown=True):
            rel_dir = Path(dirpath).relative_to(self.root)
            keep = []
            for name in dirnames:
                p = Path(dirpath) / name
                if self._is_old((rel_dir / name).as_posix()):
                    if not p.is_symlink():
                        keep.append(name)
                elif p.is_symlink():
                    p.unlink(missing_ok=True)
                else:
                    shutil.rmtree(p, ignore_errors=True)
            # Unlisted (huge) tree: only its top level is known, do not descend.
            dirnames[:] = keep if self.paths is not None else []
            for name in filenames:
                if not self._is_old((rel_dir / name).as_posix()):
                    (Path(dirpath) / name).unlink(missing_ok=True)
        inside = (lambda rel: rel == base or rel.startswith(base + "/")) if base else (lambda rel: True)
        for rel, (data, mode, times) in self.file_bytes.items():
            if not inside(rel):
                continue
            p = self.root / rel
            try:
                if not p.exists() or p.read_bytes() != data:
                    p.parent.mkdir(parents=True, exist_ok=True)
                    p.write_bytes(data)
                    os.chmod(p, mode)
                os.utime(p, ns=times)
            except OSError as exc:  # pragma: no cover - read-only or vanished file
                _log.warning("could not restore %s: %s", p, exc)
        for rel, (size, times) in self.log_sizes.items():
            p = self.root / rel
            if inside(rel) and p.exists():
                if p.stat().st_size > size:
                    os.truncate(p, size)
                os.utime(p, ns=times)
        for rel in sorted(self.dir_times, key=lambda r: -r.count("/") - (r != "")):
            p = self.root / rel
            if inside(rel) or rel == "":
                if p.is_dir():
                    os.utime(p, ns=self.dir_times[rel])

    def _remove_created_parents(self) -> None:
        p = self.root.parent
        while self.anchor is not None and p != self.anchor and self.anchor in p.parents:
            try:
                p.rmdir()  # only if empty: another job of the same command may be using it
            except OSError:
                return
            p = p.parent

    def new_paths(self, scope=None) -> list[str]:
        """Relative paths under ``scope`` (default root) that were not there when recorded."""
        scope = Path(os.path.abspath(scope)) if scope is not None else self.root
        if not scope.exists():
            return []
        if not self.existed:
            return sorted(p.relative_to(self.root).as_posix() for p in scope.rglob("*")) or ["."]
        return sorted(rel for p in scope.rglob("*")
                      if not self._is_old(rel := p.relative_to(self.root).as_posix()))


def snapshot_for(run_dir) -> Snapshot:
    """The record covering ``run_dir`` taken before Hydra wrote, or one taken now."""
    run_dir = Path(os.path.abspath(run_dir))
    for root, snap in _SNAPSHOTS.items():
        if run_dir == root or root in run_dir.parents:
            return snap
    snap = Snapshot.take(run_dir)
    _SNAPSHOTS[run_dir] = snap
    return snap


def release(run_dir) -> None:
    """Forget the record of a finished single run (a later run in this process takes its own)."""
    _SNAPSHOTS.pop(Path(os.path.abspath(run_dir)), None)


def undo_unstarted() -> list[Path]:
    """Undo what Hydra wrote for a command stopped before its job ran; returns the directories.

    Hydra creates the run directory and writes ``.hydra/*.yaml`` itself, not atomically:
    a full disk there leaves empty files and directories that no result needs.
    """
    roots = list(_SNAPSHOTS)
    for root in roots:
        _SNAPSHOTS.pop(root).undo()
    return roots


def _record(config: DictConfig, key: str) -> None:
    try:
        root = Path(os.path.abspath(str(OmegaConf.select(config, key))))
    except Exception:  # an interpolation only Hydra's job context can resolve: record at job start
        return
    _SNAPSHOTS[root] = Snapshot.take(root)


class RunDirGuard(Callback):
    """Hydra callback recording the output directory before Hydra creates or writes it."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        _record(config, "hydra.run.dir")

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        _record(config, "hydra.sweep.dir")
