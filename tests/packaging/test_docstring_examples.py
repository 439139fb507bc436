"""The docstring examples of the public API run, as written: every ``>>>`` in ``src/mcsweep``
is executed by :mod:`doctest`. Printed floats marked ``# doctest: +FLOAT_CMP`` (the astropy
convention) are compared number by number to a relative :data:`FLOAT_RTOL`, the rest exactly."""

import doctest
import importlib
import pkgutil
import re

import pytest

import mcsweep

#: Relative agreement of printed floats under FLOAT_CMP (the printed digits, not the library's).
FLOAT_RTOL = 1e-7
FLOAT_CMP = doctest.register_optionflag("FLOAT_CMP")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


class _Checker(doctest.OutputChecker):
    def check_output(self, want, got, optionflags):
        if not optionflags & FLOAT_CMP:
            return super().check_output(want, got, optionflags)
        if _NUMBER.sub("#", want).split() != _NUMBER.sub("#", got).split():
            return False
        pairs = zip(_NUMBER.findall(want), _NUMBER.findall(got))
        return all(float(g) == pytest.approx(float(w), rel=FLOAT_RTOL) for w, g in pairs)


def _modules_with_examples():
    for info in pkgutil.walk_packages(mcsweep.__path__, "mcsweep."):
        spec = importlib.util.find_spec(info.name)
        if spec and spec.origin and spec.origin.endswith(".py") and ">>>" in open(spec.origin).read():
            yield info.name


MODULES = sorted(_modules_with_examples())


def test_there_are_examples_to_run():
    assert "mcsweep.prior.model" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    finder, runner = doctest.DocTestFinder(), doctest.DocTestRunner(checker=_Checker(), optionflags=doctest.ELLIPSIS)
    tests = [t for t in finder.find(module) if t.examples]
    assert tests
    for t in tests:
        runner.run(t)
    assert runner.failures == 0, f"{runner.failures} failing example(s) in {name}"
