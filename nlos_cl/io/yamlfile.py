"""The one YAML reader for what users give nlos_cl (scene files, study files, a capture's
scene_info): PyYAML's SafeLoader with YAML 1.2 floats, and bounds on what a short description
can make, checked while it is composed so a hostile file fails fast in one line:

- aliases (`*name`) may repeat a block, not multiply it: all of them together may add at most
  ALIAS_NODES nodes (a 9-level "billion laughs" of 9 aliases each would make 9^9 = 387 M) and
  MAX_BYTES characters of text (one 100 kB string aliased 9,000 times made 900 MB of study.json
  or error message);
  an alias inside its own anchor (a structure containing itself) is refused;
- nesting deeper than MAX_DEPTH is refused (PyYAML's composer recurses, so 20,000 nested
  brackets end in RecursionError);
- a key written twice in one mapping is refused (PyYAML keeps the last one silently: a second
  `targets:` would replace the first);
- the text must be UTF-8 (a UTF-8 BOM is fine); UTF-16/32 files are named as such.
"""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

from ..core.errors import InputError, require, shown

ALIAS_NODES = 10_000  # nodes all aliases together may add (a scene or study needs a few dozen)
MAX_DEPTH = 64  # nested lists/mappings (a scene file needs about 6)
MAX_BYTES = 1 << 20  # a description, not data (meshes live in their own files)
_FLOAT_1_2 = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


class YamlLimit(Exception):
    """A bound of this module broken: problem and fix, for InputError's one line."""

    def __init__(self, problem: str, fix: str):
        super().__init__(f"{problem}. Fix: {fix}")
        self.problem, self.fix = problem, fix


def yaml_loader():
    """PyYAML's SafeLoader, with `1e-11` a number (YAML 1.2; YAML 1.1 wants a dot in the
    mantissa, so `10e-12` would silently be text) and the bounds of the module docstring."""
    import yaml
    from yaml.events import AliasEvent, CollectionStartEvent

    class Loader(yaml.SafeLoader):
        def __init__(self, stream):
            super().__init__(stream)
            self._depth, self._added, self._open, self._sizes = 0, (0, 0), set(), {}

        def compose_node(self, parent, index):
            event = self.peek_event()
            line = event.start_mark.line + 1
            if isinstance(event, AliasEvent):
                self._alias(event.anchor, line)
                return super().compose_node(parent, index)
            self._depth += 1
            if self._depth > MAX_DEPTH:
                raise YamlLimit(f"nests lists or mappings more than {MAX_DEPTH} deep (line "
                                f"{line})", "flatten the structure (a scene file needs ~6 levels)")
            anchor = event.anchor if isinstance(event, CollectionStartEvent) else None
            self._open.add(anchor)
            try:
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1
                self._open.discard(anchor)

        def _alias(self, anchor, line):
            if anchor in self._open:
                raise YamlLimit(f"the alias *{_name(anchor)} (line {line}) is inside its own "
                                f"anchor &{_name(anchor)}, a structure that contains itself",
                                "write the values out instead of the alias")
            if anchor in self.anchors:
                nodes, chars = _size(self.anchors[anchor], self._sizes)
                self._added = (self._added[0] + nodes, self._added[1] + chars)
            if self._added[0] > ALIAS_NODES or self._added[1] > MAX_BYTES:
                what = (f"{ALIAS_NODES} values" if self._added[0] > ALIAS_NODES else
                        f"{MAX_BYTES >> 20} MiB of text")
                raise YamlLimit(f"its aliases expand to more than {what} (line {line}, "
                                f"*{_name(anchor)}): an alias may repeat a block, not multiply it",
                                "write the values out, or use fewer nested aliases")

        def construct_mapping(self, node, deep=False):
            _no_duplicate_keys(self, node)
            return super().construct_mapping(node, deep=deep)

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_1_2, list("-+0123456789."))
    return Loader


def _size(node, sizes: dict) -> tuple[int, int]:
    """(nodes, characters of scalar text) `node` stands for once its aliases are expanded
    (memoised per node, so this stays linear in the file however the aliases nest)."""
    import yaml
    if id(node) not in sizes:
        if isinstance(node, yaml.SequenceNode):
            parts = [_size(n, sizes) for n in node.value]
        elif isinstance(node, yaml.MappingNode):
            parts = [_size(n, sizes) for pair in node.value for n in pair]
        else:
            parts = [(0, len(str(node.value)))]
        sizes[id(node)] = (1 + sum(p[0] for p in parts), sum(p[1] for p in parts))
    return sizes[id(node)]


def _no_duplicate_keys(loader, node) -> None:
    import yaml
    seen = {}
    for key_node, _ in node.value:
        if not isinstance(key_node, yaml.ScalarNode) or key_node.tag.endswith(":merge"):
            continue  # `<<:` merges are meant to be overridden; complex keys PyYAML refuses
        key, line = loader.construct_object(key_node), key_node.start_mark.line + 1
        try:
            again = key in seen
        except TypeError:  # an unhashable key: PyYAML's own error follows
            continue
        if again:
            raise YamlLimit(f"the key {shown(key)} appears twice in one mapping (lines {seen[key]} "
                            f"and {line}); YAML would silently keep only the last",
                            "keep one of them (merge the two entries)")
        seen[key] = line


def _name(anchor) -> str:
    """An anchor's name as messages echo it (a name may be 100 kB long)."""
    text = shown(str(anchor))
    return text[1:-1] if text[:1] in "'\"" and text[-1:] == text[:1] else text


def _yaml_problem(exc) -> str:
    """PyYAML's error as what and where, without its quote of the line (a line may be a
    100 kB value); the problem's own echo shortened."""
    problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or str(exc)
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    place = f" on line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    text = " ".join(str(problem).split())
    return (text if len(text) <= 120 else shown(text, 120)) + place


def decode(data: bytes, where: str) -> str:
    """UTF-8 text (a BOM is dropped); UTF-16/32 and other encodings are named in the error."""
    boms = ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
            (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16"))
    kind = next((name for bom, name in boms if data.startswith(bom)), None)
    if kind is None and len(data) >= 4 and data[:4].count(0) in (2, 3):
        kind = "UTF-16 or UTF-32"  # no BOM, but ASCII text with a zero byte beside each letter
    require(kind is None, where, f"is {kind} text, but nlos_cl reads YAML as UTF-8",
            "save it as UTF-8 (an editor's 'Save as... UTF-8', or iconv -f UTF-16 -t UTF-8)")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise InputError(f"{where}: is not UTF-8 text (byte 0x{data[exc.start]:02x} on line "
                         f"{line}; Latin-1 or Windows-1252, perhaps). Fix: save it as UTF-8"
                         ) from None


def load_text(text, where: str):
    """Parse YAML text (or UTF-8 bytes) with yaml_loader; every error is one InputError line."""
    import yaml
    if isinstance(text, (bytes, bytearray)):
        text = decode(bytes(text), where)
    try:
        return yaml.load(text, Loader=yaml_loader())
    except YamlLimit as exc:
        raise InputError(f"{where}: {exc.problem}. Fix: {exc.fix}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{where}: is not valid YAML ({_yaml_problem(exc)}). Fix: check the "
                         "indentation and brackets near that line") from None


def read_yaml(path, what: str = "scene file") -> dict:
    """A short YAML file (scene, study) as a mapping; at most MAX_BYTES are read."""
    from .safe_write import require_file
    path = Path(path)
    where = f"{what} {path}"
    require_file(path, where, "pass a .yaml file")
    with open(path, "rb") as fh:
        data = fh.read(MAX_BYTES + 1)
    require(len(data) <= MAX_BYTES, where, f"is larger than {MAX_BYTES >> 20} MiB",
            "it is a short description; meshes go in their own files")
    require(b"\x00" not in data or data[:2] in (b"\xff\xfe", b"\xfe\xff") or
            data[:4].count(0) in (2, 3), where, "is not a text file (it holds zero bytes)",
            "pass the YAML file itself")
    raw = load_text(decode(data, where), where)
    require(isinstance(raw, dict), where, "is not a mapping of keys",
            "write `key: value` lines (docs/scene-files.md, docs/sweeps.md)")
    return raw


# ---------------------------------------------------------------- JSON: the YAML nlos_cl writes

def dump_json_yaml(data: dict) -> str:
    """`data` as one line of JSON that PyYAML (YAML 1.1, as y-tal reads scene_info), nlos_cl's
    reader and a JSON parser all read to the same values, or PyYAML's block style where it
    cannot be (NaN, infinities, types JSON lacks, text PyYAML reads otherwise). Why: reading
    JSON needs no PyYAML, whose import is ~11 ms of a one-shot `nlos-cl locate`.
    JSON is YAML 1.2; for YAML 1.1 a float's mantissa needs a dot (1.0e-11, not 1e-11), and
    the text is checked by parsing it both ways before it is used."""
    import yaml
    try:
        text = "{" + ", ".join(f"{_json_key(k)}: {_json(v)}" for k, v in data.items()) + "}"
        if json.loads(text) == yaml.load(text, Loader=getattr(yaml, "CSafeLoader",
                                                              yaml.SafeLoader)):
            return text + "\n"
    except (TypeError, ValueError, yaml.YAMLError):
        pass
    return yaml.safe_dump(data)


def load_json_yaml(text: str):
    """What dump_json_yaml wrote (a JSON object), read without PyYAML; None where `text` is
    not a JSON object, or holds a key twice, NaN or Infinity (the YAML reader then decides,
    with its bounds and its errors). JSON is a subset of YAML 1.2: the values are YAML's."""
    if not text.lstrip().startswith("{"):
        return None
    try:
        data = json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_not_yaml)
    except (ValueError, RecursionError):  # RecursionError: deep nesting, which YAML refuses
        return None
    return data if _depth(data) <= MAX_DEPTH else None  # the YAML reader's bound, and error


def _depth(data) -> int:
    """How deep lists and mappings nest in `data` (a parsed JSON value), without recursion."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, (dict, list)):
            deepest = max(deepest, depth)
            stack.extend((v, depth + 1) for v in (value.values() if isinstance(value, dict)
                                                   else value))
    return deepest


def _json(value) -> str:
    import numpy as np
    if value is None or isinstance(value, (bool, np.bool_)):
        return {None: "null", True: "true", False: "false"}[None if value is None else
                                                            bool(value)]
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value):
            raise ValueError("JSON has no NaN or infinity")
        text = repr(float(value))
        mantissa, e, exponent = text.partition("e")
        return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text
    if isinstance(value, str):  # raw UTF-8 (PyYAML does not join json's surrogate pairs)
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_json_key(k)}: {_json(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_json(v) for v in value) + "]"
    raise TypeError(f"{type(value).__name__} is not JSON")


def _json_key(key) -> str:
    if not isinstance(key, str):
        raise TypeError("JSON keys are text")
    return json.dumps(key, ensure_ascii=False)


def _unique_keys(pairs):
    keys = [k for k, _ in pairs]
    if len(set(keys)) != len(keys):
        raise ValueError("a key twice")  # YAML's reader names it (nlos_cl.io.yamlfile)
    return dict(pairs)


def _not_yaml(name):
    raise ValueError(f"{name} is not YAML")


# ---------------------------------------------------------------- values as YAML gives them

def is_number(value) -> bool:
    """A finite number: not text, and not a bool (YAML's `true` is an int in Python)."""
    import math

    import numpy as np
    return isinstance(value, (int, float, np.integer, np.floating)) and \
        not isinstance(value, (bool, np.bool_)) and math.isfinite(value)


def whole_number(where: str, value, low=1, high=1 << 16, example=8) -> int:
    """An integer in low..high, written as one (2.7 is refused, not truncated to 2)."""
    import numpy as np
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    require(ok and low <= value <= high, where, f"expected a whole number in {low}..{high}, got "
            f"{shown(value)}", f"write e.g. {example}")
    return int(value)
