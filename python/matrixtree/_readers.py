"""Checking readers for the formats whose VTK 9.1 or meshio readers trust the file, or have none.

``vtkPLYReader`` crashes (segfault, double free) on a truncated file or one whose header declares
more elements than the file holds, and reads no triangle strips; ``vtkOBJReader`` reads a face's
out-of-range vertex index from out-of-bounds memory; VTK 9.1 has no OFF reader; meshio's SU2
reader keeps one zone's points of a multi-zone file with every zone's cells (which then index
the wrong points) and raises KeyError on high-order elements. These readers take any line ending
(LF, CRLF, CR), check every count against the data that follow, every index against the points
read, and raise ValueError naming the file, the element and the line or record; the mesh they
return equals VTK's (PLY, OBJ) or meshio's (single-zone linear SU2) for a valid file
(tests/python/test_reliability_readers.py compares them).

Not public API: ``matrixtree.read_mesh`` and ``matrixtree.read_grid`` call them.
"""

from __future__ import annotations

import os
import struct

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData, vtkUnstructuredGrid

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
    if "tristrips" in columns:
        sel, scols = columns["tristrips"]
        name = next((n for n in _FACE_LISTS if n in scols and not isinstance(dict(sel.props)[n], str)), None)
        if name is None:
            raise ValueError(f"{path}: the 'tristrips' element has no list property {' or '.join(_FACE_LISTS)}")
        tri = _strip_triangles(path, *scols[name], len(points))
        counts = np.concatenate([counts, np.full(len(tri), 3, np.int64)])
        conn = np.concatenate([conn, tri.reshape(-1)])
    return _polydata(path, points, counts, conn)


def _strip_triangles(path: str, counts: np.ndarray, values: np.ndarray, n_vertices: int) -> np.ndarray:
    """The triangles (k x 3, int64) of a PLY 'tristrips' element: each record's list holds strips
    separated by -1; the strip a b c d e gives the triangles (a b c), (c b d), (c d e): every
    second one reversed, so that all keep the first one's orientation. Triangles that repeat a
    vertex (strips join through them) are dropped: they bound no area."""
    v = np.asarray(values, dtype=np.float64)
    bad = np.flatnonzero(~(((v >= 0) & (v < n_vertices)) | (v == -1)) | (v != np.floor(v)))
    if bad.size:
        record = int(np.searchsorted(np.cumsum(counts), bad[0], side="right"))
        raise ValueError(f"{path}: tristrips record {record} refers to vertex {v[bad[0]]!r}, but the file "
                         f"has {n_vertices} vertices (valid: 0..{n_vertices - 1}, or -1 between strips)")
    v = v.astype(np.int64)
    if v.size < 3:
        return np.zeros((0, 3), np.int64)
    starts = np.zeros(v.size, bool)
    starts[np.cumsum(counts)[:-1][np.cumsum(counts)[:-1] < v.size]] = True
    starts[0] = True
    starts |= v == -1
    segment = np.cumsum(starts) - 1
    first = np.flatnonzero(starts)
    first = first + (v[first] == -1)  # a strip's first vertex follows its -1
    i = np.arange(v.size - 2)
    keep = (segment[i] == segment[i + 2]) & (v[i] >= 0) & (v[i + 1] >= 0) & (v[i + 2] >= 0)
    i = i[keep]
    odd = (i - first[segment[i]]) % 2 == 1
    a = np.where(odd, v[i + 1], v[i])
    b = np.where(odd, v[i], v[i + 1])
    tri = np.column_stack([a, b, v[i + 2]])
    return tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]


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


# ---------------------------------------------------------------------------------------------
# OFF (Geomview's Object File Format, ASCII)
# ---------------------------------------------------------------------------------------------
def _data_lines(path: str, comment: bytes):
    """(line number, stripped line) of the file's lines without comments and blank lines; any
    line ending (LF, CRLF, CR) ends a line."""
    with open(path, "rb") as f:
        data = f.read()
    out = []
    for number, line in enumerate(data.splitlines(), start=1):
        line = line.split(comment, 1)[0].strip()
        if line:
            out.append((number, line))
    return out


def read_off(path: str) -> vtkPolyData:
    """An ASCII OFF file's vertices and faces as polygons (float64 points).

    The header keyword is ``OFF`` with the optional prefixes of Geomview's format: ``ST``
    (texture coordinates), ``C`` (colours), ``N`` (normals) and ``n`` (dimension on the next
    line; only 3 is read). The counts ``vertices faces edges`` follow on the header line or the
    next one. A vertex line's values after x y z and a face line's after its ``k i1 .. ik``
    (a colour) are ignored; ``#`` starts a comment anywhere. Indices are 0-based. ValueError,
    naming the line, for binary OFF, 4-D or n-D vertices other than 3-D, a missing or
    non-numeric count or coordinate, fewer lines than the counts declare, or a face index
    outside the vertices.
    """
    check_not_empty(path, "mesh")
    lines = _data_lines(path, b"#")
    if not lines:
        raise ValueError(f"{path}: the OFF file holds only comments and blank lines")
    number, head = lines[0]
    words = head.split()
    key = words[0].decode("latin-1")
    stem = key[2:] if key.startswith("ST") else key
    stem = stem.lstrip("CN")
    if not stem.endswith("OFF") or stem not in ("OFF", "4OFF", "nOFF", "4nOFF"):
        raise ValueError(f"{path}: line {number}: not an OFF file (the first keyword is {key!r}, expected OFF "
                         "with the optional prefixes ST, C, N, n)")
    rest, at = words[1:], 1
    if rest[:1] == [b"BINARY"]:
        raise ValueError(f"{path}: line {number}: binary OFF is not supported (only ASCII OFF is read)")
    if "4" in stem:
        raise ValueError(f"{path}: line {number}: {key} holds 4-D vertices; only 3-D OFF is read")
    if "n" in stem:
        if not rest:
            if at >= len(lines):
                raise ValueError(f"{path}: {key} needs the dimension after the header keyword")
            rest, at = lines[at][1].split(), at + 1
        if rest[0] != b"3":
            raise ValueError(f"{path}: {key} declares dimension {rest[0].decode('latin-1')!r}; only 3 is read")
        rest = rest[1:]
    if not rest:
        if at >= len(lines):
            raise ValueError(f"{path}: the OFF file ends before the vertex and face counts")
        number, count_line = lines[at]
        rest, at = count_line.split(), at + 1
    if len(rest) < 2 or not all(w.isdigit() for w in rest[:3]):
        raise ValueError(f"{path}: line {number}: expected the counts 'vertices faces edges' (integers >= 0), "
                         f"got {b' '.join(rest).decode('latin-1')!r}")
    nv, nf = int(rest[0]), int(rest[1])
    if at + nv + nf > len(lines):
        raise ValueError(f"{path}: the header declares {nv} vertices and {nf} faces, but only {len(lines) - at} "
                         "data lines follow (truncated or damaged file)")
    vlines = lines[at:at + nv]
    try:
        points = np.array([ln.split()[:3] for _, ln in vlines], dtype=np.float64).reshape(nv, 3)
    except ValueError:
        first = next(n for n, ln in vlines if len(ln.split()) < 3 or not _all_numbers(ln.split()[:3]))
        raise ValueError(f"{path}: line {first}: a vertex needs three numbers x y z") from None
    counts, conn = np.zeros(nf, np.int64), []
    for k, (n, ln) in enumerate(lines[at + nv:at + nv + nf]):
        words = ln.split()
        try:
            c = int(words[0])
            face = [int(w) for w in words[1:1 + c]]
        except ValueError:
            raise ValueError(f"{path}: line {n}: a face must be 'k i1 .. ik' with integers, got "
                             f"{ln[:80].decode('latin-1')!r}") from None
        if c < 0 or len(face) != c:
            raise ValueError(f"{path}: line {n}: the face lists {c} vertices but holds {len(face)} indices")
        counts[k] = c
        conn.append(face)
    flat = np.array([i for face in conn for i in face], dtype=np.int64)
    bad = np.flatnonzero((flat < 0) | (flat >= nv))
    if bad.size:
        face = int(np.searchsorted(np.cumsum(counts), bad[0], side="right"))
        raise ValueError(f"{path}: line {lines[at + nv + face][0]}: face {face} refers to vertex {int(flat[bad[0]])}, "
                         f"but the file has {nv} vertices (valid indices 0..{nv - 1})")
    return _polydata(path, points, counts, flat)


def _all_numbers(words) -> bool:
    try:
        [float(w) for w in words]
        return True
    except ValueError:
        return False


# ---------------------------------------------------------------------------------------------
# SU2 (native ASCII mesh format)
# ---------------------------------------------------------------------------------------------
#: SU2 element type (VTK's cell type ids) -> points per element, for the linear cells SU2 writes.
_SU2_LINEAR = {3: 2, 5: 3, 9: 4, 10: 4, 12: 8, 13: 6, 14: 5}
_SU2_NAMES = {3: "line", 5: "triangle", 9: "quadrilateral", 10: "tetrahedron", 12: "hexahedron", 13: "prism",
              14: "pyramid"}
#: 3-D cell types: what read_grid keeps with volume_only.
VOLUME_TYPES = {10, 12, 13, 14, 24, 25}


def unstructured_grid(points: np.ndarray, types: np.ndarray, counts: np.ndarray, conn: np.ndarray) -> vtkUnstructuredGrid:
    """A vtkUnstructuredGrid of cells of VTK type ``types[i]`` with ``counts[i]`` point ids each
    (``conn``, already range-checked) over ``points`` (N x 3)."""
    off = np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)
    cells = vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(off, deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(conn, dtype=np.int64), deep=True))
    g = vtkUnstructuredGrid()
    g.SetPoints(vtk_points(np.ascontiguousarray(points, dtype=np.float64)))
    g.SetCells(numpy_to_vtk(np.asarray(types, np.uint8), deep=True, array_type=3), cells)  # 3 = VTK_UNSIGNED_CHAR
    return g


class _Su2Zone:
    def __init__(self, number: int):
        self.number, self.dim, self.points = number, None, None
        self.blocks = []  # (volume: bool, types, counts, conn, first line)


def _su2_type_error(path: str, number: int, code: int) -> ValueError:
    if code >= 100:
        return ValueError(f"{path}: line {number}: element type {code} is a degree-{code % 10000 // 100 + 1} "
                          f"{_SU2_NAMES.get(code % 100, f'type-{code % 100}')} of SU2's high-order (FEM) format; "
                          f"only linear elements are read (types {sorted(_SU2_LINEAR)})")
    return ValueError(f"{path}: line {number}: unknown SU2 element type {code} (linear types are "
                      f"{', '.join(f'{k} {v}' for k, v in _SU2_NAMES.items())})")


def _su2_elements(path: str, lines: list, at: int, n: int, keyword: str):
    """Parses the ``n`` element lines ``type i1 .. ik [index]`` at ``lines[at]``: (types, counts,
    flat point ids)."""
    if at + n > len(lines) or any(b"=" in ln for _, ln in lines[at:at + n]):
        have = next((k for k, (_, ln) in enumerate(lines[at:at + n]) if b"=" in ln), len(lines) - at)
        raise ValueError(f"{path}: {keyword}= declares {n} elements, but only {have} element lines follow "
                         "(truncated or damaged file)")
    rows = [ln.split() for _, ln in lines[at:at + n]]
    if n and all(len(r) == len(rows[0]) for r in rows):  # one element type: read as one array
        try:
            arr = np.array(rows, dtype=np.int64)
        except ValueError:
            arr = None
        if arr is not None and np.all(arr[:, 0] == arr[0, 0]) and arr[0, 0] in _SU2_LINEAR \
                and arr.shape[1] in (_SU2_LINEAR[arr[0, 0]] + 1, _SU2_LINEAR[arr[0, 0]] + 2):
            npc = _SU2_LINEAR[arr[0, 0]]
            return arr[:, 0].copy(), np.full(n, npc, np.int64), arr[:, 1:1 + npc].reshape(-1)
    types, counts, conn = np.zeros(n, np.int64), np.zeros(n, np.int64), []
    for k, (number, ln) in enumerate(lines[at:at + n]):
        try:
            ids = [int(w) for w in rows[k]]
        except ValueError:
            raise ValueError(f"{path}: line {number}: an element line holds a token that is not an integer: "
                             f"{ln[:80].decode('latin-1')!r}") from None
        code = ids[0]
        if code not in _SU2_LINEAR:
            raise _su2_type_error(path, number, code)
        npc = _SU2_LINEAR[code]
        if len(ids) not in (npc + 1, npc + 2):
            raise ValueError(f"{path}: line {number}: a {_SU2_NAMES[code]} (type {code}) needs {npc} point ids "
                             f"(and an optional element index), the line holds {len(ids) - 1} numbers")
        types[k], counts[k] = code, npc
        conn.append(ids[1:1 + npc])
    flat = np.array([i for c in conn for i in c], dtype=np.int64)
    return types, counts, flat


def _su2_points(path: str, lines: list, at: int, n: int, dim: int) -> np.ndarray:
    if at + n > len(lines) or any(b"=" in ln for _, ln in lines[at:at + n]):
        have = next((k for k, (_, ln) in enumerate(lines[at:at + n]) if b"=" in ln), len(lines) - at)
        raise ValueError(f"{path}: NPOIN= declares {n} points, but only {have} point lines follow "
                         "(truncated or damaged file)")
    rows = [ln.split()[:dim] for _, ln in lines[at:at + n]]
    try:
        pts = np.array(rows, dtype=np.float64)
        if pts.shape != (n, dim):
            raise ValueError
    except ValueError:
        number = next(num for (num, ln), r in zip(lines[at:at + n], rows)
                      if len(r) < dim or not _all_numbers(r))
        raise ValueError(f"{path}: line {number}: a point needs {dim} coordinates (NDIME= {dim})") from None
    return pts if dim == 3 else np.column_stack([pts, np.zeros(n)])


def _su2_count(path: str, number: int, key: str, value: bytes) -> int:
    words = value.split()
    if not words or not words[0].isdigit():
        raise ValueError(f"{path}: line {number}: {key}= needs a count (an integer >= 0), got "
                         f"{value.decode('latin-1').strip()!r}")
    return int(words[0])


def read_su2(path: str, zone: int | None = None, volume_only: bool = True) -> vtkUnstructuredGrid:
    """An SU2 mesh file's elements as a vtkUnstructuredGrid.

    A multi-zone file (``NZONE=`` with ``IZONE=`` sections, each with its own points, whose
    element ids count from 0 within the zone) gives all zones in one grid, each zone's points
    appended after the previous zone's and its cells' ids shifted to match, with a cell array
    ``zone`` (the IZONE number); ``zone=k`` reads zone ``k`` alone. The markers' boundary
    elements are kept unless ``volume_only``. Any line ending (LF, CRLF, CR) ends a line; ``%``
    starts a comment; sections SU2 does not define cells with (e.g. FFD boxes) are skipped.
    ValueError, naming the line, for a high-order (FEM) or unknown element type, a count that
    is not an integer, fewer lines than a count declares, a non-numeric coordinate or id, an
    element id outside its zone's points, or a ``zone`` the file does not have.
    """
    check_not_empty(path, "grid")
    lines = _data_lines(path, b"%")
    zones, nzone, cur, skipping, at = [], None, None, False, 0
    while at < len(lines):
        number, ln = lines[at]
        at += 1
        if b"=" not in ln:
            if skipping:
                continue
            raise ValueError(f"{path}: line {number}: a data line where a keyword (NDIME=, NELEM=, NPOIN=, "
                             f"NMARK=, ...) belongs: {ln[:80].decode('latin-1')!r} (a count above it is too small?)")
        key, value = ln.split(b"=", 1)
        key = key.strip().decode("latin-1")
        skipping = False
        if key == "NZONE":
            nzone = _su2_count(path, number, key, value)
        elif key == "IZONE":
            cur = _Su2Zone(_su2_count(path, number, key, value))
            zones.append(cur)
        elif key == "NDIME":
            if cur is None or cur.dim is not None:  # a single-zone file, or its zones without IZONE=
                cur = _Su2Zone(len(zones) + 1)
                zones.append(cur)
            dim = _su2_count(path, number, key, value)
            if dim not in (2, 3):
                raise ValueError(f"{path}: line {number}: NDIME= {dim}; SU2 meshes are 2-D or 3-D")
            cur.dim = dim
        elif key in ("NELEM", "MARKER_ELEMS", "NPOIN"):
            if cur is None or cur.dim is None:
                raise ValueError(f"{path}: line {number}: {key}= before NDIME=")
            n = _su2_count(path, number, key, value)
            if key == "NPOIN":
                if cur.points is not None:
                    raise ValueError(f"{path}: line {number}: a second NPOIN= in zone {cur.number}")
                cur.points = _su2_points(path, lines, at, n, cur.dim)
            else:
                cur.blocks.append((key == "NELEM", *_su2_elements(path, lines, at, n, key), number))
            at += n
        elif key in ("NMARK", "MARKER_TAG"):
            pass
        else:
            skipping = True
    if not zones:
        raise ValueError(f"{path}: not an SU2 mesh (no NDIME= line)")
    if nzone is not None and nzone != len(zones):
        raise ValueError(f"{path}: NZONE= {nzone}, but the file holds {len(zones)} zones")
    numbers = [z.number for z in zones]
    if len(set(numbers)) != len(numbers):
        raise ValueError(f"{path}: the zone numbers {numbers} repeat")
    if zone is not None:
        if zone not in numbers:
            raise ValueError(f"{path}: zone={zone!r}, but the file's zones are {numbers}")
        zones = [z for z in zones if z.number == zone]
    pts, types, counts, conn, zone_of, base = [], [], [], [], [], 0
    for z in zones:
        if z.points is None:
            raise ValueError(f"{path}: zone {z.number} has no NPOIN= section")
        for volume, t, c, ids, number in z.blocks:
            bad = np.flatnonzero((ids < 0) | (ids >= len(z.points)))
            if bad.size:
                e = int(np.searchsorted(np.cumsum(c), bad[0], side="right"))
                raise ValueError(f"{path}: element {e} of the section at line {number} refers to point "
                                 f"{int(ids[bad[0]])}, but zone {z.number} has {len(z.points)} points")
            keep = np.isin(t, list(VOLUME_TYPES)) if volume_only else np.ones(len(t), bool)
            types.append(t[keep])
            counts.append(c[keep])
            conn.append(ids[np.repeat(keep, c)] + base)
            zone_of.append(np.full(int(keep.sum()), z.number, np.int32))
        pts.append(z.points)
        base += len(z.points)
    types = np.concatenate(types) if types else np.zeros(0, np.int64)
    if types.size == 0:
        raise ValueError(f"{path} holds no {'3-D ' if volume_only else ''}cells")
    grid = unstructured_grid(np.concatenate(pts), types, np.concatenate(counts), np.concatenate(conn))
    if len(zones) > 1:
        arr = numpy_to_vtk(np.concatenate(zone_of), deep=True)
        arr.SetName("zone")
        grid.GetCellData().AddArray(arr)
    return grid
