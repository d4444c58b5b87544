#!/usr/bin/env python3
"""python/rtpack.py on hostile packages: one exception type, a message naming the object, exit 3.

Converts one sample (Suzanne) with rtpack-convert, then builds hostile copies of it by patching bytes
and re-sealing every checksum the patch touches (chunk, table of contents, header: the CRC-32C of
formats/SPEC.md §1.1, computed by crcmod, not by the reader under test), so that what is
exercised is the check behind the checksums: deeply nested metadata JSON, TOC entries of 2^63 bytes or
past the end of the file, a huge toc_entry_size, zstd frames declaring 3 GiB, hostile section tables,
truncations, resident chunks removed or renamed, bit flips left unsealed, other major versions.

For each, the library raises a rtpack.PackageError (nothing else: a RecursionError, OverflowError,
AttributeError, IndexError, zstd or numpy error fails the test) whose message names the offending chunk
or field, and `python3 python/rtpack.py PKG` exits 3 with that message as its one stderr line (no
traceback) and under 256 MB of peak memory. Also: a usage error exits 2, an unreadable path 3, the intact
package reads and exits 0.

Run:   python3 tests/python/test_rtpack_hostile.py --build build [-v] [unittest args]
       (or RTPACK_BUILD=build ...); CTest: `ctest -R python_reader_hostile`.
Needs: a built build/rtpack-convert; python3-numpy, python3-zstandard, python3-crcmod.
"""
import concurrent.futures
import contextlib
import io
import os
import resource
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

from reader_env import ROOT, rtpack  # re-runs under Debian's /usr/bin/python3 when needed

import crcmod.predefined  # noqa: E402
import numpy as np  # noqa: E402
import zstandard  # noqa: E402

BUILD = os.environ.get("RTPACK_BUILD", os.path.join(ROOT, "build"))
SAMPLE = os.path.join(ROOT, "samples", "khronos", "Suzanne", "glTF", "Suzanne.gltf")
CLI = os.path.join(ROOT, "python", "rtpack.py")
TIMEOUT = 60
MAX_CLI_RSS_KB = 256 * 1024  # a refusal allocates nothing of what the package declares
GIB3 = 3 << 30

# The checksums are sealed by crcmod (python3-crcmod), not by the reader under test.
crc32c = crcmod.predefined.mkPredefinedCrcFun("crc-32c")


# ---- building hostile packages -------------------------------------------------------------------------
# Header fields (SPEC §1.1) and TocEntry fields (SPEC §3): byte offset and struct format.
HEADER_FIELDS = {"version_major": (8, "<I"), "file_size": (24, "<Q"), "toc_offset": (32, "<Q"),
                 "toc_count": (40, "<Q"), "toc_entry_size": (48, "<I"), "bvh_width": (96, "<I"),
                 "leaf_width": (100, "<I")}
TOC_FIELDS = {"kind": (0, "<I"), "compression": (4, "<I"), "id": (8, "<Q"), "offset": (16, "<Q"),
              "stored_size": (24, "<Q"), "raw_size": (32, "<Q"), "crc32c": (40, "<I")}


class Patch:
    """A copy of a package's bytes to patch; seal() re-computes the TOC and header checksums."""

    def __init__(self, data):
        self.buf = bytearray(data)

    def get(self, field):
        at, f = HEADER_FIELDS[field]
        return struct.unpack_from(f, self.buf, at)[0]

    def set(self, **fields):
        for k, v in fields.items():
            at, f = HEADER_FIELDS[k]
            struct.pack_into(f, self.buf, at, v)
        return self

    def entry_at(self, i):
        return self.get("toc_offset") + i * self.get("toc_entry_size")

    def entry(self, i, field):
        at, f = TOC_FIELDS[field]
        return struct.unpack_from(f, self.buf, self.entry_at(i) + at)[0]

    def set_entry(self, i, **fields):
        for k, v in fields.items():
            at, f = TOC_FIELDS[k]
            struct.pack_into(f, self.buf, self.entry_at(i) + at, v)
        return self

    def count(self):
        return self.get("toc_count")

    def find(self, kind):
        return next(i for i in range(self.count()) if self.entry(i, "kind") == kind)

    def replace_chunk(self, i, stored, raw_size, compression):
        """Chunk i's stored bytes become `stored` (in its old place, the rest of which is zeroed), with its
        TOC entry and chunk CRC to match."""
        off, old = self.entry(i, "offset"), self.entry(i, "stored_size")
        room = -(-old // rtpack.ALIGNMENT) * rtpack.ALIGNMENT
        assert len(stored) <= room, f"{len(stored)} bytes do not fit in chunk {i}'s {room}"
        self.buf[off:off + room] = stored + bytes(room - len(stored))
        return self.set_entry(i, stored_size=len(stored), raw_size=raw_size, compression=compression,
                              crc32c=crc32c(stored))

    def drop(self, keep):
        """The TOC reduced to the entries for which keep(i) is true; the others' chunks zeroed."""
        tsize, entries = self.get("toc_entry_size"), []
        for i in range(self.count()):
            if keep(i):
                entries.append(bytes(self.buf[self.entry_at(i):self.entry_at(i) + tsize]))
            else:
                off = self.entry(i, "offset")
                self.buf[off:off + self.entry(i, "stored_size")] = bytes(self.entry(i, "stored_size"))
        toc = self.get("toc_offset")
        del self.buf[toc:]
        self.buf += b"".join(entries)
        return self.set(toc_count=len(entries), file_size=len(self.buf))

    def flip(self, at, bit=0):
        self.buf[at] ^= 1 << bit
        return self

    def seal(self):
        toc = self.get("toc_offset")
        n = self.count() * self.get("toc_entry_size")
        if toc + n <= len(self.buf):
            struct.pack_into("<I", self.buf, 52, crc32c(self.buf[toc:toc + n]))
        struct.pack_into("<I", self.buf, 124, crc32c(self.buf[:124]))
        return bytes(self.buf)


def chunk_bytes(kind, sections):
    """A raw chunk (SPEC §4): ChunkHeader, SectionEntry table, each section at a multiple of 64.
    `sections`: (type, elem_size, count, data) or (type, elem_size, count, None, offset) for a lying entry."""
    body, table = bytearray(), []
    start = -(-(16 + 24 * len(sections)) // 64) * 64
    for s in sections:
        if s[3] is None:
            table.append(struct.pack("<IIQQ", s[0], s[1], s[4], s[2]))
            continue
        body += bytes(-(start + len(body)) % 64)
        table.append(struct.pack("<IIQQ", s[0], s[1], start + len(body), s[2]))
        body += s[3]
    head = struct.pack("<IIII", rtpack.CHUNK_MAGIC, kind, len(sections), 0) + b"".join(table)
    return head + bytes(start - len(head)) + bytes(body)


def metadata_chunk(text):
    return chunk_bytes(rtpack.KIND_METADATA, [(rtpack.SEC_JSON, 1, len(text), text)])


def zstd_frame(declared, rle_bytes):
    """A hand-made zstd frame: single segment, 4-byte content size `declared`, then one last RLE block
    decoding to `rle_bytes` zeros (13 bytes, whatever it declares)."""
    block = 1 | 1 << 1 | rle_bytes << 3  # last block, type RLE, size
    return struct.pack("<IBI", 0xFD2FB528, 2 << 6 | 1 << 5, declared) + block.to_bytes(3, "little") + b"\0"


def read_all(p):
    """What the command line does with a package."""
    p.verify()
    p.summary()


def open_only(p):
    """Nothing: the package is to be refused when it is opened, before any chunk is read."""


def run_main(args):
    """(exit code, stderr) of rtpack.main(ARGS), in this process: the command line without the ~0.25 s
    of starting Python and importing numpy."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = rtpack.main(args)
        except SystemExit as ex:  # argparse
            code = ex.code
    return code, err.getvalue()


def peak_rss_kb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def run_cli(args):
    """(exit code, stderr, peak RSS in KiB) of `python3 python/rtpack.py ARGS`, a process of its own."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        p = subprocess.Popen([sys.executable, CLI] + args, stdout=out, stderr=err)
        try:
            _, status, usage = os.wait4(p.pid, 0)
        except BaseException:
            p.kill()
            raise
        p.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return p.returncode, err.read().decode("utf-8", "replace"), usage.ru_maxrss


class Hostile(unittest.TestCase):
    """Each case: (name, package bytes, library call, substrings its message must contain)."""

    @classmethod
    def setUpClass(cls):
        convert = os.path.join(BUILD, "rtpack-convert")
        if not os.access(convert, os.X_OK):
            raise AssertionError(f"{convert} not found: build the repo first (cmake --build {BUILD})")
        cls.tmp = tempfile.mkdtemp(prefix="rtpack-py-hostile-")
        cls.src = os.path.join(cls.tmp, "good.rtp")
        subprocess.run([convert, SAMPLE, "-o", cls.src, "-q", "--threads", "1"], check=True, timeout=TIMEOUT)
        with open(cls.src, "rb") as f:
            cls.good = f.read()
        with rtpack.Package(cls.src) as p:
            cls.labels = [p.label(i) for i in range(len(p.toc))]
        base = Patch(cls.good)
        cls.meta = base.find(rtpack.KIND_METADATA)
        cls.top = base.find(rtpack.KIND_TOP_LEVEL_BVH)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_own_crc32c(self):
        self.assertEqual(crc32c(b"123456789"), 0xE3069283)  # SPEC §1.1 check value
        self.assertEqual(Patch(self.good).seal(), self.good)  # sealing an untouched package changes nothing

    def write(self, data, name):
        path = os.path.join(self.tmp, name + ".rtp")
        with open(path, "wb") as f:
            f.write(data)
        return path

    def refuse(self, cases, spawn=1):
        """Every case refused by the library with a PackageError naming what its needles say, and by the
        command line with exit 3 and exactly that message on one line: rtpack.main() in this process for
        every case, and `python3 python/rtpack.py` as a process of its own (concurrently, its peak memory
        measured) for the first `spawn` cases."""
        spawned = []
        for k, (name, data, call, needles) in enumerate(cases):
            with self.subTest(case=name):
                path = self.write(data, name)
                with self.assertRaises(rtpack.PackageError) as cm:
                    with rtpack.Package(path) as p:
                        call(p)
                msg = str(cm.exception)
                print(f"  {name}: {type(cm.exception).__name__}: {msg}", file=sys.stderr)
                for n in needles:
                    self.assertIn(n, msg)
                self.assertLess(peak_rss_kb(), MAX_CLI_RSS_KB, f"{name}: peak RSS of the test")
                want = msg if call in (read_all, open_only) else None  # the command line's path: the same message
                self.cli_refused(name, path, want, *run_main([path]))
                if k < spawn:
                    spawned.append((name, path, want))
        with concurrent.futures.ThreadPoolExecutor(max_workers=4) as ex:
            results = list(ex.map(lambda j: run_cli([j[1]]), spawned))
        for (name, path, want), (code, err, rss) in zip(spawned, results):
            self.cli_refused(name + " (process)", path, want, code, err)
            self.assertLess(rss, MAX_CLI_RSS_KB, f"{name}: peak RSS {rss} KiB")

    def cli_refused(self, name, path, msg, code, err):
        """Exit 3 and one line "rtpack.py: error: PATH: MSG" (MSG when known), no traceback."""
        with self.subTest(case=name, cli=True):
            self.assertNotIn("Traceback", err)
            self.assertEqual(code, 3, err)
            self.assertEqual(err.count("\n"), 1, err)
            self.assertTrue(err.startswith(f"rtpack.py: error: {path}: "), err)
            if msg is not None:
                self.assertEqual(err, f"rtpack.py: error: {path}: {msg}\n")

    def with_metadata(self, text, compress=True):
        raw = metadata_chunk(text)
        stored = zstandard.ZstdCompressor().compress(raw) if compress else raw
        return Patch(self.good).replace_chunk(self.meta, stored, len(raw), int(compress)).seal()

    # ---- the cases ---------------------------------------------------------------------------------------
    def test_intact(self):
        with rtpack.Package(self.src) as p:
            read_all(p)
            self.assertEqual(p.metadata()["format"], "rtpack")
            self.assertEqual(len(p.instance_records()), 1)
        for args in ([self.src], [self.src, "--json"]):
            self.assertEqual(run_main(args), (0, ""))
        code, err, _ = run_cli([self.src, "--json"])
        self.assertEqual((code, err), (0, ""))

    def test_nested_metadata(self):
        label = self.labels[self.meta]
        deep = f"{label}: metadata JSON nested more than 256 levels deep"
        self.refuse([
            ("meta-100000-brackets", self.with_metadata(b"[" * 100000), read_all, [deep, "(at byte 256)"]),
            ("meta-100000-braces", self.with_metadata(b'{"a":' * 100000 + b"1" + b"}" * 100000), read_all,
             [deep, "(at byte 1280)"]),
            ("meta-257", self.with_metadata(b'{"a":' + b"[" * 256 + b"]" * 256 + b"}", compress=False),
             lambda p: p.metadata(), [deep]),
            ("meta-not-object", self.with_metadata(b"[1, 2]"), read_all, [label, "not a JSON object"]),
            ("meta-not-utf8", self.with_metadata(b'{"a": "\xff"}'), read_all, [label, "not UTF-8 JSON"]),
            ("meta-not-json", self.with_metadata(b'{"a": '), read_all, [label, "not UTF-8 JSON"]),
            ("meta-huge-int", self.with_metadata(b'{"a": ' + b"9" * 5000 + b"}"), read_all, [label, "JSON"]),
            ("meta-cameras", self.with_metadata(b'{"cameras": 7}'), read_all, [label, "/cameras: not an array"]),
        ])
        # At the limit, and brackets inside strings (escaped quotes too), are not too deep.
        for text in (b'{"a":' + b"[" * 255 + b"]" * 255 + b"}", b'{"s": "\\"' + b"[" * 300 + b'"}'):
            with rtpack.Package(self.write(self.with_metadata(text), "meta-ok")) as p:
                self.assertIn(next(iter(p.metadata())), ("a", "s"))

    def test_toc_bounds(self):
        p = Patch(self.good)
        toc, n = p.get("toc_offset"), p.count()
        last = n - 1
        oob = f"{self.labels[last].split(' (')[0]} (chunk #{last} at offset"

        def entry(**fields):
            return Patch(self.good).set_entry(last, **fields).seal()
        self.refuse([
            ("entry-size-2^63", entry(stored_size=1 << 63), read_all, [oob, f"out of bounds ({1 << 63} bytes)"]),
            ("entry-size-2^64-1", entry(stored_size=(1 << 64) - 1), read_all, [oob, "out of bounds"]),
            ("entry-past-eof", entry(offset=toc + rtpack.ALIGNMENT), read_all,
             [f"(chunk #{last} at offset {toc + rtpack.ALIGNMENT}): out of bounds"]),
            ("entry-wraps", entry(offset=(1 << 64) - rtpack.ALIGNMENT, stored_size=2 * rtpack.ALIGNMENT), read_all,
             [f"(chunk #{last} at offset {(1 << 64) - rtpack.ALIGNMENT}): out of bounds"]),
            ("entry-unaligned", entry(offset=rtpack.ALIGNMENT + 1), read_all, [f"chunk #{last}", "out of bounds"]),
            ("entry-in-header", entry(offset=0), read_all, [f"chunk #{last} at offset 0): out of bounds"]),
            ("toc-count-2^63", Patch(self.good).set(toc_count=1 << 63).seal(), read_all,
             [f"table of contents out of bounds (offset {toc}, {1 << 63} entries)"]),
            ("toc-entry-size-2^32-1", Patch(self.good).set(toc_entry_size=(1 << 32) - 1).seal(), read_all,
             [f"table of contents out of bounds (offset {toc}, {n} entries)"]),
            ("toc-entry-size-47", Patch(self.good).set(toc_entry_size=47).seal(), read_all,
             ["table of contents out of bounds"]),
            ("toc-offset-past-eof", Patch(self.good).set(toc_offset=toc + rtpack.ALIGNMENT).seal(), read_all,
             ["table of contents out of bounds"]),
        ])
        # No entries (every chunk zeroed) and an entry size of 2^31 bytes or more (once "integer won't fit
        # into a C int"): the package opens with an empty TOC, and is refused for its missing chunks.
        self.refuse([(f"toc-empty-entry-size-{size}",
                      Patch(self.good).drop(lambda i: False).set(toc_entry_size=size).seal(),
                      read_all, ["missing batching-point descriptors chunk (kind 3, id 0)"])
                     for size in (1 << 31, (1 << 32) - 1)])

    def test_zstd_sizes(self):
        i, label = self.top, self.labels[self.top]
        raw, stored_top = Patch(self.good).entry(i, "raw_size"), Patch(self.good).entry(i, "stored_size")

        def frame(declared, rle, toc_raw):
            return Patch(self.good).replace_chunk(i, zstd_frame(declared, rle), toc_raw, 1).seal()
        stored = len(zstd_frame(0, 0))
        self.refuse([
            ("zstd-declares-3GiB", frame(GIB3, 1000, raw), lambda p: p.read(i),
             [f"{label}: zstd frame declares {GIB3} bytes, the table of contents raw_size {raw}"]),
            ("zstd-3GiB-both", frame(GIB3, 1000, GIB3), open_only,
             [f"{label}: raw_size {GIB3} is more than 32768 times the {stored} stored bytes"]),
            ("zstd-decodes-more", frame(200, 1 << 17, 200), read_all, [f"{label}: zstd decompression failed"]),
            ("zstd-decodes-less", frame(1000, 10, 1000), read_all, [f"{label}: zstd decompression failed"]),
            ("zstd-no-frame", Patch(self.good).replace_chunk(i, b"\x01\x02\x03", 3, 1).seal(), read_all,
             [f"{label}: zstd frame declares an invalid header"]),
            ("zstd-empty", Patch(self.good).replace_chunk(i, b"", 0, 1).seal(), read_all,
             [f"{label}: zstd frame declares"]),
            ("zstd-trailing", Patch(self.good).replace_chunk(i, zstd_frame(1000, 1000) + b"xyz", 1000, 1).seal(),
             read_all, [f"{label}: zstd decompression failed (1000 bytes of 1000, 3 bytes after the frame)"]),
            ("stored-raw-size-2^63", Patch(self.good).set_entry(i, compression=0, raw_size=1 << 63).seal(), open_only,
             [f"{label}: raw_size {1 << 63} differs from the {stored_top} stored bytes of an uncompressed chunk"]),
            ("compression-7", Patch(self.good).set_entry(i, compression=7).seal(), read_all,
             [f"{label}: unknown compression 7"]),
        ], spawn=2)

    def test_section_tables(self):
        i, label = self.meta, self.labels[self.meta]

        def chunk(raw):
            return Patch(self.good).replace_chunk(i, raw, len(raw), 0).seal()
        text = b'{"format": "rtpack"}'
        sec = f"{label}: section {rtpack.SEC_JSON} out of bounds"
        lie = [(rtpack.SEC_JSON, 1, 1 << 63, None, 64), (rtpack.SEC_JSON, 1, 4, None, (1 << 64) - 64),
               (rtpack.SEC_JSON, 0, 4, None, 64), (rtpack.SEC_JSON, (1 << 32) - 1, 2, None, 64),
               (rtpack.SEC_JSON, 1, 4, None, 65)]
        cases = [(f"section-lie-{k}", chunk(chunk_bytes(rtpack.KIND_METADATA, [s])), read_all, [sec])
                 for k, s in enumerate(lie)]
        many = bytearray(metadata_chunk(text))
        struct.pack_into("<I", many, 8, (1 << 32) - 1)  # section_count
        wrong_kind = bytearray(metadata_chunk(text))
        struct.pack_into("<I", wrong_kind, 4, rtpack.KIND_BATCHING_POINT)
        self.refuse(cases + [
            ("section-count-2^32-1", chunk(bytes(many)), read_all, [f"{label}: section table out of bounds"]),
            ("chunk-short", chunk(b"RTCH"), read_all, [f"{label}: too short for a chunk header (4 bytes)"]),
            ("chunk-magic", chunk(b"XXXX" + metadata_chunk(text)[4:]), read_all, [f"{label}: bad chunk magic"]),
            ("chunk-kind", chunk(bytes(wrong_kind)), read_all,
             [f"{label}: chunk says kind 16, the table of contents 1"]),
            ("chunk-no-json", chunk(chunk_bytes(rtpack.KIND_METADATA, [])), lambda p: p.metadata(),
             [f"{label}: missing section {rtpack.SEC_JSON}"]),
        ])

    def test_truncated(self):
        toc = Patch(self.good).get("toc_offset")
        self.refuse([(f"truncated-{n}", self.good[:n], read_all, ["truncated file"])
                     for n in (0, 1, 100, 4095, 4096, 8192, toc, len(self.good) - 1)])

    def test_resident_chunks_missing(self):
        kinds = [int(Patch(self.good).entry(i, "kind")) for i in range(Patch(self.good).count())]
        resident = [i for i, k in enumerate(kinds) if k in rtpack.RESIDENT_KINDS]

        def missing(kind):
            return [f"missing {rtpack.kind_name(kind)} chunk (kind {kind}, id 0)"]
        first = missing(rtpack.KIND_BATCHING_POINTS)
        cases = [
            ("no-resident-chunks", Patch(self.good).drop(lambda i: i not in resident).seal(), read_all, first),
            ("resident-renamed", self.renamed(resident), read_all, first),
            ("no-chunks", Patch(self.good).drop(lambda i: False).seal(), read_all, first),
        ]
        # Each chunk the summary needs, alone missing (renamed to a kind readers skip, SPEC §3).
        for kind in (rtpack.KIND_METADATA, rtpack.KIND_TOP_LEVEL_BVH, rtpack.KIND_BATCHING_POINTS,
                     rtpack.KIND_INSTANCES, rtpack.KIND_MESHES):
            cases.append((f"no-kind-{kind}", self.renamed([kinds.index(kind)]), read_all, missing(kind)))
        cases += [
            ("no-metadata-call", self.renamed([kinds.index(rtpack.KIND_METADATA)]), lambda p: p.metadata(),
             missing(rtpack.KIND_METADATA)),
            ("no-instances-call", self.renamed([kinds.index(rtpack.KIND_INSTANCES)]), lambda p: p.instance_records(),
             missing(rtpack.KIND_INSTANCES)),
        ]
        self.refuse(cases)

    def renamed(self, indices):
        p = Patch(self.good)
        for i in indices:
            p.set_entry(i, kind=100 + p.entry(i, "kind"))
        return p.seal()

    def test_unsealed_bit_flips(self):
        p = Patch(self.good)
        toc, n = p.get("toc_offset"), p.count()
        cases = [(f"flip-header-{at}", Patch(self.good).flip(at, 3).buf, read_all, ["header checksum mismatch"])
                 for at in (16, 24, 32, 40, 48, 52, 60, 100, 123, 124, 127)]
        cases += [(f"flip-toc-{k}", Patch(self.good).flip(toc + k).buf, read_all,
                   ["table of contents checksum mismatch"])
                  for k in (0, 17, 24, 40, n * 48 - 1)]
        for i in range(n):  # each chunk, in the middle of its stored bytes
            at = p.entry(i, "offset") + p.entry(i, "stored_size") // 2
            cases.append((f"flip-chunk-{i}", Patch(self.good).flip(at, 5).buf, read_all,
                          [f"{self.labels[i]}: checksum mismatch"]))
            cases.append((f"flip-chunk-{i}-call", Patch(self.good).flip(at, 5).buf, lambda pk, i=i: pk.chunk(i),
                          [f"{self.labels[i]}: checksum mismatch"]))
        # Bytes no checksum covers: the header block's and the chunks' zero padding.
        cases.append(("flip-padding", Patch(self.good).flip(rtpack.ALIGNMENT - 1).buf, read_all,
                      ["header block padding (bytes 128..4095): byte 4095 of the file is not 0"]))
        self.refuse([(name, bytes(data), call, needles) for name, data, call, needles in cases])

    def test_versions(self):
        self.refuse([(f"version-{major}", Patch(self.good).set(version_major=major).seal(), read_all,
                      ["version", f"package version {major}.0 is not supported"])
                     for major in (0, 1, rtpack.VERSION_MAJOR - 1, rtpack.VERSION_MAJOR + 1, (1 << 32) - 1)])

    def test_widths(self):
        self.refuse([(f"widths-{w}-{b}", Patch(self.good).set(bvh_width=w, leaf_width=b).seal(), read_all,
                      [f"header: unsupported BVH width {w} / leaf width {b}"])
                     for w, b in ((0, 8), (8, 0), (2, 8), (8, 32), ((1 << 32) - 1, 8), (8, 1 << 31))])

    def test_dag_node(self):
        words = np.array([0x000000FF, 1, 2], np.uint32)  # 8 referenced children, 2 words of them
        for off, needle in ((0, "runs past the pool's 3 words"), (3, "outside"), (-1, "outside")):
            with self.assertRaises(rtpack.PackageError) as cm:
                rtpack.dag_node(words, off)
            self.assertIn(f"DAG node at word {off}: {needle}", str(cm.exception))
        self.assertEqual(rtpack.dag_node(np.array([0x0101], np.uint32), 0), [(0, "full", None)])

    def test_cli_usage_and_unreadable(self):
        for args in ([], ["--bogus", self.src], [self.src, "extra"]):
            for code, err in [run_main(args)] + ([run_cli(args)[:2]] if not args else []):
                self.assertEqual(code, 2, (args, err))
                self.assertIn("usage:", err)
                self.assertNotIn("Traceback", err)
        for path in (os.path.join(self.tmp, "does-not-exist.rtp"), self.tmp):
            with self.assertRaises(OSError):  # not a package's bytes: the library's OSError, not PackageError
                rtpack.Package(path)
            self.cli_refused(path, path, None, *run_main([path]))
        self.cli_refused("directory (process)", self.tmp, None, *run_cli([self.tmp])[:2])


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--build" in args:
        i = args.index("--build")
        BUILD = os.path.abspath(args[i + 1])
        del args[i:i + 2]
    unittest.main(argv=[sys.argv[0]] + args)
