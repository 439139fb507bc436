"""A throwaway experiment defined outside the package, as a user's or a test's would be: this
folder, one :func:`mcsweep.experiments.registry.register` call and one YAML
(``conf/experiment/throwaway.yaml``, found through ``hydra.searchpath``).

It draws ``n_chunks`` x ``per_chunk`` standard normal numbers, one chunk per store entry
(so a rerun resumes), and writes their mean and standard deviation with the standard
error of the mean, sigma / sqrt(n).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mcsweep.experiments.config_checks import require
from mcsweep.experiments.spec import ExperimentSpec

CHUNKS_DIR = "throwaway_chunks"
TABLE = "throwaway.csv"
TAG = 99  # first element of its spawn keys, unused by the built-in experiments (41-43)


@dataclass
class ThrowawayConf:
    n_chunks: int = 4
    per_chunk: int = 500

    def __post_init__(self):
        require(self.n_chunks > 0, "experiment.throwaway.n_chunks", self.n_chunks, "a positive number of chunks")
        require(self.per_chunk > 1, "experiment.throwaway.per_chunk", self.per_chunk, "at least 2 draws per chunk")


def _chunk_id(i: int) -> str:
    return f"chunk{i:04d}"


def run(config, raw_cfg: dict, run_dir: Path, prov) -> Path:
    import numpy as np
    import pandas as pd

    from mcsweep.runtime.store import ResultStore, atomic_write_bytes

    sec = config.experiment.throwaway
    store = ResultStore(Path(run_dir) / CHUNKS_DIR, prov.hash, accept_other_versions=config.resume.accept_other_versions)
    with prov.stage("draws"):
        for i in range(sec.n_chunks):
            if store.read(_chunk_id(i)) is None:
                rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(TAG, i)))
                store.write(_chunk_id(i), pd.DataFrame({"x": rng.standard_normal(sec.per_chunk)}))
    with prov.stage("aggregate"):
        x = pd.concat([store.read(_chunk_id(i)) for i in range(sec.n_chunks)])["x"].to_numpy()
        table = pd.DataFrame({"n": [x.size], "mean": [x.mean()], "std": [x.std(ddof=1)],
                              "mean_error": [x.std(ddof=1) / np.sqrt(x.size)]})
        atomic_write_bytes(Path(run_dir) / TABLE, table.to_csv(index=False).encode())
    prov.seeds["throwaway"] = f"SeedSequence(seed, spawn_key=({TAG}, chunk))"
    return Path(run_dir) / TABLE


def report(doc, run_dir: Path, prov: dict) -> None:
    import pandas as pd

    doc.heading("Throwaway experiment")
    doc.table(pd.read_csv(Path(run_dir) / TABLE), "Mean of standard normal draws", {"mean": ".4f", "std": ".4f"})


def kept(config, config_hash: str, run_dir: Path) -> str:
    from mcsweep.runtime.store import ResultStore

    done = ResultStore(Path(run_dir) / CHUNKS_DIR, config_hash).finished()
    return f"{len(done)} of {config.experiment.throwaway.n_chunks} chunks kept in {run_dir}"


SPEC = ExperimentSpec(
    kind="throwaway", title="a test's throwaway experiment", sections={"throwaway": ThrowawayConf}, run=run,
    report=report, kept=kept, outputs=(CHUNKS_DIR, TABLE), report_reads=(TABLE,),
    ignores=("sky", "magnitudes", "prior_grid", "cell", "observations", "noise", "population", "scanning",
             "prior_maps"))
