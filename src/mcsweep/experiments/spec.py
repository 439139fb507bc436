"""What the registry (:mod:`mcsweep.experiments.registry`) knows of one experiment.

An experiment lives in one folder, ``experiments/<kind>/``, whose ``__init__`` describes it
with an :class:`ExperimentSpec`: its config sections (light dataclasses, so that composing
and checking a config does not import the science), how to run it, which files it writes,
which of them its report reads, its report section, and the config keys it never reads.
The run and the report are imported only when called.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

__all__ = ["ExperimentSpec", "REPORT_FILES"]

#: What every run directory gets besides an experiment's results (written by the report
#: and by provenance).
REPORT_FILES = ("figures", "report.md", "report.html", "provenance.json")


@dataclass(frozen=True)
class ExperimentSpec:
    #: ``experiment=<kind>`` on the command line; ``kind`` in provenance.json.
    kind: str
    #: One line for the list of experiments (``experiment=`` values and what they are).
    title: str
    #: The config sections it reads under ``experiment.``: name -> dataclass.
    sections: Mapping[str, type]
    #: (config, raw config dict, run directory, Provenance) -> path of the main result.
    run: Callable[[Any, dict, Path, Any], Path]
    #: (Document, run directory, provenance dict) -> None: its section of the report.
    report: Callable[[Any, Path, dict], None]
    #: (config, config hash, run directory) -> what a rerun keeps, for the one line of a
    #: stopped command.
    kept: Callable[[Any, str, Path], str]
    #: The files and directories it writes in the run directory (its report's aside).
    outputs: tuple[str, ...]
    #: The outputs its report section reads: all must exist before a report is written.
    report_reads: tuple[str, ...]
    #: Config keys outside ``experiment.`` that it never reads (left out of its config hash;
    #: a command line setting them gets a warning). Other experiments' sections are left
    #: out without being listed here.
    ignores: tuple[str, ...] = ()
    #: Other experiments' sections that stay in its config hash although it does not read
    #: them: hashes of run directories made before the registry included them, and a
    #: changed hash would make those runs refuse to resume.
    hashed_sections: tuple[str, ...] = ()
    #: dotted key -> the value that reproduces the model from before the option existed:
    #: left out of the hash at that value, so runs made before the option keep their hash.
    defaults_from_before: Mapping[str, Any] = field(default_factory=dict)
    #: dotted key -> the key without which it has no effect (left out while that is null).
    only_with: Mapping[str, str] = field(default_factory=dict)
    #: Renamed config keys, old dotted name -> new: the old name still works on the command
    #: line (with a one-line deprecation warning), and the hash is computed under the old
    #: name, so runs made before the rename keep their hash and resume.
    renamed_keys: Mapping[str, str] = field(default_factory=dict)

    @property
    def all_outputs(self) -> tuple[str, ...]:
        """Every name a finished run of it has in its run directory."""
        return tuple(dict.fromkeys(self.outputs + REPORT_FILES))
