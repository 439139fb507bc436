import os

import pytest
from hypothesis import settings

# Derandomised Hypothesis in CI so a red build is reproducible (astropy does the same).
settings.register_profile("ci", derandomize=True, deadline=None, max_examples=50)
settings.register_profile("dev", deadline=None, max_examples=50)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(20150821)


#: Printed at the top of every run (and so of CI's log): CI resolves the newest releases
#: on the day it runs, and a drift in one of these is the first thing to look at.
KEY_PACKAGES = ("numpy", "scipy", "astropy", "pandas", "pyarrow", "hydra-core", "joblib", "matplotlib",
                "dask", "distributed")


def pytest_report_header(config):
    from importlib.metadata import PackageNotFoundError, version

    def v(name):
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    return "resolved packages: " + ", ".join(f"{name} {v(name)}" for name in KEY_PACKAGES)


@pytest.fixture(scope="module")
def dask_local_client():
    """A Client of a LocalCluster of 2 single-threaded worker processes (one per module: the
    worker-loss tests kill and restart its workers)."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                       env={"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"})
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture
def kill_worker_at(dask_local_client):
    """``log = kill_worker_at(k)``: a PCG log callback that kills one worker process of the
    module's LocalCluster at iteration ``k`` (once); ``log.killed`` says whether it did."""
    import signal

    def make(iteration: int):
        victim = sorted(dask_local_client.run(os.getpid).values())[0]

        def log(rec):
            if rec.iteration == iteration and not log.killed:
                os.kill(victim, signal.SIGKILL)
                log.killed = True

        log.killed = False
        return log

    return make
