"""Config keys that were renamed keep working under their old names.

A key's name is a contract: command lines and scripts written before a rename must still
run, and run directories made before it must resume. So an override naming a key by its
old name is rewritten to the new name before Hydra composes the config (with one warning
line), and the config hash is computed with the old name (:func:`to_old_names`), so it is
the hash of the same config before the rename. The renames come from the experiments'
specs (:attr:`mcsweep.experiments.spec.ExperimentSpec.renamed_keys`).
"""

from __future__ import annotations

from ..experiments.registry import renamed_keys

__all__ = ["with_new_names", "to_old_names"]


def _key_of(token: str) -> tuple[str, str, str]:
    """(prefix such as '+' or '~', dotted key, rest from '=' on) of an override token."""
    head, eq, value = token.partition("=")
    prefix = head[: len(head) - len(head.lstrip("+~"))]
    return prefix, head[len(prefix):], eq + value


def with_new_names(argv: list[str]) -> tuple[list[str], list[str]]:
    """``argv`` with every override of a renamed key under its new name, and one warning
    line per renamed key used."""
    renames = renamed_keys()
    out, notes = [], []
    for tok in argv:
        prefix, key, rest = _key_of(tok)
        new = renames.get(key)
        if tok.startswith("-") or new is None:
            out.append(tok)
            continue
        out.append(f"{prefix}{new}{rest}")
        note = f"{key} is deprecated: use {new} (the same setting; the config hash does not change)"
        if note not in notes:
            notes.append(note)
    return out, notes


def to_old_names(cfg: dict) -> dict:
    """``cfg`` (a resolved config as a dict) with every renamed key back under its old name,
    the dicts on the way copied: the form its hash is computed in."""
    out = cfg
    for old, new in renamed_keys().items():
        *new_parents, new_leaf = new.split(".")
        *old_parents, old_leaf = old.split(".")
        node = out
        for k in new_parents:
            node = node.get(k) if isinstance(node, dict) else None
        if not isinstance(node, dict) or new_leaf not in node or new_parents != old_parents:
            continue
        out = dict(out)
        node = out
        for k in new_parents:
            node[k] = dict(node[k])
            node = node[k]
        node[old_leaf] = node.pop(new_leaf)
    return out
