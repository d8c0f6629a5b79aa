"""Bounds on study data, so a hostile study fails fast in one short line: what error messages
show of a value (`shown`), and how large and deep a study may be once its YAML aliases are
expanded (`check_study_data`: the reader bounds the alias *nodes*, but one 100 kB string
aliased 9,000 times is 9,000 nodes and 900 MB of study.json and messages)."""
from __future__ import annotations

import reprlib

from ..core.errors import require
from ..io.yamlfile import MAX_DEPTH

MAX_STUDY_BYTES = 32 << 20  # a study describes runs; its data (a million-value axis: 8 MB) fit
MAX_SHOWN = 80  # characters of a value an error message shows

_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlevel = MAX_SHOWN, MAX_SHOWN, 3
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6


def shown(value, limit: int = MAX_SHOWN) -> str:
    """`value` as an error message shows it: repr on one line, at most `limit` characters
    (long text, deep or long containers cut with '...'; the work is bounded as well)."""
    try:
        text = _REPR.repr(value)
    except Exception:  # noqa: BLE001 - a value whose repr fails is still named by its type
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def bounded(message: str, limit: int = 300) -> str:
    """A message from below (a scene's check) as one line of at most about `limit` characters:
    a long value it quotes is cut in the middle, its `Fix:` kept."""
    text = " ".join(str(message).split())
    if len(text) <= limit:
        return text
    cut = text.rfind(" Fix: ")
    head, fix = (text, "") if cut < 0 else (text[:cut], text[cut:])
    fix = fix if len(fix) <= limit // 2 else fix[:limit // 2 - 3] + "..."
    keep = max(40, limit - len(fix) - 5)
    return head[:keep] + " ... " + fix.lstrip() if fix else head[:keep] + " ..."


def key_name(key) -> str:
    """A mapping key as a field name in an error: itself when a short one-line text, else
    shown (a 100 kB key, a number, a list)."""
    if isinstance(key, str) and key.isprintable() and 0 < len(key) <= 40:
        return key
    return shown(key, 40)


def data_size(value, limit: int = MAX_STUDY_BYTES, max_depth: int = MAX_DEPTH) -> tuple:
    """(bytes, depth) of plain data as it expands (every value 8 bytes, text its length
    more, an array its nbytes), walked without recursion; it stops as soon as the size passes
    `limit` or the depth `max_depth`, so shared or self-containing structures stop early."""
    total, deepest, stack = 8, 0, [(value, 1)]
    while stack and total <= limit and deepest <= max_depth:
        node, depth = stack.pop()
        if isinstance(node, (str, bytes)):
            total += len(node)
            continue
        if isinstance(node, dict):
            children = [*node, *node.values()]
        elif isinstance(node, (list, tuple)):
            children = node
        else:
            nbytes = getattr(node, "nbytes", 0)  # an array's data; other objects: their slot
            total += nbytes if isinstance(nbytes, int) else 0
            continue
        deepest = max(deepest, depth)
        total += 8 * len(children)
        if total <= limit:
            stack.extend((c, depth + 1) for c in children)
    return total, deepest


def check_study_data(raw, where: str) -> None:
    """A study's data (a file's, aliases expanded, or a dict's) within MAX_STUDY_BYTES and
    nested at most MAX_DEPTH deep, before anything is built from it."""
    size, depth = data_size(raw)
    require(depth <= MAX_DEPTH, where, f"nests lists or mappings more than {MAX_DEPTH} deep",
            "flatten the structure (a study needs about 8 levels)")
    require(size <= MAX_STUDY_BYTES, where, f"expands to more than {MAX_STUDY_BYTES >> 20} MiB "
            "of data (YAML aliases `*name` repeat their anchor's value in full)",
            "write the study without multiplying large values by aliases; a study describes "
            "runs, data go in files")
