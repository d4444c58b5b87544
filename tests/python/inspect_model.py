"""What rtpack-inspect computes (lib/inspect/inspect*.cpp), recomputed from python/rtpack.py's arrays:
spreads, histograms, BVH shape statistics and the DAG pool walk of SPEC §4.5. Used by
test_rtpack_reader.py to compare the Python reader with `rtpack-inspect --json` field by field.
"""
import numpy as np

import rtpack


# ---- what rtpack-inspect computes, derived here from the reader's arrays -------------------------------
def spread(values):
    v = [float(x) for x in values]
    return {"min": min(v), "mean": sum(v) / len(v), "max": max(v)} if v else {"min": None, "mean": None, "max": None}


def histogram(values):  # bucket 0 holds 0, bucket k >= 1 holds [2^(k-1), 2^k)
    counts = {}
    for v in values:
        k = int(v).bit_length()
        counts[k] = counts.get(k, 0) + 1
    if not counts:
        return []
    return [{"min": 0 if k == 0 else 1 << (k - 1), "max": 1 if k == 0 else 1 << k, "count": counts.get(k, 0)}
            for k in range(min(counts), max(counts) + 1)]


def half_area(lo, hi):  # (n, 3) float64 each; 0 for an empty box
    d = hi - lo
    a = d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0]
    return np.where(np.all(lo <= hi, axis=1), a, 0.0)


def bvh_shape(nodes, root, leaf_prims, cost_block):
    """Benthin 2008 §4 statistics of one BVH (inspect.h BvhShape), walked level by level.
    `leaf_prims(first, count)` -> primitives of the leaves' blocks (vectorized)."""
    s = dict(c_box=0.0, c_tri=0.0, branching=0.0, leaf_fill=0.0, max_depth=0, nodes=0, leaves=0, blocks=0,
             primitives=0)
    root = int(root)
    if root == rtpack.CHILD_EMPTY:
        return s
    if root & rtpack.LEAF_BIT:
        first, count = np.array([root & (2**27 - 1)]), np.array([(root >> 27 & 15) + 1])
        p = int(leaf_prims(first, count)[0])
        s.update(leaves=1, blocks=int(count[0]), primitives=p, c_tri=float(-(-p // cost_block)),
                 leaf_fill=p / (int(count[0]) * cost_block))
        return s
    frontier, root_area, filled_lanes, depth = np.array([root]), None, 0, 0
    while len(frontier):
        depth += 1
        n = nodes[frontier]
        lo, hi = n["lo"].astype(np.float64), n["hi"].astype(np.float64)  # (k, 3, W)
        ch = n["child"].astype(np.int64)
        filled = ch != rtpack.CHILD_EMPTY
        leaf = filled & ((ch & rtpack.LEAF_BIT) != 0)
        area = half_area(lo.min(axis=2), hi.max(axis=2))  # empty lanes are (+inf, -inf): no effect
        if root_area is None:
            root_area = float(area[0])
        ratio = (lambda a: a / root_area) if root_area > 0 else (lambda a: np.ones_like(a))
        s["c_box"] += float(ratio(area).sum())
        s["nodes"] += len(frontier)
        filled_lanes += int(filled.sum())
        refs = ch[leaf]
        first, count = refs & (2**27 - 1), ((refs >> 27) & 15) + 1
        prims = leaf_prims(first, count)
        lb = half_area(lo.transpose(0, 2, 1)[leaf], hi.transpose(0, 2, 1)[leaf])
        s["c_tri"] += float((ratio(lb) * np.ceil(prims / cost_block)).sum())
        s["leaves"] += len(refs)
        s["blocks"] += int(count.sum())
        s["primitives"] += int(prims.sum())
        frontier = ch[filled & ~leaf]
    s["max_depth"] = depth
    s["branching"] = filled_lanes / s["nodes"]
    s["leaf_fill"] = s["primitives"] / (s["blocks"] * cost_block) if s["blocks"] else 0.0
    return s


def mesh_shape(nodes, blocks, e, b):
    prim = blocks["prim"][int(e["block_first"]):int(e["block_first"] + e["block_count"])]
    same = prim[:, 1:] == prim[:, :-1]  # SPEC §2.3: a short block repeats its last triangle
    real = np.where(same.any(axis=1), same.argmax(axis=1) + 1, b)
    cum = np.concatenate([[0], np.cumsum(real)])
    return bvh_shape(nodes[int(e["node_first"]):int(e["node_first"] + e["node_count"])], e["root"],
                     lambda f, c: cum[f + c] - cum[f], b)


def instance_shape(nodes, e):
    return bvh_shape(nodes, e["root"], lambda f, c: c, 1)


def group(shapes):  # inspect.h BvhGroup::json
    shaped = [s for s in shapes if s["leaves"] > 0]
    return {"bvhs": len(shapes), "root_leaves": sum(s["nodes"] == 0 and s["leaves"] > 0 for s in shapes),
            "primitives": sum(s["primitives"] for s in shapes), "nodes": sum(s["nodes"] for s in shapes),
            "blocks": sum(s["blocks"] for s in shapes),
            "c_box": spread(s["c_box"] for s in shaped), "c_tri": spread(s["c_tri"] for s in shaped),
            "sah": spread(s["c_box"] + s["c_tri"] for s in shaped),
            "branching": spread(s["branching"] for s in shaped if s["nodes"]),
            "leaf_fill": spread(s["leaf_fill"] for s in shaped if s["blocks"]),
            "max_depth": spread(s["max_depth"] for s in shaped)}


def dag_stats(grids, words, leaves):
    """SPEC §4.5, as inspect_dag.cpp reports it: set cells (memoized per (node, level) over the pool),
    distinct nodes and leaves reached from any grid, and the bytes each grid reaches alone."""
    memo, node_bytes, leaf_set = {}, {}, set()

    def node_size(kids):  # words: the head, one per reference, two per inline leaf
        return 4 * (1 + sum({"ref": 1, "inline": 2, "full": 0}[w] for _, w, _ in kids))

    def cells(ref, level):
        if level == 0:
            leaf_set.add(ref)
            return bin(int(leaves[ref])).count("1")
        if (ref, level) not in memo:
            kids = rtpack.dag_node(words, ref)
            node_bytes[ref] = node_size(kids)
            memo[(ref, level)] = sum(64 << (3 * (level - 1)) if w == "full" else bin(v).count("1") if w == "inline"
                                     else cells(v, level - 1) for _, w, v in kids)
        return memo[(ref, level)]

    def alone(root, levels):  # voxel::dag_reachable_bytes
        if levels == 0:
            return 8
        seen, nodes, grid_leaves, todo = set(), {}, set(), [(root, levels)]
        while todo:
            ref, level = todo.pop()
            if (ref, level) in seen:
                continue
            seen.add((ref, level))
            kids = rtpack.dag_node(words, ref)
            nodes[ref] = node_size(kids)
            for _, w, v in kids:
                if w == "ref":
                    (grid_leaves.add(v) if level == 1 else todo.append((v, level - 1)))
        return sum(nodes.values()) + 8 * len(grid_leaves)

    out = {"set_cells": 0, "cells": 0, "separate_bytes": 0, "empty_roots": 0, "full_roots": 0, "resolutions": {}}
    for g in grids:
        r, root = int(g["resolution"]), int(g["root"])
        if r == rtpack.DAG_BOXES:  # 7.0: instance boxes, no voxels
            continue
        levels = (r // 4).bit_length() - 1  # log2(R / 4)
        out["resolutions"][str(r)] = out["resolutions"].get(str(r), 0) + 1
        out["cells"] += r ** 3
        if root == rtpack.DAG_EMPTY:
            out["empty_roots"] += 1
        elif root == rtpack.DAG_FULL:
            out["full_roots"] += 1
            out["set_cells"] += r ** 3
        else:
            out["set_cells"] += cells(root, levels)
            out["separate_bytes"] += alone(root, levels)
    out["nodes"] = len(node_bytes)
    out["reached_bytes"] = sum(node_bytes.values()) + 8 * len(leaf_set)
    return out
