#!/usr/bin/env python3
"""rtpack.py: a reader for rtpack packages (.rtp), written from formats/SPEC.md.

Reads the header, the table of contents and every chunk of a package into structured numpy arrays
whose dtypes carry the field names and widths of the C++ structs in formats/*.h, checks every
CRC-32C the format defines (header, TOC, each chunk's stored bytes), decompresses zstd chunks
(and takes stored ones as they are), and parses each chunk's section table. A bad file raises a
PackageError (or one of its subclasses) whose message names what is wrong (and which chunk / section),
never another exception: every size, offset and count is checked against the file before anything is
allocated or decompressed, the metadata JSON's nesting depth before it is parsed.

    import rtpack
    with rtpack.Package("scene.rtp") as pkg:
        print(pkg.version, pkg.bvh_width, len(pkg.toc))
        descs = pkg.resident(rtpack.KIND_BATCHING_POINTS).get(rtpack.SEC_POINT_DESCS)
        point = pkg.chunk(pkg.find(rtpack.KIND_BATCHING_POINT, 0))
        nodes = point.get(rtpack.SEC_NODES)          # WideNode<W>[]: nodes["lo"].shape == (n, 3, W)

CLI:  python3 python/rtpack.py PKG [--json]   (reads and checks every chunk, prints a summary;
exit 0 fine, 2 usage (argparse), 3 a package that is malformed, unsupported or cannot be read, with one
line "rtpack.py: error: PKG: MESSAGE" on stderr).

Needs numpy and zstandard (Debian: python3-numpy, python3-zstandard) and, for fast checksums,
crcmod (python3-crcmod). Not checked here: the cross-chunk structural invariants of SPEC §4.6
(BVH ranges, DAG well-formedness); `rtpack-inspect --verify` checks those.
"""
import json
import os
import re
import stat
import sys

try:
    import numpy as np
    import zstandard
except ImportError as _ex:  # e.g. a pyenv python3 first on PATH: Debian's python3-* are for /usr/bin/python3
    if __name__ == "__main__" and os.path.exists("/usr/bin/python3") and \
            os.path.realpath(sys.executable) != os.path.realpath("/usr/bin/python3"):
        os.execv("/usr/bin/python3", ["/usr/bin/python3"] + sys.argv)
    raise ImportError(f"rtpack.py needs numpy and zstandard ({_ex}): apt-get install python3-numpy "
                      "python3-zstandard") from _ex

# ---- CRC-32C (SPEC §1.1: Castagnoli, reflected 0x82F63B78, init and final xor 0xFFFFFFFF) ----------
# Debian's python3-crcmod provides it (predefined "crc-32c", C extension, ~300 MB/s) and is already on
# the project's machine images; python3-crc32c (hardware) would also do, but one package is enough.
# Without crcmod a table-driven pure-Python version is used (~5 MB/s, but exact: the test checks both
# against the SPEC's check value and against each other).
_CRC_TABLE = []
for _i in range(256):
    _c = _i
    for _ in range(8):
        _c = (_c >> 1) ^ 0x82F63B78 if _c & 1 else _c >> 1
    _CRC_TABLE.append(_c)


def crc32c_portable(data):
    """CRC-32C of `data` (bytes-like), byte table; the reference for crc32c()."""
    c = 0xFFFFFFFF
    t = _CRC_TABLE
    for b in bytes(data):
        c = t[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


try:
    import crcmod.predefined
    _crc_fast = crcmod.predefined.mkCrcFun("crc-32c")

    def crc32c(data):
        """CRC-32C of `data` (bytes-like)."""
        return _crc_fast(bytes(data) if not isinstance(data, bytes) else data)
except ImportError:  # pragma: no cover - depends on the machine
    crc32c = crc32c_portable

# ---- constants (formats/package.h, chunk.h, dag.h) -------------------------------------------------
MAGIC = b"RTPACK\r\n"
VERSION_MAJOR, VERSION_MINOR = 7, 0
ALIGNMENT = 4096
WIDTHS = (4, 8, 16)  # SPEC §1.1: the BVH width W and the leaf width B are each one of these
CHUNK_MAGIC = 0x48435452  # "RTCH"
MAX_CHUNK_RATIO, MAX_CHUNK_SLACK = 32768, 1 << 20  # SPEC §3: raw_size <= 32768 * stored_size + 2^20
MAX_JSON_DEPTH = 256  # arrays/objects nested deeper in the metadata are refused (lib/core/json_checked.h)
READ_PIECE = 1 << 20  # zstd input and padding checks go through memory in pieces of this size
FLAG_NORMALS, FLAG_UVS, FLAG_DAG = 1, 2, 4
COMPRESSION_NONE, COMPRESSION_ZSTD = 0, 1
CHILD_EMPTY, LEAF_BIT = 0xFFFFFFFF, 0x80000000  # ChildRef (SPEC §2.1)
PIECE_BIT, NO_ATTRIBUTE, NO_SEGMENT = 0x80000000, 0xFFFFFFFF, 0xFFFFFFFF
DAG_EMPTY, DAG_FULL = 0xFFFFFFFE, 0xFFFFFFFF
DAG_BOXES = 0  # DagGrid.resolution of a point culled by its instance boxes (7.0, section SEC_CULL_NODES)

(KIND_METADATA, KIND_TOP_LEVEL_BVH, KIND_BATCHING_POINTS, KIND_INSTANCES, KIND_MESHES, KIND_SOURCE_MAP,
 KIND_DAG_POOL) = range(1, 8)
KIND_BATCHING_POINT, KIND_MESH_SEGMENT, KIND_SEGMENT_ATTRIBUTES, KIND_POINT_ATTRIBUTES = 16, 17, 18, 19
KIND_NAMES = {1: "metadata", 2: "top-level BVH", 3: "batching-point descriptors", 4: "instance table",
              5: "mesh table", 6: "source map", 7: "DAG pool", 16: "batching point", 17: "mesh segment",
              18: "mesh segment attributes", 19: "batching point attributes"}  # as lib/reader/reader.cpp
RESIDENT_KINDS = range(1, 8)

(SEC_NODES, SEC_BLOCKS, SEC_MESH_ENTRIES, SEC_INSTANCE_IDS, SEC_INSTANCES, SEC_GLOBAL_IDS, SEC_MESH_SLOTS,
 SEC_TOP_NODES, SEC_POINT_DESCS, SEC_SEGMENT_REFS, SEC_MESH_TABLE, SEC_SOURCE_PRIMS, SEC_SOURCE_TRIS, SEC_JSON,
 SEC_INSTANCE_NODES, SEC_INSTANCE_BVH, SEC_ATTR_ENTRIES, SEC_ATTR_TRIANGLES, SEC_ATTR_NORMALS, SEC_ATTR_UVS,
 SEC_ATTR_TRI_IDS, SEC_POINT_GRIDS, SEC_DAG_NODES, SEC_DAG_LEAVES, SEC_INSTANCE_REFS, SEC_CULL_NODES) = range(1, 27)
NO_POINT = 0xFFFFFFFF  # InstanceRef.point of an instance no batching point holds


def kind_name(kind):
    return KIND_NAMES.get(int(kind), "unknown kind")


# ---- dtypes: one per C++ struct, little-endian, packed (no struct here has padding) ----------------
def _dt(fields):
    """A packed structured dtype from (name, type[, shape]) tuples, in the struct's field order."""
    return np.dtype(fields, align=False)


# SPEC §1.1 Header (128 B)
HEADER = _dt([("magic", "S8"), ("version_major", "<u4"), ("version_minor", "<u4"), ("flags", "<u8"),
              ("file_size", "<u8"), ("toc_offset", "<u8"), ("toc_count", "<u8"), ("toc_entry_size", "<u4"),
              ("toc_crc32c", "<u4"), ("unique_triangles", "<u8"), ("instanced_triangles", "<u8"),
              ("bounds_lo", "<f4", (3,)), ("bounds_hi", "<f4", (3,)), ("bvh_width", "<u4"),
              ("leaf_width", "<u4"), ("reserved", "u1", (20,)), ("header_crc32c", "<u4")])
# SPEC §3 TocEntry (48 B)
TOC_ENTRY = _dt([("kind", "<u4"), ("compression", "<u4"), ("id", "<u8"), ("offset", "<u8"),
                 ("stored_size", "<u8"), ("raw_size", "<u8"), ("crc32c", "<u4"), ("reserved", "<u4")])
# SPEC §4 ChunkHeader (16 B), SectionEntry (24 B)
CHUNK_HEADER = _dt([("magic", "<u4"), ("kind", "<u4"), ("section_count", "<u4"), ("reserved", "<u4")])
SECTION_ENTRY = _dt([("type", "<u4"), ("elem_size", "<u4"), ("offset", "<u8"), ("count", "<u8")])
# SPEC §2.4 InstanceRecord (72 B): local = inverse_linear @ (world - translation) (translation in double)
INSTANCE_RECORD = _dt([("translation", "<f8", (3,)), ("inverse_linear", "<f4", (3, 3)), ("mesh", "<u4"),
                       ("flags", "<u4"), ("reserved", "<u4")])
# SPEC §2.5 InstanceRef (20 B): where the record of a scene instance is (batching point, index in its section 5)
INSTANCE_REF = _dt([("mesh", "<u4"), ("point", "<u4"), ("local", "<u4"), ("source_node", "<u4"),
                    ("source_gpu_instance", "<u4")])
# SPEC §4.2 MeshEntry (32 B)
MESH_ENTRY = _dt([("id", "<u4"), ("root", "<u4"), ("node_first", "<u4"), ("node_count", "<u4"),
                  ("block_first", "<u4"), ("block_count", "<u4"), ("triangles", "<u8")])
# SPEC §4.1 MeshInfo (32 B)
MESH_INFO = _dt([("segment", "<u4"), ("flags", "<u4"), ("triangles", "<u8"), ("source_prim_first", "<u4"),
                 ("source_prim_count", "<u4"), ("source_tri_first", "<u8")])
# SPEC §4.1 BatchingPointDesc (64 B)
BATCHING_POINT_DESC = _dt([("lo", "<f4", (3,)), ("hi", "<f4", (3,)), ("unique_triangles", "<u8"),
                           ("instanced_triangles", "<u8"), ("instance_count", "<u4"), ("piece_count", "<u4"),
                           ("segment_first", "<u4"), ("segment_count", "<u4"), ("chunk_id", "<u4"),
                           ("reserved", "<u4")])
# SPEC §4.1 TopNode (128 B, formats/top_level.h)
TOP_NODE = _dt([("lo", "<f4", (3, 4)), ("hi", "<f4", (3, 4)), ("child", "<u4", (4,)), ("parent", "<u4"),
                ("slot", "<u4"), ("depth", "<u4"), ("reserved", "<u4")])
# SPEC §4.4 AttributeEntry (40 B)
ATTRIBUTE_ENTRY = _dt([("id", "<u4"), ("mesh", "<u4"), ("triangle_count", "<u4"), ("vertex_count", "<u4"),
                       ("triangle_first", "<u8"), ("normal_first", "<u4"), ("uv_first", "<u4"),
                       ("tri_id_first", "<u4"), ("reserved", "<u4")])
# SPEC §4.5 DagGrid (32 B)
DAG_GRID = _dt([("origin", "<f4", (3,)), ("cell", "<f4"), ("resolution", "<u4"), ("root", "<u4"),
                ("margin", "<f4"), ("ray_rel", "<f4")])


def wide_node(w):
    """SPEC §2.2 WideNode<W> (36·W bytes)."""
    return _dt([("lo", "<f4", (3, w)), ("hi", "<f4", (3, w)), ("child", "<u4", (w,)), ("order", "u1", (8, w))])


def cull_node(w):
    """SPEC §4.5 CullNode<W> (24 + 10·W bytes, 7.0): a box plane is origin + q * scale in double."""
    return _dt([("origin", "<f4", (3,)), ("scale", "<f4", (3,)), ("lo", "u1", (3, w)), ("hi", "u1", (3, w)),
                ("child", "<u4", (w,))])


def leaf_block(b):
    """SPEC §2.3 LeafBlock<B> (40·B bytes)."""
    return _dt([("v0", "<f4", (3, b)), ("v1", "<f4", (3, b)), ("v2", "<f4", (3, b)), ("prim", "<u4", (b,))])


def _check_layouts():
    """The static_asserts of formats/*.h, on the dtypes above."""
    def off(dt, f):
        return dt.fields[f][1]
    assert HEADER.itemsize == 128 and off(HEADER, "toc_offset") == 32 and off(HEADER, "toc_crc32c") == 52
    assert off(HEADER, "bounds_lo") == 72 and off(HEADER, "bvh_width") == 96 and off(HEADER, "header_crc32c") == 124
    assert TOC_ENTRY.itemsize == 48 and off(TOC_ENTRY, "offset") == 16 and off(TOC_ENTRY, "crc32c") == 40
    assert CHUNK_HEADER.itemsize == 16 and SECTION_ENTRY.itemsize == 24 and off(SECTION_ENTRY, "offset") == 8
    assert INSTANCE_RECORD.itemsize == 72 and off(INSTANCE_RECORD, "inverse_linear") == 24
    assert off(INSTANCE_RECORD, "mesh") == 60 and off(INSTANCE_RECORD, "reserved") == 68
    assert INSTANCE_REF.itemsize == 20 and off(INSTANCE_REF, "local") == 8 and off(INSTANCE_REF, "source_gpu_instance") == 16
    assert MESH_ENTRY.itemsize == 32 and off(MESH_ENTRY, "triangles") == 24
    assert MESH_INFO.itemsize == 32 and off(MESH_INFO, "source_tri_first") == 24
    assert BATCHING_POINT_DESC.itemsize == 64 and off(BATCHING_POINT_DESC, "chunk_id") == 56
    assert ATTRIBUTE_ENTRY.itemsize == 40 and off(ATTRIBUTE_ENTRY, "triangle_first") == 16
    assert off(ATTRIBUTE_ENTRY, "tri_id_first") == 32
    assert TOP_NODE.itemsize == 128 and off(TOP_NODE, "child") == 96 and off(TOP_NODE, "parent") == 112
    assert DAG_GRID.itemsize == 32 and off(DAG_GRID, "cell") == 12 and off(DAG_GRID, "root") == 20
    assert off(DAG_GRID, "ray_rel") == 28
    assert [wide_node(w).itemsize for w in (4, 8, 16)] == [144, 288, 576]
    assert off(wide_node(8), "hi") == 96 and off(wide_node(8), "child") == 192 and off(wide_node(8), "order") == 224
    assert [cull_node(w).itemsize for w in (4, 8, 16)] == [64, 104, 184]
    assert off(cull_node(8), "lo") == 24 and off(cull_node(8), "hi") == 48 and off(cull_node(8), "child") == 72
    assert [leaf_block(b).itemsize for b in (4, 8, 16)] == [160, 320, 640]
    assert off(leaf_block(8), "v1") == 96 and off(leaf_block(8), "prim") == 288


_check_layouts()


def section_dtype(sec_type, w, b):
    """The element dtype of section type `sec_type` (SPEC §4) in a package of widths W, B; None if unknown."""
    u4 = np.dtype("<u4")
    return {SEC_NODES: wide_node(w), SEC_BLOCKS: leaf_block(b), SEC_MESH_ENTRIES: MESH_ENTRY, SEC_INSTANCE_IDS: u4,
            SEC_INSTANCES: INSTANCE_RECORD, SEC_GLOBAL_IDS: u4, SEC_MESH_SLOTS: u4, SEC_TOP_NODES: TOP_NODE,
            SEC_POINT_DESCS: BATCHING_POINT_DESC, SEC_SEGMENT_REFS: u4, SEC_MESH_TABLE: MESH_INFO,
            SEC_SOURCE_PRIMS: np.dtype(("<u4", (2,))), SEC_SOURCE_TRIS: np.dtype(("<u4", (2,))),
            SEC_JSON: np.dtype("u1"), SEC_INSTANCE_NODES: wide_node(w), SEC_INSTANCE_BVH: MESH_ENTRY,
            SEC_ATTR_ENTRIES: ATTRIBUTE_ENTRY, SEC_ATTR_TRIANGLES: np.dtype(("<u4", (3,))),
            SEC_ATTR_NORMALS: np.dtype(("<f4", (3,))), SEC_ATTR_UVS: np.dtype(("<f4", (2,))), SEC_ATTR_TRI_IDS: u4,
            SEC_POINT_GRIDS: DAG_GRID, SEC_DAG_NODES: u4, SEC_DAG_LEAVES: np.dtype("<u8"),
            SEC_INSTANCE_REFS: INSTANCE_REF, SEC_CULL_NODES: cull_node(w)}.get(int(sec_type))


# SPEC §4.5 pool: an inner node at word offset `off` of section 23 (words) -- word 0 = child mask
# (bits 0-7) | full mask << 8 | inline mask << 16; then per child in the child mask and not the full mask,
# ascending: an inline child's leaf mask as two words (low half first), otherwise one reference.
def dag_node(words, off):
    """The children of the DAG node at word offset `off`: a list of (child, what, value) with what
    "full" (value None), "inline" (value = the 64-bit leaf mask) or "ref" (value = the reference one
    level below: a word offset, or at level 1 a leaf index into section 24). Raises MalformedError
    when the node (its head word or a child's words) is not inside `words`."""
    off = int(off)
    if not 0 <= off < len(words):
        raise MalformedError(f"DAG node at word {off}: outside the pool's {len(words)} words")
    head = int(words[off])
    cm, fm, im = head & 0xFF, head >> 8 & 0xFF, head >> 16 & 0xFF
    kids = [(c, "full" if fm >> c & 1 else "inline" if im >> c & 1 else "ref") for c in range(8) if cm >> c & 1]
    end = off + 1 + sum({"full": 0, "inline": 2, "ref": 1}[what] for _, what in kids)
    if end > len(words):
        raise MalformedError(f"DAG node at word {off}: runs past the pool's {len(words)} words")
    out, at = [], off + 1
    for c, what in kids:
        if what == "full":
            out.append((c, what, None))
        elif what == "inline":
            out.append((c, what, int(words[at]) | int(words[at + 1]) << 32))
            at += 2
        else:
            out.append((c, what, int(words[at])))
            at += 1
    return out


# ---- errors ------------------------------------------------------------------------------------------
class PackageError(ValueError):
    """The package is malformed or unsupported (the C++ tools exit 3)."""


class TruncatedError(PackageError):
    pass


class BadMagicError(PackageError):
    pass


class VersionError(PackageError):
    pass


class ChecksumError(PackageError):
    pass


class MalformedError(PackageError):
    pass


# ---- chunks ------------------------------------------------------------------------------------------
class Chunk:
    """One decoded chunk: `raw` bytes, its ChunkHeader, its SectionEntry table and `sections`
    {type: numpy array of `count` elements} (read-only views of `raw`; unknown section types are
    uint8 arrays of shape (count, elem_size))."""

    def __init__(self, index, entry, label, raw, header, table, sections):
        self.index, self.entry, self.label, self.raw = index, entry, label, raw
        self.kind, self.id = int(entry["kind"]), int(entry["id"])
        self.header, self.table, self.sections = header, table, sections

    def has(self, sec_type):
        return int(sec_type) in self.sections

    def get(self, sec_type, required=True):
        """Section `sec_type`'s array; None (or MalformedError if required) when absent."""
        a = self.sections.get(int(sec_type))
        if a is None and required:
            raise MalformedError(f"{self.label}: missing section {int(sec_type)}")
        return a


def parse_chunk(raw, kind, label, w, b):
    """SPEC §4: ChunkHeader, then section_count SectionEntry records; each section at a multiple of 64
    inside the chunk, with the element size this reader expects for its type."""
    size = len(raw)
    if size < CHUNK_HEADER.itemsize:
        raise MalformedError(f"{label}: too short for a chunk header ({size} bytes)")
    h = np.frombuffer(raw, CHUNK_HEADER, 1)[0]
    if h["magic"] != CHUNK_MAGIC:
        raise MalformedError(f"{label}: bad chunk magic 0x{int(h['magic']):08x} (expected \"RTCH\")")
    if h["kind"] != kind:
        raise MalformedError(f"{label}: chunk says kind {int(h['kind'])}, the table of contents {kind}")
    n = int(h["section_count"])
    if n > (size - CHUNK_HEADER.itemsize) // SECTION_ENTRY.itemsize:
        raise MalformedError(f"{label}: section table out of bounds ({n} sections in {size} bytes)")
    table = np.frombuffer(raw, SECTION_ENTRY, n, CHUNK_HEADER.itemsize)
    sections = {}
    for e in table:
        t, es, off, cnt = int(e["type"]), int(e["elem_size"]), int(e["offset"]), int(e["count"])
        if off % 64 or off > size or es == 0 or cnt > (size - off) // es:
            raise MalformedError(f"{label}: section {t} out of bounds (offset {off}, {cnt} x {es} bytes, "
                                 f"chunk {size} bytes)")
        if t in sections:  # a repeated type: the first entry wins, as in the C++ reader
            continue
        dt = section_dtype(t, w, b)
        if dt is None:  # a section type this reader does not know: kept as bytes (SPEC §4: skipped)
            sections[t] = np.frombuffer(raw, np.uint8, cnt * es, off).reshape(cnt, es)
        elif es != dt.itemsize:
            raise MalformedError(f"{label}: section {t} has elements of {es} bytes, expected {dt.itemsize}")
        else:
            sections[t] = np.frombuffer(raw, dt, cnt, off)
    return h, table, sections


def _unzstd(stored, raw_size, label):
    """The one zstd frame `stored`, which must decode to exactly raw_size bytes (already checked against
    the frame header and SPEC §3's ratio). Neither size is believed before the bytes exist, as in the C++
    reader: the input goes in pieces and the output only grows with what the frame really decodes to,
    refused as soon as it passes raw_size."""
    d = zstandard.ZstdDecompressor().decompressobj()
    view, parts, done, fed = memoryview(stored), [], 0, 0
    try:
        while fed < len(view) and not d.eof:
            part = d.decompress(view[fed:fed + READ_PIECE])
            fed = min(len(view), fed + READ_PIECE)
            done += len(part)
            if done > raw_size:
                raise MalformedError(f"{label}: zstd decompression failed (the frame decodes to more than "
                                     f"raw_size {raw_size})")
            parts.append(part)
    except zstandard.ZstdError as ex:
        raise MalformedError(f"{label}: zstd decompression failed ({ex})") from None
    after = len(d.unused_data) + len(view) - fed
    if done != raw_size or not d.eof or after:
        raise MalformedError(f"{label}: zstd decompression failed ({done} bytes of {raw_size}, "
                             f"{after} bytes after the frame)")
    return b"".join(parts)


def check_json_depth(text, what):
    """Refuses JSON text (bytes) nesting arrays/objects more than MAX_JSON_DEPTH levels deep, before any
    parser sees it (json.loads recurses: 100000 '[' would be a RecursionError). As jsonc::check_depth:
    brackets inside strings (escapes included) do not count, the message gives the byte offset."""
    if text.count(b"[") + text.count(b"{") <= MAX_JSON_DEPTH:  # cannot be deeper: the common case
        return
    blanked = _JSON_STRING.sub(lambda m: bytes(len(m[0])), text)  # same length: offsets stay true
    b = np.frombuffer(blanked, np.uint8)
    step = np.isin(b, _JSON_OPEN).astype(np.int64) - np.isin(b, _JSON_CLOSE)
    deep = np.flatnonzero(np.cumsum(step) > MAX_JSON_DEPTH)
    if len(deep):
        raise MalformedError(f"{what}JSON nested more than {MAX_JSON_DEPTH} levels deep (at byte {int(deep[0])})")


# A JSON string: from its quote to the next unescaped quote (or the end of the text, unterminated).
_JSON_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"?', re.DOTALL)
_JSON_OPEN, _JSON_CLOSE = np.frombuffer(b"[{", np.uint8), np.frombuffer(b"]}", np.uint8)


# ---- the package -------------------------------------------------------------------------------------
class Package:
    """An open .rtp package. The constructor checks the header and the TOC (SPEC §1.1 order);
    chunks are read, CRC-checked and decompressed on demand (chunk(), read(), verify())."""

    def __init__(self, path):
        self.path = path
        self._fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO must not block the open
        try:
            if not stat.S_ISREG(os.fstat(self._fd).st_mode):
                raise OSError(f"cannot open '{path}': is not a regular file")
            self._open()
        except BaseException:
            os.close(self._fd)
            self._fd = -1
            raise

    def close(self):
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        if getattr(self, "_fd", -1) >= 0:
            self.close()

    def _pread(self, offset, size, what):
        out = bytearray()
        while len(out) < size:
            part = os.pread(self._fd, size - len(out), offset + len(out))
            if not part:
                raise TruncatedError(f"{what}: truncated file (wanted {size} bytes at offset {offset}, "
                                     f"got {len(out)})")
            out += part
        return bytes(out)

    # SPEC §1.1: a reader checks, in this order: size >= 4096, magic, major version, header CRC,
    # file_size, TOC bounds, TOC CRC, every entry inside [4096, toc_offset) and aligned.
    def _open(self):
        st = os.fstat(self._fd)
        self.file_size = st.st_size
        if self.file_size < ALIGNMENT:
            head = os.pread(self._fd, min(self.file_size, 8), 0)
            if head and head != MAGIC[:len(head)]:  # does not even start like a package
                raise BadMagicError(f"not an rtpack package (bad magic; {self.file_size} bytes)")
            raise TruncatedError(f"truncated file: {self.file_size} bytes, smaller than the {ALIGNMENT}-byte "
                                 "header block")
        block = self._pread(0, ALIGNMENT, "header")
        h = self.header = np.frombuffer(block, HEADER, 1)[0]
        if bytes(block[:8]) != MAGIC:
            raise BadMagicError("not an rtpack package (bad magic)")
        major, minor = int(h["version_major"]), int(h["version_minor"])
        if major != VERSION_MAJOR:
            raise VersionError(f"package version {major}.{minor} is not supported by this reader (version "
                               f"{VERSION_MAJOR}.x)" + (": it was written by an older rtpack-convert; convert "
                                                        "the source again" if major < VERSION_MAJOR else ""))
        hcrc = crc32c(block[:124])
        if hcrc != h["header_crc32c"]:
            raise ChecksumError(f"header checksum mismatch (stored {int(h['header_crc32c']):08x}, computed "
                                f"{hcrc:08x}): corrupt header")
        if h["file_size"] > self.file_size:
            raise TruncatedError(f"truncated file: header says {int(h['file_size'])} bytes, the file has "
                                 f"{self.file_size}")
        if h["file_size"] < self.file_size:
            raise MalformedError(f"the file has {self.file_size - int(h['file_size'])} bytes more than the header's "
                                 f"{int(h['file_size'])} (data appended after the package?)")
        # SPEC §1.1 / §3: the TOC lies inside the file; entries may be longer than 48 bytes in a newer
        # minor version, a reader uses their prefix.
        toff, tcount, tsize = int(h["toc_offset"]), int(h["toc_count"]), int(h["toc_entry_size"])
        if (tsize < TOC_ENTRY.itemsize or toff % ALIGNMENT or toff < ALIGNMENT or toff > self.file_size
                or tcount * tsize > self.file_size - toff):
            raise MalformedError(f"table of contents out of bounds (offset {toff}, {tcount} entries)")
        toc_bytes = self._pread(toff, tcount * tsize, "table of contents")
        tcrc = crc32c(toc_bytes)
        if tcrc != h["toc_crc32c"]:
            raise ChecksumError(f"table of contents checksum mismatch (stored {int(h['toc_crc32c']):08x}, "
                                f"computed {tcrc:08x})")
        # Each entry's 48-byte prefix, whatever toc_entry_size (up to 2^32 - 1) is: no dtype of that size.
        rows = np.frombuffer(toc_bytes, np.uint8).reshape(tcount, tsize)[:, :TOC_ENTRY.itemsize]
        self.toc = rows.copy().view(TOC_ENTRY).reshape(tcount)  # a writable copy, as before
        for i, e in enumerate(self.toc):
            off, stored = int(e["offset"]), int(e["stored_size"])
            if off % ALIGNMENT or off < ALIGNMENT or stored > toff or off > toff - stored:
                raise MalformedError(f"{self.label(i)}: out of bounds ({stored} bytes)")
            self._check_sizes(i)
        self.version = f"{major}.{minor}"
        self.flags = int(h["flags"])
        self.bvh_width, self.leaf_width = int(h["bvh_width"]), int(h["leaf_width"])
        if self.bvh_width not in WIDTHS or self.leaf_width not in WIDTHS:  # SPEC §1.1; they size every dtype
            raise MalformedError(f"header: unsupported BVH width {self.bvh_width} / leaf width {self.leaf_width}")

    # SPEC §3, as PackageReader::check_sizes: every declared raw size checked when the TOC is read, so that
    # nothing is ever sized from one the reader would refuse at decode.
    def _check_sizes(self, i):
        e = self.toc[i]
        raw, stored = int(e["raw_size"]), int(e["stored_size"])
        if int(e["compression"]) == COMPRESSION_NONE:
            if raw != stored:
                raise MalformedError(f"{self.label(i)}: raw_size {raw} differs from the {stored} stored bytes of an "
                                     "uncompressed chunk")
        elif raw > MAX_CHUNK_RATIO * stored + MAX_CHUNK_SLACK:
            raise MalformedError(f"{self.label(i)}: raw_size {raw} is more than {MAX_CHUNK_RATIO} times the "
                                 f"{stored} stored bytes (the limit of formats/SPEC.md §3)")

    def label(self, i):
        """The C++ reader's name for chunk i: "batching point 3 (chunk #9 at offset 40960)"."""
        e = self.toc[i]
        return f"{kind_name(e['kind'])} {int(e['id'])} (chunk #{i} at offset {int(e['offset'])})"

    def find(self, kind, cid=0):
        """Index in toc of chunk (kind, id), or None."""
        hit = np.nonzero((self.toc["kind"] == kind) & (self.toc["id"] == cid))[0]
        return int(hit[0]) if len(hit) else None

    def read_stored(self, i):
        e = self.toc[i]
        return self._pread(int(e["offset"]), int(e["stored_size"]), self.label(i))

    # SPEC §3: the CRC of the stored bytes is checked before decompression; a zstd frame must declare
    # raw_size as its content size (raw_size <= 32768 * stored_size + 2^20 was checked at open).
    def read(self, i):
        """Chunk i's raw (decompressed) bytes, CRC-checked."""
        e, label = self.toc[i], self.label(i)
        stored = self.read_stored(i)
        c = crc32c(stored)
        if c != e["crc32c"]:
            raise ChecksumError(f"{label}: checksum mismatch (stored {int(e['crc32c']):08x}, computed {c:08x}): "
                                "corrupt chunk")
        raw_size, comp = int(e["raw_size"]), int(e["compression"])
        if comp == COMPRESSION_NONE:
            return stored  # raw_size = stored_size (_check_sizes)
        if comp != COMPRESSION_ZSTD:
            raise MalformedError(f"{label}: unknown compression {comp}")
        try:
            declared = zstandard.frame_content_size(stored)
        except zstandard.ZstdError:
            declared = "an invalid header"
        if declared != raw_size:
            what = "no size" if declared == -1 else declared if isinstance(declared, str) else f"{declared} bytes"
            raise MalformedError(f"{label}: zstd frame declares {what}, the table of contents raw_size {raw_size}")
        return _unzstd(stored, raw_size, label)  # raw_size within SPEC §3's ratio (_check_sizes)

    def chunk(self, i):
        """Chunk i read, checked and parsed into a Chunk. Unknown kinds: raw bytes only (no sections)."""
        raw = self.read(i)
        e = self.toc[i]
        if int(e["kind"]) not in KIND_NAMES:  # SPEC §3: readers skip kinds they do not know
            return Chunk(i, e, self.label(i), raw, None, None, {})
        h, table, sections = parse_chunk(raw, int(e["kind"]), self.label(i), self.bvh_width, self.leaf_width)
        return Chunk(i, e, self.label(i), raw, h, table, sections)

    def resident(self, kind):
        """The resident chunk (kind, id 0), parsed; None when absent (only the DAG pool may be)."""
        i = self.find(kind, 0)
        return None if i is None else self.chunk(i)

    def require(self, kind):
        """The resident chunk (kind, id 0), parsed; MalformedError naming it when the package has none."""
        c = self.resident(kind)
        if c is None:
            raise MalformedError(f"missing {kind_name(kind)} chunk (kind {int(kind)}, id 0): the table of "
                                 f"contents has {len(self.toc)} entries, none of them this chunk")
        return c

    def instance_records(self):
        """Every scene instance's record in instance-table order (INSTANCE_RECORD[]), read from the batching
        point and local index its InstanceRef names (SPEC §2.5: records live only in the points since 5.0).
        `mesh` is the scene mesh, not the stored point-local slot; an instance no point holds (a mesh without
        triangles) is an all-zero row. Raises MalformedError when a place holds another instance."""
        refs = self.require(KIND_INSTANCES).get(SEC_INSTANCE_REFS)
        out = np.zeros(len(refs), dtype=INSTANCE_RECORD)
        placed = np.nonzero(refs["point"] != NO_POINT)[0]
        placed = placed[np.argsort(refs["point"][placed], kind="stable")]  # grouped by point, one pass
        pts = refs["point"][placed]
        starts = np.flatnonzero(np.r_[True, pts[1:] != pts[:-1]]) if len(pts) else np.zeros(0, np.int64)
        for s, e in zip(starts, np.r_[starts[1:], len(pts)]):
            p, here = int(pts[s]), placed[s:e]
            i = self.find(KIND_BATCHING_POINT, p)
            c = None if i is None else self.chunk(i)
            recs = c.get(SEC_INSTANCES) if c else np.zeros(0, INSTANCE_RECORD)
            gids = c.get(SEC_GLOBAL_IDS) if c else np.zeros(0, "<u4")
            local = refs["local"][here].astype(np.int64)
            ok = local < min(len(recs), len(gids))
            ok[ok] = gids[local[ok]] == here[ok]
            if not ok.all():
                g = int(here[np.argmin(ok)])
                raise MalformedError(f"instance table: instance {g} is placed at batching point {p} record "
                                     f"{int(refs['local'][g])}, which does not hold it")
            out[here] = recs[local]
        out["mesh"] = refs["mesh"]
        return out

    def metadata(self):
        """The metadata JSON (SPEC §4.1, section 14) as a dict; its nesting depth checked first."""
        c = self.require(KIND_METADATA)
        text = c.get(SEC_JSON).tobytes()
        check_json_depth(text, f"{c.label}: metadata ")
        # ValueError: also an integer of more digits than int() takes; RecursionError: cannot happen after
        # check_json_depth (256 levels), unless the caller is itself deep in recursion.
        try:
            meta = json.loads(text.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as ex:
            raise MalformedError(f"{c.label}: metadata is not UTF-8 JSON ({ex})") from None
        if not isinstance(meta, dict):
            raise MalformedError(f"{c.label}: metadata is not a JSON object")
        return meta

    def chunks(self):
        """Every chunk, in TOC order, read, checked and parsed."""
        for i in range(len(self.toc)):
            yield self.chunk(i)

    # SPEC §1: zeros after the 128-byte header up to 4096 and between chunks, chunks not overlapping,
    # the file ending with the TOC (the bytes no checksum covers); messages as rtpack-inspect --verify's.
    def check_padding(self):
        def zeros(start, end, what):  # in pieces: a padding's size is the file's word, not memory's
            for at in range(start, end, READ_PIECE):
                block = np.frombuffer(self._pread(at, min(READ_PIECE, end - at), what), np.uint8)
                nz = np.flatnonzero(block)
                if len(nz):
                    raise MalformedError(f"{what}: byte {at + int(nz[0])} of the file is not 0")
        zeros(HEADER.itemsize, ALIGNMENT, "header block padding (bytes 128..4095)")
        end, after = ALIGNMENT, "the header block"
        for i in np.argsort(self.toc["offset"], kind="stable"):
            off = int(self.toc[i]["offset"])
            if off < end:
                raise MalformedError(f"{self.label(i)}: overlaps {after}")
            zeros(end, off, f"padding after {after}")
            end, after = max(end, off + int(self.toc[i]["stored_size"])), self.label(i)
        zeros(end, int(self.header["toc_offset"]), f"padding after {after}")
        toc_end = int(self.header["toc_offset"]) + len(self.toc) * int(self.header["toc_entry_size"])
        if toc_end != self.file_size:
            raise MalformedError(f"file: {self.file_size - toc_end} bytes after the table of contents")

    # SPEC §1.1, §3: unknown flag bits and reserved fields 0; (kind, id) unique; resident chunks id 0.
    def check_toc(self):
        if self.flags & ~(FLAG_NORMALS | FLAG_UVS | FLAG_DAG) or any(self.header["reserved"]):
            raise MalformedError("header: flags or reserved bytes are not 0")
        seen = set()
        for i, e in enumerate(self.toc):
            key = (int(e["kind"]), int(e["id"]))
            if key in seen:
                raise MalformedError(f"{self.label(i)}: a second chunk of this kind with this id")
            seen.add(key)
            if key[0] in RESIDENT_KINDS and key[1] != 0:
                raise MalformedError(f"{self.label(i)}: a resident chunk with an id other than 0")
            if e["reserved"]:
                raise MalformedError(f"{self.label(i)}: table-of-contents entry has a non-zero reserved field")

    def verify(self):
        """check_toc(), check_padding(), then every chunk read, checked and parsed; raises on the first
        problem."""
        self.check_toc()
        self.check_padding()
        for _ in self.chunks():
            pass

    def summary(self):
        """A dict of what the package holds, from the header, TOC and resident chunks."""
        h = self.header
        kinds = {}
        for e in self.toc:
            k = kinds.setdefault(kind_name(e["kind"]), {"chunks": 0, "raw_bytes": 0, "stored_bytes": 0})
            k["chunks"] += 1
            k["raw_bytes"] += int(e["raw_size"])
            k["stored_bytes"] += int(e["stored_size"])
        descs = self.require(KIND_BATCHING_POINTS)
        d = descs.get(SEC_POINT_DESCS)
        grids = descs.get(SEC_POINT_GRIDS, required=False)
        pool = self.resident(KIND_DAG_POOL)
        meshes = self.require(KIND_MESHES).get(SEC_MESH_TABLE)
        top = self.require(KIND_TOP_LEVEL_BVH).get(SEC_TOP_NODES)
        meta = self.metadata()
        cameras = meta.get("cameras", [])
        if not isinstance(cameras, list):
            raise MalformedError(f"{self.label(self.find(KIND_METADATA))}: metadata /cameras: not an array")
        return {
            "file": self.path, "package_bytes": self.file_size, "version": self.version,
            "attributes": [n for bit, n in ((FLAG_NORMALS, "normal"), (FLAG_UVS, "uv")) if self.flags & bit],
            "bvh_width": self.bvh_width, "leaf_width": self.leaf_width,
            "unique_triangles": int(h["unique_triangles"]), "instanced_triangles": int(h["instanced_triangles"]),
            "bounds": {"min": [float(x) for x in h["bounds_lo"]], "max": [float(x) for x in h["bounds_hi"]]},
            "toc_entries": len(self.toc), "by_kind": kinds,
            "batching_points": len(d), "pieces": int(d["piece_count"].sum()),
            "point_instances": int(d["instance_count"].sum()),
            "mesh_segments": int((self.toc["kind"] == KIND_MESH_SEGMENT).sum()),
            "meshes": len(meshes), "segment_meshes": int((meshes["segment"] != NO_SEGMENT).sum()),
            "instances": len(self.require(KIND_INSTANCES).get(SEC_INSTANCE_REFS)),
            "top_level": {"nodes": len(top), "max_depth": int(top["depth"].max()) + 1 if len(top) else 0},
            "dag": {"present": pool is not None, "grids": 0 if grids is None else len(grids),
                    "pool_bytes": 0 if pool is None else pool.get(SEC_DAG_NODES).nbytes + pool.get(SEC_DAG_LEAVES).nbytes},
            "source": meta.get("source"), "tool_version": meta.get("tool_version"),
            "cameras": len(cameras),
        }


def print_summary(s):
    """The summary dict of Package.summary() as text, on stdout."""
    b = s["bounds"]
    print(f"package       {s['file']}: {s['package_bytes']:,} bytes, version {s['version']}, {s['toc_entries']} chunks")
    print(f"  widths      W = {s['bvh_width']}, B = {s['leaf_width']}; attributes: "
          f"{', '.join(s['attributes']) or 'none'}")
    print(f"  triangles   {s['unique_triangles']:,} unique, {s['instanced_triangles']:,} instanced; {s['meshes']} meshes "
          f"({s['segment_meshes']} in {s['mesh_segments']} segments), {s['instances']} instances")
    print(f"  bounds      min ({', '.join(f'{x:g}' for x in b['min'])})  max ({', '.join(f'{x:g}' for x in b['max'])})")
    print(f"  points      {s['batching_points']} batching points ({s['pieces']} pieces, {s['point_instances']} "
          f"instances); top level {s['top_level']['nodes']} nodes, {s['top_level']['max_depth']} levels")
    dag = s["dag"]
    print("  culling     " + (f"{dag['grids']} grids, pool {dag['pool_bytes']:,} bytes" if dag["present"] else "no DAGs"))
    for name, k in s["by_kind"].items():
        print(f"  {name:<28} {k['chunks']:6} chunks {k['raw_bytes']:>14,} raw {k['stored_bytes']:>14,} stored")
    print(f"  source      {s['source']} ({s['tool_version']}), {s['cameras']} cameras")
    print("ok: " + s["checked"])


def main(argv=None):
    """The command line: 0 read and checked, 2 usage (argparse), 3 a package that cannot be read or is
    malformed (one line on stderr, no traceback)."""
    import argparse
    ap = argparse.ArgumentParser(prog="rtpack.py", description="Read and check an rtpack package (every CRC, "
                                                               "every chunk); print a summary.")
    ap.add_argument("package")
    ap.add_argument("--json", action="store_true", help="print the summary as JSON")
    a = ap.parse_args(argv)
    try:
        with Package(a.package) as pkg:
            pkg.verify()
            s = pkg.summary()
    except (PackageError, OSError) as ex:
        why = ex.strerror if isinstance(ex, OSError) and ex.strerror else str(ex)
        print(f"{ap.prog}: error: {a.package}: {why}".replace("\n", " "), file=sys.stderr)
        return 3
    s["checked"] = "every checksum, zstd frame and section table"
    # Metadata strings (source, tool_version) are the package's: never an encoding error on printing them.
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(errors="backslashreplace")
    if a.json:
        print(json.dumps(s, indent=2))
    else:
        print_summary(s)
    return 0


if __name__ == "__main__":
    sys.exit(main())
