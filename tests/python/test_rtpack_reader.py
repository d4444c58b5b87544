#!/usr/bin/env python3
"""python/rtpack.py against rtpack-inspect, on every sample package.

Converts each glTF/glb under samples/ (plus variants: --attributes normal,uv, --no-dag, --bvh-width 4
and 16, --leaf-width 4, --zstd-level 0 (stored chunks), a small --chunk-target, --bvh-build split) with
rtpack-convert into a temporary directory, runs `rtpack-inspect --json --chunks --verify` on each, and
compares its report field by field with what the Python reader derives from the arrays it reads: header,
sizes per chunk kind, batching points, mesh segments, top level, culling DAGs (walked from SPEC §4.5),
per-chunk rows and BVH statistics, metadata. Then corrupts copies (a flipped byte in a chunk, the TOC and
the header; another major version; bad magic; truncation; a patched element size or raw_size with every
CRC fixed up) and checks that the reader refuses each with the C++ reader's message.

Run:   python3 tests/python/test_rtpack_reader.py --build build [-v] [unittest args]
       (or RTPACK_BUILD=build python3 tests/python/test_rtpack_reader.py); CTest: `ctest -R python_reader`.
       RTPACK_ONLY=REGEX limits the comparisons to the packages whose name matches (for debugging).
Needs: a built build/rtpack-convert and build/rtpack-inspect; python3-numpy, python3-zstandard
(python3-crcmod for fast checksums).
"""
import base64
import concurrent.futures
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

from reader_env import ROOT, rtpack  # re-runs under Debian's /usr/bin/python3 when needed

import numpy as np  # noqa: E402

BUILD = os.environ.get("RTPACK_BUILD", os.path.join(ROOT, "build"))
ONLY = os.environ.get("RTPACK_ONLY", "")  # a regex: compare only the packages whose name matches (debugging)
S = os.path.join(ROOT, "samples")
# (name, input relative to samples/, extra rtpack-convert options)
VARIANTS = [
    ("gallery-attrs", "generated/gallery.glb", ["--attributes", "normal,uv"]),
    ("lantern-attrs", "khronos/Lantern/glTF/Lantern.gltf", ["--attributes", "normal,uv"]),
    ("boombox-attrs-w4", "khronos/BoomBox/glTF/BoomBox.gltf", ["--attributes", "normal,uv", "--bvh-width", "4"]),
    ("gallery-nodag", "generated/gallery.glb", ["--no-dag"]),
    ("gallery-w4", "generated/gallery.glb", ["--bvh-width", "4"]),
    ("gallery-w16b16", "generated/gallery.glb", ["--bvh-width", "16", "--leaf-width", "16"]),
    # Written by write_octahedra(): an instanced mesh with normals and uvs (segment attributes, kind 18).
    ("octahedra-attrs", "@octahedra.gltf", ["--attributes", "normal,uv"]),
    ("suzanne-w16", "khronos/Suzanne/glTF/Suzanne.gltf", ["--bvh-width", "16"]),
    ("suzanne-w8b4", "khronos/Suzanne/glTF/Suzanne.gltf", ["--leaf-width", "4"]),
    ("gallery-stored", "generated/gallery.glb", ["--zstd-level", "0"]),
    ("helmet-small-points", "khronos/FlightHelmet/glTF/FlightHelmet.gltf",
     ["--chunk-target", "3000", "--attributes", "normal,uv", "--bvh-build", "split"]),
    ("forest-small-points", "generated/forest-small.glb", ["--chunk-target", "200000", "--no-dag"]),
    # Points of 64 instances or more cull by their instance boxes (7.0), the others by voxels.
    ("forest-small-boxes", "generated/forest-small.glb", ["--chunk-target", "300000"]),
    ("forest-small-boxes-w4", "generated/forest-small.glb", ["--chunk-target", "300000", "--bvh-width", "4"]),
]
TOOL_TIMEOUT = 120


def samples():
    out = []
    for d, _, files in sorted(os.walk(S)):
        for f in sorted(files):
            if f.endswith((".gltf", ".glb")):
                rel = os.path.relpath(os.path.join(d, f), S)
                out.append((rel.replace("/", "_").rsplit(".", 1)[0], rel, []))
    return out


def write_octahedra(path):
    """A glTF with one octahedron mesh (NORMAL, TEXCOORD_0) used by three nodes and a second one used once."""
    pos = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float32)
    uv = (pos[:, :2] * 0.5 + 0.5).astype(np.float32)
    idx = np.array([0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5], np.uint16)
    blob = pos.tobytes() + pos.tobytes() + uv.tobytes() + idx.tobytes()
    views = [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in ((0, 72), (72, 72), (144, 48), (192, 48))]
    acc = [{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [-1] * 3, "max": [1] * 3},
           {"bufferView": 1, "componentType": 5126, "count": 6, "type": "VEC3"},
           {"bufferView": 2, "componentType": 5126, "count": 6, "type": "VEC2"},
           {"bufferView": 3, "componentType": 5123, "count": 24, "type": "SCALAR"}]
    prim = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2, 3]}],
           "nodes": [{"mesh": 0, "translation": [3.0 * k, 0, 0]} for k in range(3)] +
                    [{"mesh": 1, "translation": [0, 3, 0], "scale": [2, 1, 1]}],
           "meshes": [{"name": "shared", "primitives": [prim]}, {"name": "once", "primitives": [prim]}],
           "accessors": acc, "bufferViews": views,
           "buffers": [{"byteLength": len(blob),
                        "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}]}
    with open(path, "w") as f:
        json.dump(doc, f)


def run(cmd, check=True):
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=TOOL_TIMEOUT)
    if check and p.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)}: exit {p.returncode}\n{p.stderr}")
    return p


def inspect(path, check=True):
    p = run([os.path.join(BUILD, "rtpack-inspect"), "--json", "--chunks", "--verify", path], check=check)
    return p, (json.loads(p.stdout) if p.stdout.strip() else None)


from inspect_model import spread, histogram, half_area, bvh_shape, mesh_shape, instance_shape, group, dag_stats  # noqa: E402


class Derived:
    """Everything the comparisons need, read once per package through rtpack.Package."""

    def __init__(self, path):
        with rtpack.Package(path) as p:
            self.pkg, self.h, self.toc = p, p.header, p.toc
            self.chunks = list(p.chunks())  # every CRC, frame and section table checked here
            p.check_padding()
            p.check_toc()
            self.meta = p.metadata()
        self.res = {c.kind: c for c in self.chunks if c.kind in rtpack.RESIDENT_KINDS}
        self.descs = self.res[rtpack.KIND_BATCHING_POINTS].get(rtpack.SEC_POINT_DESCS)
        self.meshes = self.res[rtpack.KIND_MESHES].get(rtpack.SEC_MESH_TABLE)
        self.instances = self.res[rtpack.KIND_INSTANCES].get(rtpack.SEC_INSTANCE_REFS)
        self.top = self.res[rtpack.KIND_TOP_LEVEL_BVH].get(rtpack.SEC_TOP_NODES)


class ReaderVsInspect(unittest.TestCase):
    tmp = None
    packages = {}  # name -> (path, Derived, inspect JSON)

    @classmethod
    def setUpClass(cls):
        for tool in ("rtpack-convert", "rtpack-inspect"):
            if not os.access(os.path.join(BUILD, tool), os.X_OK):
                raise AssertionError(f"{BUILD}/{tool} not found: build the repo first (cmake --build {BUILD})")
        cls.tmp = tempfile.mkdtemp(prefix="rtpack-py-")
        write_octahedra(os.path.join(cls.tmp, "octahedra.gltf"))

        def make(job):
            name, rel, opts = job
            out = os.path.join(cls.tmp, name + ".rtp")
            src = os.path.join(cls.tmp, rel[1:]) if rel.startswith("@") else os.path.join(S, rel)
            run([os.path.join(BUILD, "rtpack-convert"), src, "-o", out, "-q", "--threads", "1"] + opts)
            proc, report = inspect(out)
            return name, (out, Derived(out), report)

        jobs = [j for j in samples() + VARIANTS if re.search(ONLY, j[0])]
        with concurrent.futures.ThreadPoolExecutor(max_workers=2) as ex:
            cls.packages = dict(ex.map(make, jobs))
        print(f"\n{len(cls.packages)} packages compared with rtpack-inspect --json --chunks --verify:", file=sys.stderr)
        for name, (path, d, j) in sorted(cls.packages.items()):
            kinds = sorted(set(int(k) for k in d.toc["kind"]))
            print(f"  {name:<42} W{d.pkg.bvh_width} B{d.pkg.leaf_width} {len(d.toc):3} chunks "
                  f"({sum(int(c) == 0 for c in d.toc['compression'])} stored), {len(d.descs)} points, "
                  f"{len(d.top)} top nodes, kinds {kinds}", file=sys.stderr)

    @classmethod
    def tearDownClass(cls):
        if cls.tmp:
            shutil.rmtree(cls.tmp, ignore_errors=True)

    def close(self, a, b, what):
        if a is None or b is None:
            self.assertEqual(a, b, what)
        else:
            self.assertTrue(math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), f"{what}: {a} != {b}")

    def same_spread(self, got, want, what):
        for k in ("min", "mean", "max"):
            self.close(got[k], want[k], f"{what}.{k}")

    def same_group(self, got, want, what):
        for k in ("bvhs", "root_leaves", "primitives", "nodes", "blocks"):
            self.assertEqual(got[k], want[k], f"{what}.{k}")
        for k in ("c_box", "c_tri", "sah", "branching", "leaf_fill", "max_depth"):
            self.same_spread(got[k], want[k], f"{what}.{k}")

    def for_each(self, check):
        """Runs check(path, Derived, inspect JSON) on every package, each as its own subtest."""
        if not ONLY:
            self.assertGreaterEqual(len(self.packages), 20)
        for name, (path, d, j) in sorted(self.packages.items()):
            with self.subTest(package=name):
                check(path, d, j)

    def test_verified_clean(self):
        self.for_each(self._verified_clean)

    def _verified_clean(self, path, d, j):
        self.assertTrue(j["verified"])
        self.assertEqual(j["problems"]["count"], 0, j["problems"]["listed"])

    def test_header(self):
        self.for_each(self._header)

    def _header(self, path, d, j):
        h, jh = d.h, j["header"]
        self.assertEqual(j["package_bytes"], int(h["file_size"]))
        self.assertEqual(j["package_bytes"], os.path.getsize(path))
        self.assertEqual(jh["version"], f"{int(h['version_major'])}.{int(h['version_minor'])}")
        self.assertEqual(jh["attributes"], [n for bit, n in ((1, "normal"), (2, "uv")) if int(h["flags"]) & bit])
        for k in ("bvh_width", "leaf_width", "unique_triangles", "instanced_triangles"):
            self.assertEqual(jh[k], int(h[k]), k)
        self.assertEqual(jh["toc_entries"], len(d.toc))
        self.assertEqual(jh["bounds"]["min"], [float(x) for x in h["bounds_lo"]])
        self.assertEqual(jh["bounds"]["max"], [float(x) for x in h["bounds_hi"]])
        self.assertEqual(j["instances"], len(d.instances))
        self.assertEqual(j["meshes"], len(d.meshes))
        # Reader-side identities of SPEC §1.1 / §4.1.
        self.assertEqual(int(h["unique_triangles"]), int(d.meshes["triangles"].sum()))
        self.assertEqual(int(h["instanced_triangles"]), int(d.meshes["triangles"][d.instances["mesh"]].sum()))
        self.assertEqual(bool(int(h["flags"]) & rtpack.FLAG_DAG), rtpack.KIND_DAG_POOL in d.res)

    def test_sizes(self):
        self.for_each(self._sizes)

    def _sizes(self, path, d, j):
        tris = max(1, int(d.h["unique_triangles"]))
        kinds = sorted(set(int(k) for k in d.toc["kind"]))
        self.assertEqual([k["kind"] for k in j["sizes"]["by_kind"]], kinds)
        for row in j["sizes"]["by_kind"]:
            sel = d.toc[d.toc["kind"] == row["kind"]]
            raw, stored = int(sel["raw_size"].sum()), int(sel["stored_size"].sum())
            self.assertEqual(row["name"], rtpack.kind_name(row["kind"]))
            self.assertEqual(row["residency"], "resident" if row["kind"] <= 7 else "on demand")
            self.assertEqual((row["chunks"], row["raw_bytes"], row["stored_bytes"]), (len(sel), raw, stored))
            self.close(row["ratio"], raw / stored if stored else 1.0, "ratio")
            self.close(row["stored_bytes_per_unique_triangle"], stored / tris, "stored B/tri")
        for key, sel in (("resident", d.toc["kind"] <= 7), ("on_demand", d.toc["kind"] >= 16)):
            r = j["sizes"][key]
            self.assertEqual((r["chunks"], r["raw_bytes"], r["stored_bytes"]),
                             (int(sel.sum()), int(d.toc["raw_size"][sel].sum()), int(d.toc["stored_size"][sel].sum())))
        toc_bytes = int(d.h["toc_count"]) * int(d.h["toc_entry_size"])
        self.assertEqual(j["sizes"]["header_block_bytes"], rtpack.ALIGNMENT)
        self.assertEqual(j["sizes"]["toc_bytes"], toc_bytes)
        self.assertEqual(j["sizes"]["alignment_padding_bytes"],
                         int(d.h["file_size"]) - 4096 - toc_bytes - int(d.toc["stored_size"].sum()))
        self.close(j["bytes_per_unique_triangle"], int(d.h["file_size"]) / tris, "bytes per triangle")

    def test_batching_points_and_segments(self):
        self.for_each(self._batching_points_and_segments)

    def _batching_points_and_segments(self, path, d, j):
        p, ds = j["batching_points"], d.descs
        points = [c for c in d.chunks if c.kind == rtpack.KIND_BATCHING_POINT]
        self.assertEqual((p["count"], p["chunks_read"]), (len(ds), len(points)))
        self.assertEqual(len(points), len(ds))
        for k in ("unique_triangles", "instanced_triangles"):
            self.assertEqual(p[k], int(ds[k].sum()), k)
        self.assertEqual(p["instances"], int(ds["instance_count"].sum()))
        self.assertEqual(p["pieces"], int(ds["piece_count"].sum()))
        tris = ds["unique_triangles"] + ds["instanced_triangles"]
        stored = [int(d.toc[d.pkg.find(rtpack.KIND_BATCHING_POINT, int(c))]["stored_size"]) for c in ds["chunk_id"]]
        self.same_spread(p["triangles"], spread(tris), "triangles")
        self.same_spread(p["stored_bytes"], spread(stored), "stored_bytes")
        self.same_spread(p["instances_per_point"], spread(ds["instance_count"]), "instances_per_point")
        self.same_spread(p["pieces_per_point"], spread(ds["piece_count"]), "pieces_per_point")
        self.assertEqual(p["triangles_histogram"], histogram(tris))
        self.assertEqual(p["stored_bytes_histogram"], histogram(stored))
        self.assertEqual(p["instances_histogram"], histogram(ds["instance_count"]))
        # Each point chunk against its descriptor (SPEC §4.1, §4.2).
        for c in points:
            dsc = ds[c.id]
            self.assertEqual(int(dsc["chunk_id"]), c.id)
            recs, slots = c.get(rtpack.SEC_INSTANCES), c.get(rtpack.SEC_MESH_SLOTS)
            is_piece = (slots[recs["mesh"]] & rtpack.PIECE_BIT) != 0
            self.assertEqual(int(is_piece.sum()), int(dsc["piece_count"]))
            self.assertEqual(int((~is_piece).sum()), int(dsc["instance_count"]))
            self.assertEqual(int(c.get(rtpack.SEC_MESH_ENTRIES)["triangles"].sum()), int(dsc["unique_triangles"]))
            self.assertEqual(len(c.get(rtpack.SEC_GLOBAL_IDS)), len(recs))
        # The instance table names each instance's record (SPEC §2.5): that point's global id there is the
        # instance, its source fields are the record's; every instance some point holds is placed.
        gids = {c.id: c.get(rtpack.SEC_GLOBAL_IDS) for c in points}
        recs = {c.id: c.get(rtpack.SEC_INSTANCES) for c in points}
        held = set()
        for g in gids.values():
            held.update(int(x) for x in g)
        placed = d.instances["point"] != rtpack.NO_POINT
        self.assertEqual(int(placed.sum()), len(held))
        for g in np.nonzero(placed)[0][:2000]:
            ref = d.instances[g]
            p_, k = int(ref["point"]), int(ref["local"])
            self.assertEqual(int(gids[p_][k]), int(g))
            # the record's mirrored flag is the sign of its stored L^-1's determinant (SPEC §2.4)
            det = np.linalg.det(recs[p_][k]["inverse_linear"].astype(np.float64))
            self.assertEqual(int(recs[p_][k]["flags"]) & 1, 1 if det < 0 else 0)
        s = j["mesh_segments"]
        segs = [c for c in d.chunks if c.kind == rtpack.KIND_MESH_SEGMENT]
        sel = d.toc[d.toc["kind"] == rtpack.KIND_MESH_SEGMENT]
        self.assertEqual((s["count"], s["chunks_read"]), (len(sel), len(segs)))
        self.assertEqual(s["triangles"], int(d.meshes["triangles"][d.meshes["segment"] != rtpack.NO_SEGMENT].sum()))
        self.same_spread(s["meshes_per_segment"], spread(len(c.get(rtpack.SEC_MESH_ENTRIES)) for c in segs), "meshes")
        self.same_spread(s["triangles_per_segment"],
                         spread(int(c.get(rtpack.SEC_MESH_ENTRIES)["triangles"].sum()) for c in segs), "tris")
        self.same_spread(s["stored_bytes"], spread(sel["stored_size"]), "segment stored")
        self.same_spread(s["raw_bytes"], spread(sel["raw_size"]), "segment raw")
        self.assertEqual(j["top_level"], {"nodes": len(d.top),
                                          "max_depth": int(d.top["depth"].max()) + 1 if len(d.top) else 0})

    def test_instance_records(self):
        # Package.instance_records() against the glTF write_octahedra() wrote (four nodes: three translated
        # copies of mesh 0, then mesh 1 scaled by (2, 1, 1)), then on every package against its points.
        if "octahedra-attrs" in self.packages or not ONLY:
            with rtpack.Package(self.packages["octahedra-attrs"][0]) as p:
                r = p.instance_records()
                np.testing.assert_array_equal(r["translation"], [[0, 0, 0], [3, 0, 0], [6, 0, 0], [0, 3, 0]])
                want = np.repeat(np.eye(3, dtype=np.float32)[None], 4, axis=0)
                want[3, 0, 0] = 0.5
                np.testing.assert_array_equal(r["inverse_linear"], want)
                self.assertEqual((r["mesh"].tolist(), (r["flags"] & 1).tolist()), ([0, 0, 0, 1], [0, 0, 0, 0]))
                refs = p.resident(rtpack.KIND_INSTANCES)
                refs.sections[rtpack.SEC_INSTANCE_REFS] = refs.get(rtpack.SEC_INSTANCE_REFS).copy()
                refs.sections[rtpack.SEC_INSTANCE_REFS]["local"][1] += 1  # a place that holds another instance
                p.resident = lambda kind: refs if kind == rtpack.KIND_INSTANCES else rtpack.Package.resident(p, kind)
                self.assertRaisesRegex(rtpack.MalformedError, "instance 1 is placed at", p.instance_records)
        self.for_each(self._instance_records)

    def _instance_records(self, path, d, j):
        with rtpack.Package(path) as p:
            r = p.instance_records()
        self.assertEqual(r["mesh"].tolist(), d.instances["mesh"].tolist())
        placed = d.instances["point"] != rtpack.NO_POINT
        self.assertTrue(np.all(r["translation"][~placed] == 0))
        recs = {c.id: c.get(rtpack.SEC_INSTANCES) for c in d.chunks if c.kind == rtpack.KIND_BATCHING_POINT}
        for g in np.nonzero(placed)[0][:500]:  # each placed row is its point's record there, mesh aside
            want = recs[int(d.instances[g]["point"])][int(d.instances[g]["local"])]
            for k in ("translation", "inverse_linear", "flags"):
                self.assertEqual(r[g][k].tobytes(), want[k].tobytes(), k)

    def test_dag(self):
        self.for_each(self._dag)

    def _dag(self, path, d, j):
        g, pool = j["dag"], d.res.get(rtpack.KIND_DAG_POOL)
        grids = d.res[rtpack.KIND_BATCHING_POINTS].get(rtpack.SEC_POINT_GRIDS, required=False)
        self.assertEqual(g["present"], pool is not None)
        self.assertEqual(grids is not None, pool is not None)
        self.assertEqual(d.meta.get("dag"), pool is not None)
        if pool is None:
            self.assertEqual((g["pool_bytes"], g["node_words"], g["leaves"]), (0, 0, 0))
            return
        words, leaves = pool.get(rtpack.SEC_DAG_NODES), pool.get(rtpack.SEC_DAG_LEAVES)
        self.assertEqual(len(grids), len(d.descs))
        self.assertEqual(g["pool_bytes"], words.nbytes + leaves.nbytes)
        self.assertEqual((g["node_words"], g["leaves"], g["grids"]), (len(words), len(leaves), len(grids)))
        self.assertEqual(g["grid_bytes"], grids.nbytes)
        st = dag_stats(grids, words, leaves)
        for k in ("resolutions", "empty_roots", "full_roots", "nodes", "set_cells", "cells", "separate_bytes"):
            self.assertEqual(g[k], st[k], k)
        # Instance boxes (7.0): each box point's nodes are its instance BVH's, boxes rounded outward.
        cull, boxes = pool.get(rtpack.SEC_CULL_NODES, required=False), grids["resolution"] == rtpack.DAG_BOXES
        self.assertEqual(g["box_points"], int(boxes.sum()))
        self.assertEqual(g["box_node_bytes"], 0 if cull is None else cull.nbytes)
        for p in np.flatnonzero(boxes):
            nodes = d.chunks[d.pkg.find(rtpack.KIND_BATCHING_POINT, int(p))].get(rtpack.SEC_INSTANCE_NODES)
            q = cull[int(grids["root"][p]):int(grids["root"][p]) + len(nodes)]
            self.assertEqual(len(q), len(nodes))
            np.testing.assert_array_equal(q["child"], nodes["child"])
            filled = (nodes["child"] != rtpack.CHILD_EMPTY)[:, None, :]
            org, scale = q["origin"].astype("f8")[:, :, None], q["scale"].astype("f8")[:, :, None]
            self.assertTrue(np.all(~filled | (org + q["lo"] * scale <= nodes["lo"])), f"point {p}: a box minimum rounded up")
            self.assertTrue(np.all(~filled | (org + q["hi"] * scale >= nodes["hi"])), f"point {p}: a box maximum rounded down")
        self.assertEqual(g["unreachable_bytes"], g["pool_bytes"] - min(g["pool_bytes"], st["reached_bytes"]))
        self.close(g["sharing"], st["separate_bytes"] / g["pool_bytes"] if g["pool_bytes"] else 1.0, "sharing")
        self.close(g["bytes_per_point"], g["pool_bytes"] / len(grids), "bytes_per_point")
        self.assertEqual((g["malformed_grids"], g["unchecked_grids"]), (0, 0))

    def test_metadata(self):
        self.for_each(self._metadata)

    def _metadata(self, path, d, j):
        m, jm = d.meta, j["metadata"]
        for k in ("format", "tool_version", "source", "options", "bvh_build", "chunk_target", "chunk_by",
                  "batching_points", "mesh_segments", "pieces", "dag"):
            self.assertEqual(jm.get(k), m.get(k), k)
        self.assertEqual(m["format"], "rtpack")
        self.assertEqual((m["bvh_width"], m["leaf_width"]), (d.pkg.bvh_width, d.pkg.leaf_width))
        self.assertEqual(m["batching_points"], len(d.descs))
        self.assertEqual(m["mesh_segments"], int((d.toc["kind"] == rtpack.KIND_MESH_SEGMENT).sum()))
        self.assertEqual(m["pieces"], int(d.descs["piece_count"].sum()))
        self.assertEqual(jm["meshes"], len(m["mesh_names"]))
        self.assertEqual(len(m["mesh_names"]), len(d.meshes))
        self.assertEqual([c["name"] for c in jm["cameras"]], [c["name"] for c in m["cameras"]])
        for jc, c in zip(jm["cameras"], m["cameras"]):
            self.assertEqual(jc["position"], [c["world"][3], c["world"][7], c["world"][11]])
            self.assertEqual(jc["type"], c["type"])

    def test_chunks_and_bvh_statistics(self):
        self.for_each(self._chunks_and_bvh_statistics)

    def _chunks_and_bvh_statistics(self, path, d, j):
        w, b = d.pkg.bvh_width, d.pkg.leaf_width
        rows = j["chunks"]
        self.assertEqual(len(rows), len(d.toc))
        seg_shapes, piece_shapes, inst_shapes = [], [], []
        for row, c in zip(rows, d.chunks):
            e = c.entry
            self.assertEqual((row["index"], row["kind"], row["id"], row["offset"]),
                             (c.index, rtpack.kind_name(c.kind), c.id, int(e["offset"])))
            self.assertEqual(row["compression"], {0: "none", 1: "zstd"}[int(e["compression"])])
            self.assertEqual((row["raw_bytes"], row["stored_bytes"]), (len(c.raw), int(e["stored_size"])))
            self.close(row["ratio"], len(c.raw) / int(e["stored_size"]), "ratio")
            if c.kind in (rtpack.KIND_MESH_SEGMENT, rtpack.KIND_BATCHING_POINT):
                nodes, blocks, entries = c.get(rtpack.SEC_NODES), c.get(rtpack.SEC_BLOCKS), c.get(rtpack.SEC_MESH_ENTRIES)
                self.assertEqual(nodes["lo"].shape[1:], (3, w))
                self.assertEqual(blocks["prim"].shape[1:], (b,))
                shapes = [mesh_shape(nodes, blocks, e_, b) for e_ in entries]
                self.assertEqual([s["primitives"] for s in shapes], [int(t) for t in entries["triangles"]])
                self.same_group(row["bvh"], group(shapes), f"{c.label} bvh")
            if c.kind == rtpack.KIND_MESH_SEGMENT:
                self.assertEqual(row["meshes"], len(entries))
                self.assertEqual(row["triangles"], int(entries["triangles"].sum()))
                self.assertTrue(np.all(d.meshes["segment"][entries["id"]] == c.id))
                seg_shapes += shapes
            elif c.kind == rtpack.KIND_BATCHING_POINT:
                recs, slots = c.get(rtpack.SEC_INSTANCES), c.get(rtpack.SEC_MESH_SLOTS)
                inst = slots[recs["mesh"]][(slots[recs["mesh"]] & rtpack.PIECE_BIT) == 0]
                self.assertEqual(row["pieces"], len(entries))
                self.assertEqual(row["instances"], len(inst))
                self.assertEqual(row["unique_triangles"], int(entries["triangles"].sum()))
                self.assertEqual(row["instanced_triangles"], int(d.meshes["triangles"][inst].sum()))
                te = c.get(rtpack.SEC_INSTANCE_BVH)
                self.assertEqual(len(te), 1)
                ids = c.get(rtpack.SEC_INSTANCE_IDS)
                self.assertEqual((int(te[0]["node_count"]), int(te[0]["block_count"])),
                                 (len(c.get(rtpack.SEC_INSTANCE_NODES)), len(ids)))
                self.assertEqual(sorted(ids.tolist()), list(range(len(recs))))
                ish = instance_shape(c.get(rtpack.SEC_INSTANCE_NODES), te[0])
                for k in ("nodes", "max_depth"):
                    self.assertEqual(row["instance_bvh"][k], ish[k], k)
                for k in ("c_box", "c_tri", "branching"):
                    self.close(row["instance_bvh"][k], ish[k], k)
                piece_shapes += shapes
                inst_shapes.append(ish)
        self.same_group(j["bvh"]["segment meshes"], group(seg_shapes), "segment meshes")
        self.same_group(j["bvh"]["batching-point pieces"], group(piece_shapes), "pieces")
        self.same_group(j["bvh"]["instance BVHs"], group(inst_shapes), "instance BVHs")

    def test_attributes(self):
        """SPEC §4.4 from the reader alone (inspect reports no attribute statistics beyond the flags)."""
        kinds_seen = set()
        self.for_each(lambda path, d, j: self._attributes(d, kinds_seen))
        if not ONLY:
            self.assertEqual(kinds_seen, {rtpack.KIND_SEGMENT_ATTRIBUTES, rtpack.KIND_POINT_ATTRIBUTES})

    def _attributes(self, d, kinds_seen):
        by_key = {(c.kind, c.id): c for c in d.chunks}
        flags = 0
        for c in d.chunks:
            if c.kind not in (rtpack.KIND_SEGMENT_ATTRIBUTES, rtpack.KIND_POINT_ATTRIBUTES):
                continue
            kinds_seen.add(c.kind)
            geo = by_key[(rtpack.KIND_MESH_SEGMENT if c.kind == rtpack.KIND_SEGMENT_ATTRIBUTES
                          else rtpack.KIND_BATCHING_POINT, c.id)]
            ae, me = c.get(rtpack.SEC_ATTR_ENTRIES), geo.get(rtpack.SEC_MESH_ENTRIES)
            self.assertEqual(ae["id"].tolist(), me["id"].tolist())
            stored = ae["triangle_count"] > 0
            self.assertTrue(np.all(ae["triangle_count"][stored] == me["triangles"][stored]))
            tris = c.get(rtpack.SEC_ATTR_TRIANGLES)
            self.assertTrue(np.all(ae["triangle_first"] + ae["triangle_count"] <= len(tris)))
            for sec, field, bit in ((rtpack.SEC_ATTR_NORMALS, "normal_first", 1), (rtpack.SEC_ATTR_UVS, "uv_first", 2)):
                has = ae[field] != rtpack.NO_ATTRIBUTE
                if has.any():
                    flags |= bit
                    n = len(c.get(sec))
                    self.assertTrue(np.all(ae[field][has].astype(np.int64) + ae["vertex_count"][has] <= n))
            for e in ae[stored]:
                t = tris[int(e["triangle_first"]):int(e["triangle_first"] + e["triangle_count"])]
                self.assertTrue(np.all(t < e["vertex_count"]))
                if c.kind == rtpack.KIND_POINT_ATTRIBUTES:
                    ids = c.get(rtpack.SEC_ATTR_TRI_IDS)[int(e["tri_id_first"]):][:int(e["triangle_count"])]
                    self.assertTrue(np.all(np.diff(ids.astype(np.int64)) > 0))
        self.assertEqual(flags, int(d.h["flags"]) & 3)


def patch_header(buf):
    """Recomputes the TOC CRC and the header CRC of a whole package in `buf` (bytearray)."""
    h = np.frombuffer(bytes(buf[:128]), rtpack.HEADER, 1)[0]
    toc = bytes(buf[int(h["toc_offset"]):int(h["toc_offset"]) + int(h["toc_count"]) * int(h["toc_entry_size"])])
    struct.pack_into("<I", buf, 52, rtpack.crc32c(toc))
    struct.pack_into("<I", buf, 124, rtpack.crc32c(bytes(buf[:124])))


class Refusals(unittest.TestCase):
    """Corrupted copies: the reader refuses each, with the same message as the C++ reader."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="rtpack-py-bad-")
        cls.src = os.path.join(cls.tmp, "good.rtp")
        run([os.path.join(BUILD, "rtpack-convert"), os.path.join(S, "khronos/Lantern/glTF/Lantern.gltf"), "-o", cls.src,
             "-q", "--zstd-level", "0", "--chunk-target", "4000"])
        with open(cls.src, "rb") as f:
            cls.good = f.read()
        with rtpack.Package(cls.src) as p:
            cls.toc, cls.header = p.toc.copy(), p.header.copy()
            cls.point = p.find(rtpack.KIND_BATCHING_POINT, 1)
            cls.label = p.label(cls.point)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def write(self, data, name):
        path = os.path.join(self.tmp, name + ".rtp")
        with open(path, "wb") as f:
            f.write(data)
        return path

    def refused(self, data, name, error, whole=False):
        """Opens (and with `whole` reads every chunk of) the patched package; returns the message."""
        path = self.write(data, name)
        with self.assertRaises(error) as cm:
            with rtpack.Package(path) as p:
                if whole:
                    p.verify()
        msg = str(cm.exception)
        print(f"  {name}: {type(cm.exception).__name__}: {msg}", file=sys.stderr)
        proc, report = inspect(path, check=False)
        self.assertEqual(proc.returncode, 3, proc.stderr)
        # --verify lists problems; a package refused before that is {"error": {...}} (docs/json.md).
        if report and "error" in report:
            self.assertEqual(report["error"]["code"], 3)
            self.assertEqual(report["schema_version"], 3)
        listed = report["problems"]["listed"] if report and "problems" in report else []
        cpp = listed + ([report["error"]["message"]] if report and "error" in report else []) + [proc.stderr]
        self.assertTrue(any(msg in m for m in cpp), f"python: {msg}\nC++: {cpp}")
        return msg

    def test_crc32c(self):
        self.assertEqual(rtpack.crc32c(b"123456789"), 0xE3069283)  # SPEC §1.1 check value
        data = np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8).tobytes()
        self.assertEqual(rtpack.crc32c(data), rtpack.crc32c_portable(data))
        self.assertEqual(rtpack.crc32c(self.good[:124]), int(self.header["header_crc32c"]))

    def test_chunk_crc(self):
        bad = bytearray(self.good)
        bad[int(self.toc[self.point]["offset"]) + 100] ^= 0x20
        path = self.write(bytes(bad), "flip-chunk")
        with rtpack.Package(path) as p:  # the header and TOC are fine: the chunk fails when read
            with self.assertRaises(rtpack.ChecksumError) as cm:
                p.chunk(self.point)
        self.assertIn(self.label, str(cm.exception))
        self.assertIn("checksum mismatch", str(cm.exception))
        self.refused(bytes(bad), "flip-chunk", rtpack.ChecksumError, whole=True)

    def test_toc_and_header_crc(self):
        bad = bytearray(self.good)
        bad[int(self.header["toc_offset"]) + 9] ^= 1
        self.assertIn("table of contents checksum", self.refused(bytes(bad), "flip-toc", rtpack.ChecksumError))
        bad = bytearray(self.good)
        bad[60] ^= 1  # unique_triangles
        self.assertIn("header checksum", self.refused(bytes(bad), "flip-header", rtpack.ChecksumError))

    def test_version_and_magic(self):
        for major in (2, rtpack.VERSION_MAJOR - 1, rtpack.VERSION_MAJOR + 1):
            bad = bytearray(self.good)
            struct.pack_into("<I", bad, 8, major)
            patch_header(bad)
            msg = self.refused(bytes(bad), f"version-{major}", rtpack.VersionError)
            self.assertIn("version", msg)
            self.assertIn(f"{major}.0", msg)
        bad = bytearray(self.good)
        bad[0:1] = b"X"
        self.assertIn("bad magic", self.refused(bytes(bad), "magic", rtpack.BadMagicError))

    def test_truncated(self):
        self.assertIn("smaller than the 4096-byte header block",
                      self.refused(self.good[:1000], "trunc-1000", rtpack.TruncatedError))
        self.assertIn("truncated file: header says",
                      self.refused(self.good[:-100], "trunc-tail", rtpack.TruncatedError))
        self.assertIn("100 bytes more than the header's",
                      self.refused(self.good + bytes(100), "appended", rtpack.MalformedError))
        self.assertIn("not an rtpack package (bad magic; 17 bytes)",
                      self.refused(b'{"asset": "2.0"}\n', "short-json", rtpack.BadMagicError))

    def test_patched_fields(self):
        """Fields changed with every CRC fixed up: only the structural checks can catch them."""
        off = int(self.toc[self.point]["offset"])
        raw = self.good[off:off + int(self.toc[self.point]["stored_size"])]
        table = np.frombuffer(raw, rtpack.SECTION_ENTRY, int(np.frombuffer(raw, rtpack.CHUNK_HEADER, 1)[0]["section_count"]), 16)
        k = int(np.nonzero(table["type"] == rtpack.SEC_INSTANCES)[0][0])
        bad = bytearray(self.good)
        struct.pack_into("<I", bad, off + 16 + 24 * k + 4, 100)  # InstanceRecord elem_size 72 -> 100
        toc_at = int(self.header["toc_offset"]) + self.point * int(self.header["toc_entry_size"])
        struct.pack_into("<I", bad, toc_at + 40, rtpack.crc32c(bytes(bad[off:off + len(raw)])))
        patch_header(bad)
        msg = self.refused(bytes(bad), "elem-size", rtpack.MalformedError, whole=True)
        self.assertEqual(msg, f"{self.label}: section 5 has elements of 100 bytes, expected 72")
        bad = bytearray(self.good)  # a stored chunk whose raw_size disagrees
        struct.pack_into("<Q", bad, toc_at + 32, len(raw) + 64)
        patch_header(bad)
        self.assertIn(f"raw_size {len(raw) + 64} differs from the {len(raw)} stored bytes of an uncompressed chunk",
                      self.refused(bytes(bad), "raw-size", rtpack.MalformedError, whole=True))
        bad = bytearray(self.good)  # non-zero padding: no checksum covers it
        bad[200] = 1
        self.assertEqual(self.refused(bytes(bad), "padding", rtpack.MalformedError, whole=True),
                         "header block padding (bytes 128..4095): byte 200 of the file is not 0")
        bad = bytearray(self.good)  # a TOC entry's reserved field
        struct.pack_into("<I", bad, toc_at + 44, 7)
        patch_header(bad)
        self.assertIn("non-zero reserved field", self.refused(bytes(bad), "toc-reserved", rtpack.MalformedError,
                                                              whole=True))

    def test_cli(self):
        ok = subprocess.run([sys.executable, os.path.join(ROOT, "python", "rtpack.py"), self.src, "--json"],
                            capture_output=True, text=True, timeout=60)
        self.assertEqual(ok.returncode, 0, ok.stderr)
        s = json.loads(ok.stdout)
        self.assertEqual((s["version"], s["package_bytes"]), (f"{rtpack.VERSION_MAJOR}.{rtpack.VERSION_MINOR}", len(self.good)))
        path = self.write(self.good[:-1], "cli-trunc")
        bad = subprocess.run([sys.executable, os.path.join(ROOT, "python", "rtpack.py"), path],
                             capture_output=True, text=True, timeout=60)
        self.assertEqual(bad.returncode, 3)
        self.assertIn("truncated file", bad.stderr)


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--build" in args:
        i = args.index("--build")
        BUILD = os.path.abspath(args[i + 1])
        del args[i:i + 2]
    unittest.main(argv=[sys.argv[0]] + args)
