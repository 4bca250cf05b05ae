"""Checking readers for the surface formats whose VTK 9.1 readers trust the file: PLY and OBJ.

``vtkPLYReader`` crashes (segfault, double free) on a truncated file or one whose header declares
more elements than the file holds; ``vtkOBJReader`` reads a face's out-of-range vertex index from
out-of-bounds memory. These readers check every count against the bytes that follow, every index
against the vertices read, and raise ValueError naming the file, the element and the line or
record; the mesh they return equals VTK's for a valid file (tests/python/test_reliability_readers.py
compares them on every mesh of the shared data).

Not public API: ``matrixtree.read_mesh`` calls them.
"""

from __future__ import annotations

import os
import struct

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtkIdTypeArray
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

from matrixtree._util import vtk_points

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_FACE_LISTS = ("vertex_indices", "vertex_index")
_MAX_HEADER = 1 << 20


def check_not_empty(path: str, kind: str) -> None:
    """ValueError if the file at ``path`` holds no bytes (every reader would fail or misreport)."""
    if os.path.getsize(path) == 0:
        raise ValueError(f"{path}: the {kind} file is empty (0 bytes)")


def _polydata(path: str, points: np.ndarray, counts: np.ndarray, conn: np.ndarray) -> vtkPolyData:
    """Polygons of ``counts[i]`` vertices each (indices ``conn``, already range-checked) over
    ``points``; faces of fewer than three vertices are dropped (they bound no area)."""
    counts = counts.astype(np.int64, copy=False)
    keep = counts >= 3
    if not keep.all():
        conn = conn[np.repeat(keep, counts)]
        counts = counts[keep]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    cells = vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(conn, dtype=np.int64), deep=True))
    pd = vtkPolyData()
    pd.SetPoints(vtk_points(points))
    pd.SetPolys(cells)
    return pd


def _face_indices(path: str, values: np.ndarray, counts: np.ndarray, n_vertices: int) -> np.ndarray:
    """The faces' vertex indices as int64; ValueError naming the first face with an index that
    is not an integer in [0, n_vertices)."""
    bad = np.flatnonzero(~((values >= 0) & (values < n_vertices) & (values == np.floor(values))))
    if bad.size:
        face = int(np.searchsorted(np.cumsum(counts), bad[0], side="right"))
        raise ValueError(f"{path}: face {face} refers to vertex {values[bad[0]]!r}, but the file has "
                         f"{n_vertices} vertices (valid indices 0..{n_vertices - 1})")
    return values.astype(np.int64)


# ---------------------------------------------------------------------------------------------
# PLY
# ---------------------------------------------------------------------------------------------
class _Element:
    def __init__(self, name: str, count: int):
        self.name, self.count, self.props = name, count, []  # props: (name, code) or (name, (ccode, icode))

    @property
    def scalar(self) -> bool:
        return all(isinstance(p[1], str) for p in self.props)


def _ply_header(path: str, data: bytes):
    end = data.find(b"end_header", 0, _MAX_HEADER)
    if not data.startswith(b"ply") or end < 0:
        raise ValueError(f"{path}: not a PLY file (it must start with 'ply' and have an 'end_header' line "
                         f"in its first {_MAX_HEADER} bytes)")
    body = data.index(b"\n", end) + 1 if b"\n" in data[end:end + 64] else len(data)
    fmt, elements = None, []
    for number, raw in enumerate(data[:end].decode("latin-1").splitlines(), start=1):
        words = raw.split()
        if not words or words[0] in ("ply", "comment", "obj_info"):
            continue
        where = f"{path}: header line {number} ({raw.strip()!r})"
        if words[0] == "format":
            if len(words) != 3 or words[1] not in _PLY_FORMATS:
                raise ValueError(f"{where}: the format must be one of {sorted(_PLY_FORMATS)}")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise ValueError(f"{where}: expected 'element NAME COUNT' with a count >= 0")
            elements.append(_Element(words[1], int(words[2])))
        elif words[0] == "property":
            if not elements:
                raise ValueError(f"{where}: a property before any element")
            if len(words) == 5 and words[1] == "list" and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES:
                if _PLY_TYPES[words[2]][0] == "f" or _PLY_TYPES[words[3]][0] == "f":
                    raise ValueError(f"{where}: list counts and indices must be integer types")
                elements[-1].props.append((words[4], (_PLY_TYPES[words[2]], _PLY_TYPES[words[3]])))
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1].props.append((words[2], _PLY_TYPES[words[1]]))
            else:
                raise ValueError(f"{where}: expected 'property TYPE NAME' or 'property list COUNT_TYPE "
                                 f"INDEX_TYPE NAME' with types from {sorted(_PLY_TYPES)}")
        else:
            raise ValueError(f"{where}: unknown header keyword {words[0]!r}")
    if fmt is None:
        raise ValueError(f"{path}: the PLY header has no 'format' line")
    return fmt, elements, body


def _truncated(path: str, el: _Element, need: int, have: int, unit: str = "bytes") -> ValueError:
    return ValueError(f"{path}: the header declares {el.count} '{el.name}' elements, which need at least "
                      f"{need} more {unit}, but only {have} follow (truncated or damaged file)")


def _binary_element(path: str, el: _Element, data: bytes, pos: int, endian: str):
    """Reads element ``el`` at byte ``pos``: returns (columns, next pos). Scalar properties become
    arrays; list properties (counts, flat values)."""
    n = el.count
    min_record = sum(np.dtype(p[1]).itemsize if isinstance(p[1], str) else np.dtype(p[1][0]).itemsize
                     for p in el.props)
    if n * min_record > len(data) - pos:
        raise _truncated(path, el, n * min_record, len(data) - pos)
    if el.scalar:
        dt = np.dtype([(f"p{i}", endian + code) for i, (_, code) in enumerate(el.props)])
        rec = np.frombuffer(data, dtype=dt, count=n, offset=pos)
        return {p[0]: rec[f"p{i}"] for i, p in enumerate(el.props)}, pos + n * dt.itemsize
    if n == 0:
        return {p[0]: (np.zeros(0, np.int64), np.zeros(0, np.int64)) if not isinstance(p[1], str)
                else np.zeros(0) for p in el.props}, pos
    # Fast path: every record has the list lengths of the first (a triangle or quad mesh).
    fields, q = [], pos
    for i, (_, code) in enumerate(el.props):
        if isinstance(code, str):
            fields.append((f"p{i}", endian + code))
            q += np.dtype(code).itemsize
        else:
            ccode, icode = code
            if q + np.dtype(ccode).itemsize > len(data):
                break
            c = int(np.frombuffer(data, dtype=endian + ccode, count=1, offset=q)[0])
            if c < 0:
                break
            fields += [(f"c{i}", endian + ccode), (f"v{i}", endian + icode, (c,))]
            q += np.dtype(ccode).itemsize + c * np.dtype(icode).itemsize
    else:
        dt = np.dtype(fields)
        if n * dt.itemsize <= len(data) - pos:
            rec = np.frombuffer(data, dtype=dt, count=n, offset=pos)
            uniform = all(np.all(rec[f"c{i}"] == rec[f"c{i}"][0]) for i, p in enumerate(el.props)
                          if not isinstance(p[1], str))
            if uniform:
                out = {}
                for i, (name, code) in enumerate(el.props):
                    if isinstance(code, str):
                        out[name] = rec[f"p{i}"]
                    else:
                        vals = rec[f"v{i}"].reshape(n, -1)
                        out[name] = (np.full(n, vals.shape[1], np.int64), vals.reshape(-1))
                return out, pos + n * dt.itemsize
    # General path: record by record (mixed polygon sizes).
    view = np.frombuffer(data, dtype=np.uint8)
    lists = {i: ([], []) for i, p in enumerate(el.props) if not isinstance(p[1], str)}
    scalars = {i: [] for i, p in enumerate(el.props) if isinstance(p[1], str)}
    unpack = {}
    for i, (_, code) in enumerate(el.props):
        c = code if isinstance(code, str) else code[0]
        unpack[i] = struct.Struct(endian + np.dtype(c).char)
    q, end = pos, len(data)
    for r in range(n):
        for i, (_, code) in enumerate(el.props):
            s = unpack[i]
            if q + s.size > end:
                raise ValueError(f"{path}: '{el.name}' record {r} of {n} runs past the end of the file "
                                 "(truncated or damaged file)")
            (v,) = s.unpack_from(data, q)
            q += s.size
            if isinstance(code, str):
                scalars[i].append(v)
                continue
            isize = np.dtype(code[1]).itemsize
            if v < 0 or q + v * isize > end:
                raise ValueError(f"{path}: '{el.name}' record {r} of {n} lists {v} values, past the end "
                                 "of the file (truncated or damaged file)")
            lists[i][0].append(v)
            lists[i][1].append(q)
            q += v * isize
    out = {}
    for i, (name, code) in enumerate(el.props):
        if isinstance(code, str):
            out[name] = np.asarray(scalars[i], dtype=code)
            continue
        counts = np.asarray(lists[i][0], dtype=np.int64)
        starts = np.asarray(lists[i][1], dtype=np.int64)
        isize = np.dtype(code[1]).itemsize
        first = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]) * isize, counts)
        at = first + np.arange(int(counts.sum()), dtype=np.int64) * isize
        raw = view[at[:, None] + np.arange(isize)].reshape(-1)
        out[name] = (counts, np.frombuffer(raw.tobytes(), dtype=endian + code[1]))
    return out, q


def _ascii_element(path: str, el: _Element, tokens: list, pos: int):
    """Reads element ``el`` from the whitespace tokens at ``pos``: (columns, next pos)."""
    n = el.count

    def numbers(chunk, what):
        try:
            return np.array(chunk, dtype=np.float64)
        except ValueError:
            raise ValueError(f"{path}: '{el.name}' {what} holds a token that is not a number") from None

    if n > len(tokens) - pos:
        raise _truncated(path, el, n, len(tokens) - pos, "values")
    if el.scalar:
        k = len(el.props)
        if n * k > len(tokens) - pos:
            raise ValueError(f"{path}: the header declares {el.count} '{el.name}' elements of {k} values, "
                             f"but only {len(tokens) - pos} values follow (truncated or damaged file)")
        vals = numbers(tokens[pos:pos + n * k], "data").reshape(n, k)
        return {p[0]: vals[:, i] for i, p in enumerate(el.props)}, pos + n * k
    if n == 0:
        return {p[0]: (np.zeros(0, np.int64), np.zeros(0, np.int64)) if not isinstance(p[1], str)
                else np.zeros(0) for p in el.props}, pos
    # Fast path: every record has the list lengths of the first.
    layout, q = [], pos
    for _, code in el.props:
        if isinstance(code, str):
            layout.append(None)
            q += 1
        else:
            c = numbers(tokens[q:q + 1], "list count")
            if c.size != 1 or not (c[0] >= 0) or c[0] != int(c[0]):
                break
            layout.append(int(c[0]))
            q += 1 + int(c[0])
    else:
        width = q - pos
        if n * width <= len(tokens) - pos:
            vals = numbers(tokens[pos:pos + n * width], "data").reshape(n, width)
            out, col, uniform = {}, 0, True
            for (name, code), c in zip(el.props, layout):
                if c is None:
                    out[name] = vals[:, col]
                    col += 1
                    continue
                uniform &= bool(np.all(vals[:, col] == c))
                out[name] = (np.full(n, c, np.int64), vals[:, col + 1:col + 1 + c].reshape(-1))
                col += 1 + c
            if uniform:
                return out, pos + n * width
    # General path: record by record.
    out = {p[0]: ([], []) if not isinstance(p[1], str) else [] for p in el.props}
    q = pos
    for r in range(n):
        for name, code in el.props:
            if q >= len(tokens):
                raise ValueError(f"{path}: '{el.name}' record {r} of {n} runs past the end of the file "
                                 "(truncated or damaged file)")
            v = numbers(tokens[q:q + 1], f"record {r}")[0]
            q += 1
            if isinstance(code, str):
                out[name].append(v)
                continue
            if not (v >= 0) or v != int(v) or q + int(v) > len(tokens):
                raise ValueError(f"{path}: '{el.name}' record {r} of {n} has the list length {v!r}: not a "
                                 "count, or past the end of the file (truncated or damaged file)")
            out[name][0].append(int(v))
            out[name][1].append(numbers(tokens[q:q + int(v)], f"record {r}"))
            q += int(v)
    for name, code in el.props:
        if isinstance(code, str):
            out[name] = np.asarray(out[name])
        else:
            counts, vals = out[name]
            out[name] = (np.asarray(counts, np.int64), np.concatenate(vals) if vals else np.zeros(0))
    return out, q


def read_ply(path: str) -> vtkPolyData:
    """A PLY file's vertices and faces as polygons (ASCII and both binary encodings).

    Points keep the file's precision (float32 when x, y and z are float32, as vtkPLYReader gives
    them, else float64). ValueError for a malformed header, a file shorter than its header
    declares, a non-numeric or non-integral value where a count or an index belongs, a missing
    vertex element or x/y/z property, or a face index outside the vertices.
    """
    check_not_empty(path, "mesh")
    with open(path, "rb") as f:
        data = f.read()
    fmt, elements, body = _ply_header(path, data)
    endian = _PLY_FORMATS[fmt]
    tokens = data[body:].split() if endian is None else None
    pos = 0 if endian is None else body
    columns = {}
    for el in elements:
        if endian is None:
            cols, pos = _ascii_element(path, el, tokens, pos)
        else:
            cols, pos = _binary_element(path, el, data, pos, endian)
        columns[el.name] = (el, cols)
    if "vertex" not in columns:
        raise ValueError(f"{path}: the PLY file has no 'vertex' element")
    vel, vcols = columns["vertex"]
    missing = [a for a in "xyz" if a not in vcols]
    if missing:
        raise ValueError(f"{path}: the 'vertex' element lacks the properties {missing}")
    codes = {p[0]: p[1] for p in vel.props}
    dtype = np.float32 if all(codes[a] == "f4" for a in "xyz") else np.float64
    points = np.column_stack([np.asarray(vcols[a], dtype=dtype) for a in "xyz"]) if vel.count else \
        np.zeros((0, 3), dtype)
    counts, conn = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if "face" in columns:
        fel, fcols = columns["face"]
        name = next((n for n in _FACE_LISTS if n in fcols and not isinstance(dict(fel.props)[n], str)), None)
        if name is None:
            raise ValueError(f"{path}: the 'face' element has no list property {' or '.join(_FACE_LISTS)}")
        counts, values = fcols[name]
        conn = _face_indices(path, np.asarray(values), counts, len(points))
    return _polydata(path, points, counts, conn)


# ---------------------------------------------------------------------------------------------
# OBJ
# ---------------------------------------------------------------------------------------------
def read_obj(path: str) -> vtkPolyData:
    """An OBJ file's vertices (``v``) and faces (``f``) as polygons.

    Face corners may be ``i``, ``i/t``, ``i/t/n`` or ``i//n``; only the vertex index ``i`` is
    used: 1-based, or negative for "counting back from the last vertex read so far" (OBJ's
    relative indices). Points are float32, as vtkOBJReader gives them. As in vtkOBJReader, the
    obsolete face outlines (``fo``), lines (``l``), points (``p``), texture coordinates, normals,
    groups and materials are ignored. ValueError, naming the line, for a non-numeric coordinate,
    an index 0, or an index outside the vertices read.
    """
    check_not_empty(path, "mesh")
    with open(path, "rb") as f:
        lines = f.read().splitlines()
    verts, counts, conn = [], [], []
    for number, line in enumerate(lines, start=1):
        words = line.split()
        if not words:
            continue
        key = words[0]
        if key == b"v":
            try:
                xyz = [float(w) for w in words[1:4]]
            except ValueError:
                raise ValueError(f"{path}: line {number}: a vertex coordinate is not a number: "
                                 f"{line[:80]!r}") from None
            if len(xyz) != 3:
                raise ValueError(f"{path}: line {number}: a vertex needs x y z: {line[:80]!r}")
            verts.append(xyz)
        elif key == b"f":
            nv = len(verts)
            face = []
            for w in words[1:]:
                head = w.split(b"/", 1)[0]
                try:
                    i = int(head)
                except ValueError:
                    raise ValueError(f"{path}: line {number}: a face corner is not an index: {w!r}") from None
                if i == 0 or i > nv or i < -nv:
                    raise ValueError(f"{path}: line {number}: the face index {i} is out of range: "
                                     f"{nv} vertices are defined before it (valid: 1..{nv}, or -1..-{nv} "
                                     "counting back)" if i else
                                     f"{path}: line {number}: face index 0 is invalid (OBJ indices start at 1)")
                face.append(i - 1 if i > 0 else nv + i)
            counts.append(len(face))
            conn.extend(face)
    points = np.asarray(verts, dtype=np.float32).reshape(-1, 3)
    return _polydata(path, points, np.asarray(counts, np.int64), np.asarray(conn, np.int64))
