"""The execution backend's worker release (sweep.execution.executor)."""

from __future__ import annotations

import os
import sys

import pytest

from mcsweep.runtime.execution import executor
from mcsweep.command.schema import ExecutionConf


def _children() -> set[str]:
    return set(open(f"/proc/{os.getpid()}/task/{os.getpid()}/children").read().split())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_release_workers_ends_the_loky_processes():
    # Without release joblib keeps loky's workers for reuse (they outlive the context);
    # with it, the processes the context started are gone when it ends.
    conf = ExecutionConf(backend="loky", n_jobs=2)
    with executor(conf, release_workers=True) as run:
        assert sorted(run(abs, range(-4, 4))) == sorted(abs(i) for i in range(-4, 4))
        during = _children()
    kept = {c for c in during if os.path.exists(f"/proc/{c}")}
    with executor(conf) as run:
        list(run(abs, range(8)))
    started = _children() - during
    assert started  # the next context's workers live on after it
    assert len(kept) < len(during)  # the released context's workers did not
