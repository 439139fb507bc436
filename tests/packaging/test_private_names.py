"""No module reaches into another's private names: a leading underscore means "only this
module uses it", so the name can change without a search of the whole tree. Checked on the
syntax trees of the package, the tests, the benchmarks and the docs' scripts: a
``from ... import _name`` of an mcsweep module, or ``module._name`` where ``module`` is an
imported mcsweep module."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TREES = ("src", "tests", "benchmarks", "docs/scripts")


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_uses(path: Path) -> list[str]:
    """``file:line what`` of each private name of another mcsweep module used in ``path``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    modules, found = set(), []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level > 0 or (node.module or "").startswith("mcsweep")):
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"{path}:{node.lineno} imports {alias.name}")
                modules.add(alias.asname or alias.name)
        elif isinstance(node, ast.Import):
            modules.update((a.asname or a.name).split(".")[0] for a in node.names if a.name.startswith("mcsweep"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr) and isinstance(node.value, ast.Name) \
                and node.value.id in modules:
            found.append(f"{path}:{node.lineno} uses {node.value.id}.{node.attr}")
    return found


def test_the_checker_sees_both_forms(tmp_path):
    f = tmp_path / "probe.py"
    f.write_text("from mcsweep.solver import problem as P\nfrom .blocks import _rows\nx = P._hidden\ny = P.shown\n")
    assert [u.split(" ", 1)[1] for u in private_uses(f)] == ["imports _rows", "uses P._hidden"]


def test_no_private_name_is_used_across_modules():
    files = sorted(p for tree in TREES for p in (ROOT / tree).rglob("*.py"))
    assert len(files) > 100
    found = [u for f in files for u in private_uses(f)]
    assert found == []
