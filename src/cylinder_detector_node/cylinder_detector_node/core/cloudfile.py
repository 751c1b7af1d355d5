"""Reading .pcd and .ply point clouds (Open3D), their headers and sizes checked first.

Open3D reads a truncated ASCII .pcd or any truncated .ply as a full cloud padded with zeros
(RPly only prints to stderr), a truncated binary .pcd and any non-cloud file as an empty one. So the
header is parsed here and the data checked against it before Open3D reads the file, and the
number of points Open3D returns is checked after: a file that is not what its header says is a
CloudFileError (a ValueError) with a one-line message naming the file and the problem.

    points, image = read_cloud(Path('scan.pcd'))   # (H, W, 3) organized or (N, 3); RGB or None
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

SUFFIXES = ('.pcd', '.ply')
HEADER_LIMIT = 65536                    #: bytes; a header longer than this is not a point cloud's
PCD_TYPES = {'F': (4, 8), 'I': (1, 2, 4, 8), 'U': (1, 2, 4, 8)}
PCD_DATA = ('ascii', 'binary', 'binary_compressed')
PLY_FORMATS = ('ascii', 'binary_little_endian', 'binary_big_endian')
PLY_SIZES = {'char': 1, 'int8': 1, 'uchar': 1, 'uint8': 1, 'short': 2, 'int16': 2, 'ushort': 2,
             'uint16': 2, 'int': 4, 'int32': 4, 'uint': 4, 'uint32': 4, 'float': 4, 'float32': 4,
             'double': 8, 'float64': 8}


class CloudFileError(ValueError):
    """A file that is no readable point cloud; str() is one line naming the file."""


@dataclass(frozen=True)
class PcdHeader:
    fields: tuple[str, ...]
    width: int
    height: int
    points: int
    data: str                 #: ascii, binary or binary_compressed
    point_step: int           #: bytes per point (binary)
    values: int               #: values per point (ascii: tokens per line)


@dataclass(frozen=True)
class PlyElement:
    name: str
    count: int
    properties: tuple[str, ...]
    size: int | None          #: bytes per item in binary, None with a list property


def _ints(path: Path, key: str, words: list[str]) -> list[int]:
    try:
        return [int(w) for w in words]
    except ValueError:
        raise CloudFileError(f'{path}: PCD header line {key} {" ".join(words)!r} '
                             f'is not integers') from None


def parse_pcd_header(path: Path, raw: bytes) -> tuple[PcdHeader, int]:
    """The header of a .pcd file's bytes and where its data starts; CloudFileError if malformed."""
    fields: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = raw.find(b'\n', pos)
        if end < 0 or end > HEADER_LIMIT:
            raise CloudFileError(f'{path}: not a PCD file (no DATA line in its header)')
        line = raw[pos:end].decode('ascii', 'replace').strip()
        pos = end + 1
        if not line or line.startswith('#'):
            continue
        key, *words = line.split()
        if not key.isalpha() or not key.isupper():
            shown = f' {line[:40]!r}' if line.isascii() and line.isprintable() else ''
            raise CloudFileError(f'{path}: not a PCD file '
                                 f'(header line{shown} is no "KEY values" line)')
        fields[key] = words
        if key == 'DATA':
            break
    missing = [k for k in ('FIELDS', 'SIZE', 'TYPE', 'WIDTH', 'HEIGHT') if k not in fields]
    if missing:
        raise CloudFileError(f'{path}: PCD header has no {", ".join(missing)} line')
    names = tuple(fields['FIELDS'])
    sizes = _ints(path, 'SIZE', fields['SIZE'])
    types = fields['TYPE']
    counts = _ints(path, 'COUNT', fields.get('COUNT', ['1'] * len(names)))
    if not len(names) == len(sizes) == len(types) == len(counts):
        raise CloudFileError(f'{path}: PCD header has {len(names)} FIELDS, {len(sizes)} SIZE, '
                             f'{len(types)} TYPE and {len(counts)} COUNT values')
    for n, s, t, c in zip(names, sizes, types, counts, strict=True):
        if s not in PCD_TYPES.get(t, ()) or c < 1:
            raise CloudFileError(f'{path}: PCD field {n} has TYPE {t} SIZE {s} COUNT {c}')
    if not {'x', 'y', 'z'} <= set(names):
        raise CloudFileError(f'{path}: PCD fields {" ".join(names)} have no x, y, z')
    (width,), (height,) = _ints(path, 'WIDTH', fields['WIDTH'][:1] or ['']), \
        _ints(path, 'HEIGHT', fields['HEIGHT'][:1] or [''])
    points = _ints(path, 'POINTS', fields.get('POINTS', [str(width * height)])[:1] or [''])[0]
    if width < 0 or height < 0 or points != width * height:
        raise CloudFileError(f'{path}: PCD header says POINTS {points} but WIDTH x HEIGHT is '
                             f'{width} x {height}')
    data = (fields['DATA'] or [''])[0].lower()
    if data not in PCD_DATA:
        raise CloudFileError(f'{path}: PCD DATA {data!r} is none of {", ".join(PCD_DATA)}')
    step = sum(s * c for s, c in zip(sizes, counts, strict=True))
    return PcdHeader(names, width, height, points, data, step, sum(counts)), pos


def check_pcd(path: Path, raw: bytes) -> PcdHeader:
    """The header of a .pcd file's bytes, its data checked against it (CloudFileError)."""
    head, start = parse_pcd_header(path, raw)
    if head.points == 0:
        raise CloudFileError(f'{path}: the cloud has no points (POINTS 0)')
    body = raw[start:]
    if head.data == 'binary':
        need = head.points * head.point_step
        if len(body) < need:
            raise CloudFileError(f'{path}: truncated: {len(body)} bytes of binary data where '
                                 f'{head.points} points need {need}')
    elif head.data == 'binary_compressed':
        if len(body) < 8:
            raise CloudFileError(f'{path}: truncated: no compressed data after the header')
        packed, unpacked = struct.unpack('<II', body[:8])
        if unpacked != head.points * head.point_step:
            raise CloudFileError(f'{path}: compressed data unpacks to {unpacked} bytes where '
                                 f'{head.points} points need {head.points * head.point_step}')
        if len(body) - 8 < packed:
            raise CloudFileError(f'{path}: truncated: {len(body) - 8} of {packed} bytes of '
                                 'compressed data')
    else:
        _check_ascii_rows(path, body, head.points, head.values, 'PCD')
    return head


def _check_ascii_rows(path: Path, body: bytes, rows: int, values: int, kind: str,
                      skip: int = 0) -> None:
    """The ASCII body has skip + rows lines and the last of the rows holds `values` numbers."""
    lines = [ln for ln in body.split(b'\n') if ln.strip()]
    if len(lines) < skip + rows:
        raise CloudFileError(f'{path}: truncated: {max(len(lines) - skip, 0)} of the {rows} point '
                             f'lines the {kind} header declares')
    last = lines[skip + rows - 1].split()
    try:
        [float(v) for v in last[:values]]
    except ValueError:
        raise CloudFileError(f'{path}: point line {rows} is not numbers: '
                             f'{b" ".join(last[:6]).decode("ascii", "replace")!r}') from None
    if len(last) < values:
        raise CloudFileError(f'{path}: truncated: the last point line has {len(last)} of '
                             f'{values} values')


def parse_ply_header(path: Path, raw: bytes) -> tuple[str, list[PlyElement], int]:
    """(format, elements, data offset) of a .ply file's bytes; CloudFileError if malformed."""
    if not raw.startswith(b'ply'):
        raise CloudFileError(f'{path}: not a PLY file (it does not start with "ply")')
    end = raw.find(b'end_header', 0, HEADER_LIMIT)
    nl = raw.find(b'\n', end) if end >= 0 else -1
    if end < 0 or nl < 0:
        raise CloudFileError(f'{path}: PLY header has no end_header line')
    fmt = None
    elements: list[tuple[str, int, list[str], list[int | None]]] = []
    for line in raw[:end].decode('ascii', 'replace').splitlines()[1:]:
        words = line.split()
        if not words or words[0] in ('comment', 'obj_info'):
            continue
        if words[0] == 'format' and len(words) >= 2:
            fmt = words[1]
        elif words[0] == 'element' and len(words) == 3:
            try:
                count = int(words[2])
            except ValueError:
                raise CloudFileError(f'{path}: PLY element line {line.strip()[:40]!r} '
                                     f'has no count') from None
            elements.append((words[1], count, [], []))
        elif words[0] == 'property' and elements and len(words) >= 3:
            if words[1] == 'list' and len(words) == 5:
                elements[-1][2].append(words[4])
                elements[-1][3].append(None)
            elif words[1] in PLY_SIZES and len(words) == 3:
                elements[-1][2].append(words[2])
                elements[-1][3].append(PLY_SIZES[words[1]])
            else:
                raise CloudFileError(f'{path}: PLY property line {line.strip()[:40]!r} '
                                     f'has an unknown type')
        else:
            shown = f' {line.strip()[:40]!r}' if line.isascii() and line.isprintable() else ''
            raise CloudFileError(f'{path}: PLY header line{shown} is no format, element or '
                                 f'property line')
    if fmt not in PLY_FORMATS:
        raise CloudFileError(f'{path}: PLY format {fmt!r} is none of {", ".join(PLY_FORMATS)}')
    out = [PlyElement(n, c, tuple(p), None if any(s is None for s in ss) else sum(ss))  # type: ignore[arg-type]
           for n, c, p, ss in elements]
    return fmt, out, nl + 1


def check_ply(path: Path, raw: bytes) -> int:
    """The number of vertices of a .ply file's bytes, its data checked against the header."""
    fmt, elements, start = parse_ply_header(path, raw)
    names = [e.name for e in elements]
    if 'vertex' not in names:
        raise CloudFileError(f'{path}: PLY file has no vertex element')
    at = names.index('vertex')
    vertex = elements[at]
    if not {'x', 'y', 'z'} <= set(vertex.properties):
        raise CloudFileError(f'{path}: PLY vertices have no x, y, z (properties: '
                             f'{" ".join(vertex.properties) or "none"})')
    if vertex.count <= 0:
        raise CloudFileError(f'{path}: the cloud has no points (element vertex {vertex.count})')
    body = raw[start:]
    if fmt == 'ascii':
        _check_ascii_rows(path, body, vertex.count, len(vertex.properties), 'PLY',
                          skip=sum(e.count for e in elements[:at]))
    elif all(e.size is not None for e in elements[:at + 1]):
        need = sum(e.count * cast(int, e.size) for e in elements[:at + 1])   # sizes checked
        if len(body) < need:
            raise CloudFileError(f'{path}: truncated: {len(body)} bytes of binary data where '
                                 f'{vertex.count} vertices need {need}')
    return vertex.count


def read_cloud(path: Path) -> tuple[NDArray[np.float64], NDArray[np.uint8] | None]:
    """(points, image) of a .pcd or .ply file: points (H, W, 3) for an organized .pcd (HEIGHT > 1),
    else (N, 3), NaN kept; image (H, W, 3) uint8 RGB from an organized cloud's colours, else None.
    CloudFileError (one line, naming the file) for anything that is no such point cloud."""
    import open3d as o3d
    if path.is_dir():
        raise CloudFileError(f'{path}: is a directory, not a point cloud file')
    if not path.exists():
        raise CloudFileError(f'{path}: no such file')
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise CloudFileError(f'{path}: expected a .pcd or .ply file, not {suffix or "no suffix"}')
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise CloudFileError(f'{path}: cannot read it: {exc.strerror or exc}') from None
    head: PcdHeader | None = None
    if suffix == '.pcd':
        head = check_pcd(path, raw)
        declared = head.points
    else:
        declared = check_ply(path, raw)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)   # keep stdout pure JSON
    pcd = o3d.io.read_point_cloud(path, format=suffix[1:], remove_nan_points=False,
                                  remove_infinite_points=False)
    pts = np.asarray(pcd.points, dtype=np.float64)
    if len(pts) != declared:
        raise CloudFileError(f'{path}: not a readable {suffix[1:].upper()} point cloud '
                             f'(Open3D read {len(pts)} of the {declared} points its header '
                             f'declares)')
    if head is None or head.height <= 1:
        return pts, None
    w, h = head.width, head.height
    image = None
    if pcd.has_colors():
        image = (np.clip(np.asarray(pcd.colors) * 255.0 + 0.5, 0, 255).astype(np.uint8)
                 .reshape(h, w, 3))
    return pts.reshape(h, w, 3), image
