"""What a scan file's header declares, checked against its body before its points are read.

A point cloud's header says how many points the file holds; the body holds them. The libraries
vebuild reads scans with trust the header in different ways: trimesh reads an ASCII PLY's lines up
to the count its header gives and stops short without a word where the body holds fewer; laspy reads
the points a LAS header declares, and fewer where the file ends first; libE57Format reads the
records an E57 header declares and leaves the rest of its buffers as they were (memory never
written: points that are not in the file). So each header is checked here against its body first,
and a header that disagrees with its body (more points, fewer, a truncated body, data beyond the
last point) is refused, naming the file and the header's field:

- PLY: every element's count against the body's lines (ASCII: one line per element, its values
  counted too) or bytes (binary: count × the element's size, where its properties have a fixed
  size; an element with lists is left to trimesh, which refuses a body of the wrong length);
- LAS: the point records' bytes (count × record length after the header's offset to the points)
  against the file's length, or the first extended VLR's offset (LAS 1.4);
- LAZ: the chunk table against the header's count (a chunk count that disagrees, or compressed
  chunks that do not end where the chunk table begins);
- E57: every scan's ``recordCount`` against the records each of its binary streams holds (their
  data packets' bytes over each field's bits per record).

Each returns the points the header declares; :func:`vebuild.project.scans.read_point_cloud`
then checks that it read exactly that many. Layer 3 of DESIGN.md: file I/O, no GL.
"""

from __future__ import annotations

import io
import re
import struct
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from vebuild.errors import ProjectError

#: The longest PLY header read (its lines of elements, properties and comments).
PLY_HEADER_BYTES = 1 << 20
#: Bytes per value of the PLY property types.
PLY_TYPES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
             "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
#: The largest E57 XML section read (it describes the scans and images; a few MiB at most).
E57_XML_BYTES = 64 << 20
_BLOCK = 1 << 24


class _Lie(Exception):
    """A header that disagrees with its body: (the header's field, what disagrees)."""

    def __init__(self, field: str, message: str, unreadable: bool = False) -> None:
        self.field, self.message, self.unreadable = field, message, unreadable
        super().__init__(message)


def declared_points(path: Path, fmt: str, where: str = "") -> int:
    """The points ``path``'s header declares, once its body is found to hold exactly those (module
    docstring); a ProjectError naming the file and the header's field otherwise."""
    check: Callable[[Path], int] = {"ply": _ply, "las": _las, "laz": _las, "e57": _e57}[fmt]
    try:
        return check(path)
    except _Lie as e:
        if e.unreadable:
            raise ProjectError(path, where, f"cannot read it as {fmt.upper()}: {e.field}: {e.message}") from None
        raise ProjectError(path, where, f"its {fmt.upper()} header disagrees with its body, so it is refused: "
                           f"{e.field}: {e.message} (the file is damaged, cut short or written wrongly: export "
                           "the scan again)") from None


# ----------------------------------------------------------------------------------------------
# PLY


def _ply_header(f: IO[bytes]) -> tuple[str, list[tuple[str, int, list[Any]]], int]:
    """(format, [(element, count, [property size, or ("list", count size, item size)])], header bytes)."""
    head = f.read(PLY_HEADER_BYTES)
    end = re.search(rb"end_header[ \t]*\r?\n", head)
    if not head.startswith(b"ply") or end is None:
        raise _Lie("first lines", "expected 'ply' and, within 1 MiB, 'end_header'", True)
    fmt = ""
    elements: list[tuple[str, int, list[Any]]] = []
    for raw in head[: end.start()].decode("ascii", "replace").splitlines()[1:]:
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and re.fullmatch(r"\d{1,30}", words[2]):
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) == 5 and words[1] == "list" \
                and words[2] in PLY_TYPES and words[3] in PLY_TYPES:
            elements[-1][2].append(("list", PLY_TYPES[words[2]], PLY_TYPES[words[3]]))
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in PLY_TYPES:
            elements[-1][2].append(PLY_TYPES[words[1]])
        else:
            raise _Lie(f"line {raw.strip()[:60]!r}", "expected format, element NAME COUNT, property TYPE NAME, "
                       "property list COUNT_TYPE TYPE NAME, comment or end_header", True)
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise _Lie("format", f"expected ascii, binary_little_endian or binary_big_endian, got {fmt or 'none'!r}", True)
    return fmt, elements, end.end()


def _ply(path: Path) -> int:
    size = path.stat().st_size
    with open(path, "rb") as f:
        fmt, elements, start = _ply_header(f)
        vertices = next((n for name, n, _ in elements if name == "vertex"), None)
        if vertices is None:
            raise _Lie("elements", "no 'element vertex': expected the points as vertices")
        declared = ", ".join(f"element {name} {n}" for name, n, _ in elements)
        f.seek(start)
        if fmt == "ascii":
            _ply_ascii_body(f, elements, declared)
        else:
            fixed = [all(isinstance(p, int) for p in props) for _, _, props in elements]
            need = sum(n * sum(props) for (_, n, props), ok in zip(elements, fixed, strict=True) if ok)
            if all(fixed) and need != size - start:
                raise _Lie(declared, f"declares {need} bytes after the header ({fmt}); the file holds "
                           f"{size - start}")
            least = need + sum(n * sum(p if isinstance(p, int) else p[1] for p in props)
                               for (_, n, props), ok in zip(elements, fixed, strict=True) if not ok)
            if least > size - start:
                raise _Lie(declared, f"declares at least {least} bytes after the header ({fmt}); the file "
                           f"holds {size - start}")
    return vertices


def _ply_ascii_body(f: IO[bytes], elements: list[tuple[str, int, list[Any]]], declared: str) -> None:
    """One line per element (blank lines aside), each with as many values as its properties where
    they hold no list."""
    lines = values = 0
    carry = b""
    while block := f.read(_BLOCK):
        block = carry + block
        cut = block.rfind(b"\n") + 1
        whole, carry = block[:cut], block[cut:]
        values += len(whole.split())
        lines += sum(1 for line in whole.split(b"\n")[:-1] if line.strip())
    if carry.strip():
        lines += 1
        values += len(carry.split())
    want = sum(n for _, n, _ in elements)
    if lines != want:
        raise _Lie(declared, f"declares {want} lines of values after the header (ascii); the body holds {lines}")
    if all(isinstance(p, int) for _, _, props in elements for p in props):
        want = sum(n * len(props) for _, n, props in elements)
        if values != want:
            raise _Lie(declared, f"declares {want} values after the header (ascii, one per property); the body "
                       f"holds {values}")


# ----------------------------------------------------------------------------------------------
# LAS and LAZ


def _las(path: Path) -> int:
    import laspy  # type: ignore[import-untyped]

    size = path.stat().st_size
    with laspy.open(str(path)) as reader:
        h = reader.header
        count, start, record = int(h.point_count), int(h.offset_to_point_data), int(h.point_format.size)
        evlrs = int(getattr(h, "number_of_evlrs", 0) or 0)
        first_evlr = int(getattr(h, "start_of_first_evlr", 0) or 0)
        waveforms = int(getattr(h, "start_of_waveform_data_packet_record", 0) or 0)
        laz = next((v for v in h.vlrs if getattr(v, "record_id", None) == 22204), None)
    field = f"point count {count}"
    if start > size:
        raise _Lie(f"offset to point data {start}", f"lies beyond the end of the file ({size} bytes)")
    # The points end where what follows them begins: waveform packets (LAS 1.3), the extended VLRs
    # (LAS 1.4), or the end of the file.
    ends = {"the waveform data packets": waveforms, "the first extended VLR": first_evlr if evlrs else 0,
            "the end of the file": size}
    what, end = min(((w, e) for w, e in ends.items() if start < e <= size), key=lambda we: we[1],
                    default=("the end of the file", size))
    if laz is None:
        if start + count * record != end:
            raise _Lie(field, f"declares {count} points of {record} bytes: {count * record} bytes from byte "
                       f"{start}; {what} is {end - start} bytes from it (room for {(end - start) / record:.6g} "
                       "points)")
        return count
    with open(path, "rb") as f:
        _laz_chunks(f, laz.record_data, count, (start, end, what), field)
    return count


def _laz_chunks(f: IO[bytes], vlr_data: bytes, count: int, span: tuple[int, int, str], field: str) -> None:
    """The chunk table against the header's count, and its chunks and itself from the points' start
    (``span``: start, end, what is at the end) to their end."""
    import lazrs  # type: ignore[import-untyped]

    start, end, what = span
    f.seek(start)
    table_at = struct.unpack("<q", f.read(8).ljust(8, b"\0"))[0]
    if table_at == -1:  # written as a stream: no chunk table to check against
        return
    if not start + 8 <= table_at <= end:
        raise _Lie("chunk table offset", f"{table_at} lies outside the compressed points ({start + 8} to {end})")
    vlr = lazrs.LazVlr(vlr_data)
    f.seek(start)
    try:
        chunks = lazrs.read_chunk_table(f, vlr)
    except Exception as e:  # lazrs raises its own error for a damaged table
        raise _Lie("chunk table", f"cannot be read ({type(e).__name__}: {e})") from None
    stored = start + 8 + sum(int(b) for _, b in chunks)
    if stored != table_at:
        raise _Lie(f"chunk table ({len(chunks)} chunks)", f"its chunks end at byte {stored}, the table "
                   f"begins at byte {table_at}")
    table = io.BytesIO()
    lazrs.write_chunk_table(table, chunks, vlr)  # its length: the table's own coding is deterministic
    if table_at + len(table.getvalue()) != end:
        raise _Lie(f"chunk table ({len(chunks)} chunks)", f"it ends at byte {table_at + len(table.getvalue())}, "
                   f"{what} is at byte {end}")
    if vlr.uses_variable_size_chunks():
        held = sum(int(n) for n, _ in chunks)
        if held != count:
            raise _Lie(field, f"declares {count} points; the chunk table's {len(chunks)} chunks hold {held}")
    elif len(chunks) != -(-count // int(vlr.chunk_size())):
        size = int(vlr.chunk_size())
        raise _Lie(field, f"declares {count} points, {-(-count // size)} chunks of {size}; the chunk table "
                   f"holds {len(chunks)} chunks ({(len(chunks) - 1) * size + 1} to {len(chunks) * size} points)")


# ----------------------------------------------------------------------------------------------
# E57 (ASTM E2807): pages of 1020 bytes of data and a 4-byte checksum


class _Pages:
    """Logical bytes of an E57 file (its pages without their checksums)."""

    def __init__(self, f: IO[bytes], page: int, length: int) -> None:
        self.f, self.page, self.data, self.length = f, page, page - 4, length

    def logical(self, physical: int) -> int:
        return physical // self.page * self.data + physical % self.page

    def read(self, at: int, n: int) -> bytes:
        out = bytearray()
        while len(out) < n:
            page, offset = divmod(at + len(out), self.data)
            if page * self.page >= self.length:
                raise _Lie("binary sections", "a data packet runs past the end of the file")
            self.f.seek(page * self.page + offset)
            out += self.f.read(min(self.data - offset, n - len(out)))
        return bytes(out)


def _bits(node: Any) -> tuple[int, int]:
    """(bits per record, how many records the padding after the last may seem to hold) of a
    prototype field; 0 bits for an integer of one value."""
    kind = node.get("type")
    if kind == "Float":
        return (32, 0) if node.get("precision") == "single" else (64, 0)
    if kind in ("Integer", "ScaledInteger"):
        lo, hi = int(node.get("minimum", -(2**63))), int(node.get("maximum", 2**63 - 1))
        bits = max(hi - lo, 0).bit_length()
        if bits > 64:
            raise _Lie(f"prototype field {node.tag}", f"minimum {lo} and maximum {hi}: more than 64 bits", True)
        # libE57Format packs them in a register of 8 to 64 bits and writes the last one whole; other
        # writers may use another register: allow the padding of the widest.
        return bits, 0 if bits == 0 else 64 // bits
    raise _Lie(f"prototype field {node.tag}", f"expected Float, Integer or ScaledInteger, got {kind!r}", True)


def _e57(path: Path) -> int:
    import xml.etree.ElementTree as ET

    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(48)
        if len(head) < 48 or head[:8] != b"ASTM-E57":
            raise _Lie("signature", "expected the file to begin with ASTM-E57", True)
        _, _, length, xml_at, xml_length, page = struct.unpack("<IIQQQQ", head[8:])
        if length != size or page < 64 or page % 4:
            raise _Lie("filePhysicalLength", f"declares {length} bytes (pages of {page}); the file holds {size}")
        pages = _Pages(f, page, size)
        if xml_length > E57_XML_BYTES:
            raise _Lie("xmlLogicalLength", f"{xml_length} bytes; vebuild reads an XML section of at most "
                       f"{E57_XML_BYTES >> 20} MiB")
        try:
            root = ET.fromstring(pages.read(pages.logical(xml_at), xml_length))
        except ET.ParseError as e:
            raise _Lie("XML section", f"cannot be read ({e})", True) from None
        ns = {"e": root.tag[1:].split("}")[0]} if root.tag.startswith("{") else {}
        pre = "e:" if ns else ""
        total = 0
        scans = root.findall(f"{pre}data3D/{pre}vectorChild", ns)
        for i, scan in enumerate(scans):
            points = scan.find(f"{pre}points", ns)
            proto = None if points is None else points.find(f"{pre}prototype", ns)
            if points is None or proto is None:
                raise _Lie(f"data3D[{i}]", "no points (a CompressedVector with a prototype)")
            n = int(points.get("recordCount", "-1"))
            field = f"data3D[{i}] points recordCount {n}"
            held = _e57_records(pages, int(points.get("fileOffset", "0")), [_bits(c) for c in proto], field)
            for k, (records, slack) in enumerate(held):
                if records is not None and not n <= records <= n + slack:
                    name = list(proto)[k].tag.split("}")[-1]
                    raise _Lie(field, f"declares {n} points; the body's {name} values hold {records}"
                               + (f" (to {records - slack}, less the padding of their last register)" if slack else ""))
            total += n
    return total


def _e57_records(pages: _Pages, section_at: int, fields: list[tuple[int, int]], field: str
                 ) -> list[tuple[int | None, int]]:
    """Per field of a compressed vector: (records its bytestream holds, None for a field of no bits;
    how many of them may be the padding of its last register)."""
    start = pages.logical(section_at)
    head = pages.read(start, 32)
    section_id, _, section_length, data_at, _ = struct.unpack("<B7sQQQ", head)
    if section_id != 1:
        raise _Lie(f"{field} (fileOffset {section_at})", "expected a compressed vector section there")
    at, end = pages.logical(data_at), min(start + section_length, pages.logical(pages.length))
    streams = [0] * len(fields)
    while at < end:
        kind, _, length = struct.unpack("<BBH", pages.read(at, 4))
        if kind == 1:
            (count,) = struct.unpack("<H", pages.read(at + 4, 2))
            if count != len(fields):
                raise _Lie(field, f"a data packet holds {count} bytestreams, the prototype has {len(fields)} fields")
            for k, b in enumerate(struct.unpack(f"<{count}H", pages.read(at + 6, 2 * count))):
                streams[k] += b
        at += length + 1
    return [(None if bits == 0 else 8 * b // bits, slack) for b, (bits, slack) in zip(streams, fields, strict=True)]
