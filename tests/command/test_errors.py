"""Only errors a user can cause become one line and exit 2; a bug keeps its traceback.

Formerly ``command/validate.py`` turned every exception into a one-line "user error",
hiding genuine bugs. Decision: a bug propagates; Python ends the command with status 1
and the traceback, which also goes to the run's log when a job had started.
"""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hydra.errors import ConfigCompositionException

from mcsweep.errors import UserInputError
from mcsweep.command import schema, validate

BIN = Path(sys.executable).parent


def _boom(*args, **kwargs):
    raise ZeroDivisionError("injected bug")


def test_bug_in_a_schema_check_is_not_a_user_error(monkeypatch):
    monkeypatch.setattr(schema.CellConf, "__post_init__", _boom)
    with pytest.raises(ZeroDivisionError):
        validate.preflight(["sky=single"])


def test_bug_during_composition_is_not_a_user_error(monkeypatch):
    import hydra

    monkeypatch.setattr(hydra, "compose", _boom)
    with pytest.raises(ZeroDivisionError):
        validate.compose_config(["sky=single"])


def test_hydra_error_caused_by_a_bug_is_not_a_user_error(monkeypatch):
    import hydra

    def wrapped(*a, **k):
        try:
            _boom()
        except ZeroDivisionError as e:
            raise ConfigCompositionException("Error merging override") from e

    monkeypatch.setattr(hydra, "compose", wrapped)
    with pytest.raises(ConfigCompositionException):
        validate.compose_config(["sky=single"])


@pytest.mark.parametrize("args", [["sky=nowhere"], ["confidence=abc"], ["cell.nope=1"], ["confidence=[1"]])
def test_config_mistakes_stay_user_errors(args):
    with pytest.raises(UserInputError):
        validate.preflight(args)


def _run_with_injected_bug(tmp_path, patch: str):
    script = textwrap.dedent(f"""
        import sys
        {patch}
        from mcsweep.cli import main
        sys.argv = ["mcsweep", "hydra.run.dir={tmp_path / 'run'}", "sky=single", "magnitudes=g15"]
        main()
    """)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)


def test_cli_bug_before_the_job_gives_a_traceback_and_status_1(tmp_path):
    r = _run_with_injected_bug(tmp_path, "import mcsweep.command.schema as s; "
                                         "s.CellConf.__post_init__ = lambda self: 1 / 0")
    assert r.returncode == 1, r.stderr[-2000:]
    assert "Traceback" in r.stderr and "ZeroDivisionError" in r.stderr
    assert not (tmp_path / "run").exists()


def test_cli_bug_inside_the_job_keeps_traceback_and_writes_it_to_the_log(tmp_path):
    r = _run_with_injected_bug(tmp_path, "import mcsweep.command.provenance as p; "
                                         "p.Provenance.check_compatible = lambda self: 1 / 0")
    assert r.returncode == 1, r.stderr[-2000:]
    assert "ZeroDivisionError" in r.stderr and "mcsweep: error" not in r.stderr
    log = "".join(p.read_text() for p in (tmp_path / "run").glob("*.log"))
    assert "Traceback" in log and "ZeroDivisionError" in log
