"""Mesh files read through the input gate (nlos_cl.core.gate): OBJ, STL, PLY, OFF, glTF and GLB,
plain or gzip/bz2/xz-compressed or in a zip/tar archive.

Before trimesh parses a byte: the file (and every asset it names: a glTF's buffers) must be a
regular file, and everything it expands to (decompressed bytes, archive members, a glTF's
buffers and declared accessors) must fit a budget of memory_limit() / PARSE_FACTOR bytes; the
counts a format declares (an STL's triangles, a PLY's elements, an OFF's counts, a GLB's length)
must be held by the file, and an OBJ must end with its last line whole, so that a file cut short
is refused rather than simulated as the few faces before the cut. Materials and textures are
never read (only geometry is simulated), so no image is decoded and no mtllib opened."""
from __future__ import annotations

import io
import json
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import trimesh

from ..core import gate
from ..core.errors import InputError, require
from ..core.limits import memory_limit, require_memory

FORMATS = ("obj", "stl", "ply", "off", "glb", "gltf")
# parsing costs at most this many times the file's bytes (a binary STL: 50 bytes a triangle,
# ~250 in trimesh's vertices, faces, normals and merge; text formats cost less per byte)
PARSE_FACTOR = 8
FIX = "pass a whole mesh file (OBJ, STL, PLY, OFF, GLB or glTF) as a regular file"
_GLTF_SIZES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_GLTF_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9,
                    "MAT4": 16}


class _Assets(trimesh.resolvers.Resolver):
    """What a mesh names beside itself (a glTF's buffers), through the gate: regular files in
    the mesh's own folder (or members of its archive), within what is left of the budget."""

    def __init__(self, where: str, folder: Path | None, members: dict, budget: int):
        self.where, self.folder, self.members, self.left = where, folder, members, budget

    def get(self, name):
        name = unquote(str(name)).replace("\\", "/")
        label = f"{self.where}: asset {name[:80]!r}"
        if self.folder is None:  # an archive: its own members only
            key = next((k for k in self.members if k == name or k.endswith("/" + name)), None)
            require(key is not None, label, "is not in the archive", FIX)
            data = self.members[key]
        else:
            path = (self.folder / name).resolve()
            require(path.is_relative_to(self.folder.resolve()), label, "lies outside the "
                    "mesh's folder, which nlos_cl does not read", "keep the mesh's buffers "
                    "beside it (relative names)")
            with gate.open_regular(path, label, "make the asset a regular file beside the "
                                   "mesh") as fh:
                data = gate.read_bounded(fh, self.left, label)
        require(len(data) <= self.left, label, "takes the mesh past its memory budget", FIX)
        self.left -= len(data)
        return data

    def keys(self):
        return list(self.members)

    def write(self, name, data):
        raise InputError(f"{self.where}: asks to write {name!r}. Fix: {FIX}")

    def namespaced(self, namespace):
        return self


def read_mesh(path) -> trimesh.Trimesh:
    """The one mesh in `path` (see the module docstring), or an InputError naming the file."""
    path = Path(path)
    where = f"mesh file {path}"
    budget = max(memory_limit() // PARSE_FACTOR, 1)
    members, kind = gate.read_all(path, budget, where, FIX)
    meshes = [n for n in members if _format(n) in FORMATS]
    require(len(meshes) == 1, where, f"holds {len(meshes)} mesh files"
            + (f" ({', '.join(sorted(meshes)[:4])})" if meshes else
               f" of {', '.join(FORMATS)} (a {Path(next(iter(members), '?')).suffix or 'file'} "
               "without a known mesh suffix)"), FIX if len(meshes) == 0 else
            "pass an archive holding one mesh, or the mesh file itself")
    name = meshes[0]
    data, fmt = members[name], _format(name)
    require_memory(where, PARSE_FACTOR * float(sum(map(len, members.values()))),
                   f"parsing {name}", "pass a smaller mesh")
    assets = _Assets(where, path.parent if kind is None else None, members,
                     budget - len(data))
    options = {"skip_materials": True} if fmt in ("obj", "glb", "gltf") else {}
    try:
        DECLARED[fmt](data, where, assets)  # counts and cuts, before trimesh parses a byte
        loaded = trimesh.load(io.BytesIO(data), file_type=fmt, resolver=assets, force="mesh",
                              **options)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types for bad files
        raise InputError(f"{where}: could not be read ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:160]}). Fix: {FIX}") from None
    require(isinstance(loaded, trimesh.Trimesh) and len(loaded.faces) > 0, where,
            "holds no triangles", "pass a file with a surface mesh")
    if fmt == "obj":
        _obj_faces_kept(data, loaded, where)
    require(bool(np.all(np.isfinite(loaded.vertices))), where, "has vertices that are NaN "
            "or inf", "pass a mesh with finite coordinates")
    return loaded


def _format(name: str) -> str:
    return Path(name).suffix.lower().lstrip(".")


def _cut(where: str, problem: str) -> InputError:
    return InputError(f"{where}: {problem}: the file is cut short (truncated) or damaged. "
                      "Fix: copy or export the whole mesh again")


def _stl(data: bytes, where: str, _assets) -> None:
    """Binary: the header's count of 50-byte triangles is held; ASCII: `endsolid` closes it."""
    head = data[:512].lstrip().lower()
    n = struct.unpack("<I", data[80:84])[0] if len(data) >= 84 else -1
    if head.startswith(b"solid") and (n < 0 or len(data) != 84 + 50 * n):
        if b"endsolid" not in data[-1024:].lower():
            raise _cut(where, "an ASCII STL without its closing `endsolid`")
        opened, closed = data.lower().count(b"facet normal"), data.lower().count(b"endfacet")
        if opened != closed:
            raise _cut(where, f"an ASCII STL with {opened} facets opened, {closed} closed")
        return
    if n < 0 or len(data) < 84 + 50 * n:
        raise _cut(where, f"a binary STL declaring {max(n, 0):,} triangles "
                   f"({84 + 50 * max(n, 0):,} bytes) in {len(data):,} bytes")


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2,
              "int16": 2, "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4,
              "float": 4, "float32": 4, "double": 8, "float64": 8}


def _ply(data: bytes, where: str, _assets) -> None:
    """The header's elements are held by the body: binary, at least their smallest rows'
    bytes (a face list of 3); ASCII, a line each."""
    end = data.find(b"end_header")
    require(data.startswith(b"ply") and end > 0, where, "is not a PLY file (no `ply` ... "
            "`end_header` header)", FIX)
    header = data[:end].decode("latin-1").split("\n")
    body = data[data.index(b"\n", end) + 1:] if b"\n" in data[end:] else b""
    fmt = next((ln.split()[1] for ln in header if ln.startswith("format ")), "ascii")
    elements = []  # (name, count, smallest row bytes, values in a row)
    for line in header:
        words = line.split()
        if words[:1] == ["element"] and len(words) == 3 and words[2].isdigit():
            elements.append([words[1], int(words[2]), 0, 0])
        elif words[:1] == ["property"] and elements:
            list_of = words[1] == "list" and len(words) >= 5
            size = _PLY_SIZES.get(words[2 if list_of else 1], 4)
            elements[-1][2] += _PLY_SIZES.get(words[2], 1) + 3 * _PLY_SIZES.get(words[3], 4) \
                if list_of else size
            elements[-1][3] += 4 if list_of else 1
    if fmt == "ascii":
        have, need = len(body.split(b"\n")) - (1 if body.endswith(b"\n") else 0), \
            sum(e[1] for e in elements)
        what = "lines"
    else:
        have, need, what = len(body), sum(e[1] * e[2] for e in elements), "bytes"
    if have < need:
        raise _cut(where, f"a PLY whose header declares "
                   f"{', '.join(f'{e[1]:,} {e[0]}' for e in elements)} ({need:,} {what} at "
                   f"least) with {have:,} {what} after it")


def _off(data: bytes, where: str, _assets) -> None:
    """The counts line (vertices, faces) is held: 3 numbers a vertex, 4 at least a face."""
    lines = [ln.split(b"#")[0].split() for ln in data.split(b"\n")]
    words = [w for ln in lines for w in ln]
    require(len(words) >= 4 and words[0].endswith(b"OFF"), where, "is not an OFF file (no "
            "`OFF` and counts)", FIX)
    try:
        nv, nf = int(words[1]), int(words[2])
    except ValueError:
        raise InputError(f"{where}: its OFF counts {words[1:3]} are not numbers. Fix: {FIX}"
                         ) from None
    have = len(words) - 4
    if have < 3 * nv + 4 * nf:
        raise _cut(where, f"an OFF declaring {nv:,} vertices and {nf:,} faces in {have:,} "
                   "numbers")


def _obj(data: bytes, where: str, _assets) -> None:
    """An OBJ has no counts: its last statement must end with a line break, or the cut fell
    inside it (`f 1 2 3` of `f 1 2 34`)."""
    if data.rstrip(b" \t") and not data.rstrip(b" \t").endswith((b"\n", b"\r")):
        last = data.rsplit(b"\n", 1)[-1].decode("latin-1", "replace").strip()[:40]
        raise InputError(f"{where}: its last line {last!r} does not end with a line break: the "
                         "file may be cut short (truncated). Fix: copy or export the whole "
                         "mesh again (a complete file written by hand: end it with a newline)")


def _obj_faces_kept(data: bytes, mesh, where: str) -> None:
    """Every `f` statement gave at least one triangle: one naming a vertex the file does not
    hold (cut before it, or a wrong index) is refused, never dropped."""
    stated = sum(1 for line in data.split(b"\n") if line.lstrip()[:2] == b"f ")
    require(len(mesh.faces) >= stated, where, f"states {stated:,} faces but only "
            f"{len(mesh.faces):,} triangles could be built (faces naming vertices the file "
            "does not hold)", "copy or export the whole mesh again")


def _gltf_json(data: bytes, where: str) -> dict:
    if data[:4] == b"glTF":
        require(len(data) >= 20, where, "is a GLB shorter than its header", FIX)
        declared, size = struct.unpack("<I", data[8:12])[0], struct.unpack("<I", data[12:16])[0]
        if len(data) < declared or len(data) < 20 + size:
            raise _cut(where, f"a GLB declaring {declared:,} bytes in {len(data):,}")
        data = data[20:20 + size]
    try:
        tree = json.loads(data.decode("utf-8-sig"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise InputError(f"{where}: its glTF JSON cannot be read ({str(exc)[:80]}). Fix: {FIX}"
                         ) from None
    require(isinstance(tree, dict), where, "is not a glTF document (its JSON is no object)", FIX)
    return tree


def _gltf(data: bytes, where: str, assets: _Assets) -> None:
    """Buffers and accessors (what trimesh allocates: a bufferless or sparse accessor is
    filled with zeros of its declared count) within the budget left."""
    tree = _gltf_json(data, where)
    try:
        declared = sum(int(b.get("byteLength", 0)) for b in tree.get("buffers", []))
        for a in tree.get("accessors", []):
            declared += int(a.get("count", 0)) * _GLTF_SIZES.get(a.get("componentType"), 8) * \
                _GLTF_COMPONENTS.get(a.get("type"), 16)
    except (TypeError, ValueError, AttributeError):
        raise InputError(f"{where}: its glTF buffers or accessors are malformed. Fix: {FIX}"
                         ) from None
    require(declared <= assets.left, where, f"declares {declared / 2**20:.4g} MiB of buffers "
            f"and accessors, more than the {assets.left / 2**20:.4g} MiB a mesh may take",
            "pass a smaller mesh, or raise NLOS_CL_MEMORY_LIMIT if it is genuine")


DECLARED = {"stl": _stl, "ply": _ply, "off": _off, "obj": _obj, "glb": _gltf, "gltf": _gltf}
