#!/usr/bin/env python3
"""The one-way layering of lib/ (lib/layers.txt, docs/design.md "Data flow"), checked on the sources.

Every `#include "m/..."` in lib/<module>/ (subfolders too) must name the module itself, formats/, or a
module that lib/layers.txt lets it use (the closure of its line). Every folder of lib/ has a line, every
line names modules listed before it (so the layering has no cycle), and neither half of the package path
(writer: scene .. package; reader: reader .. rtpack) can reach the other. Exit 0 when all holds, 1 with one
line per violation otherwise.

    layering_test.py [--root DIR]   check the tree at DIR (default: this repository)
    layering_test.py --self-test    also prove the check fails: a copy of the layering with one wrong
                                    include, one cycle and one cross-half line must each be refused
"""
import argparse
import os
import re
import shutil
import sys
import tempfile

WRITER_HALF = {"scene", "mesh", "cluster", "bvh", "voxel", "package"}
READER_HALF = {"reader", "trace", "inspect", "rtpack"}
INCLUDE = re.compile(r'^\s*#\s*include\s*"([A-Za-z0-9_]+)/[^"]*"', re.M)


def read_layers(path):
    """{module: set of direct deps} in file order; problems as strings."""
    layers, problems = {}, []
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            m = re.fullmatch(r"([a-z]+):\s*(.*)", line)
            if not m:
                problems.append(f"{path}:{n}: not 'module: deps': {line!r}")
                continue
            name, deps = m.group(1), m.group(2).split()
            for d in deps:
                if d not in layers:
                    problems.append(f"{path}:{n}: {name} uses {d}, which has no line before it (a cycle or a typo)")
            layers[name] = set(deps)
    return layers, problems


def closure(layers):
    out = {}
    for name, deps in layers.items():  # file order: every dep is already closed
        c = set()
        for d in deps:
            c |= {d} | out.get(d, set())
        out[name] = c
    return out


def check(root):
    problems = []
    lib = os.path.join(root, "lib")
    layers, problems = read_layers(os.path.join(lib, "layers.txt"))
    allowed = closure(layers)
    for name in sorted(WRITER_HALF | READER_HALF):
        if name not in allowed:
            continue
        other = READER_HALF if name in WRITER_HALF else WRITER_HALF
        crossed = sorted(allowed[name] & other)
        if crossed:
            problems.append(f"lib/layers.txt: {name} reaches {', '.join(crossed)} across the two halves")
    for module in sorted(os.listdir(lib)):
        mdir = os.path.join(lib, module)
        if not os.path.isdir(mdir):
            continue
        if module not in layers:
            problems.append(f"lib/{module}: no line in lib/layers.txt")
            continue
        ok = {module, "formats"} | allowed[module]
        for dirpath, _, files in os.walk(mdir):
            for fn in sorted(files):
                if not fn.endswith((".h", ".cpp", ".hpp", ".inc")):
                    continue
                path = os.path.join(dirpath, fn)
                with open(path, encoding="utf-8", errors="replace") as f:
                    text = f.read()
                for m in INCLUDE.finditer(text):
                    inc = m.group(1)
                    if inc not in ok:
                        line = text.count("\n", 0, m.start()) + 1
                        rel = os.path.relpath(path, root)
                        problems.append(f"{rel}:{line}: {module} includes {inc}/, which lib/layers.txt does not let it use")
    return problems


def self_test(root):
    """The check must refuse three broken copies of the real tree."""
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        def copy():
            dst = os.path.join(tmp, "tree")
            shutil.rmtree(dst, ignore_errors=True)
            shutil.copytree(os.path.join(root, "lib"), os.path.join(dst, "lib"),
                            ignore=shutil.ignore_patterns("*.cpp"))
            return dst
        cases = []
        t = copy()  # 1. bvh.h includes the tracer (what issue 53 found in the code)
        with open(os.path.join(t, "lib", "bvh", "bvh.h"), "a", encoding="utf-8") as f:
            f.write('\n#include "trace/trace.h"\n')
        cases.append(("bvh including trace/", check(t)))
        t = copy()  # 2. core uses layout: a cycle
        p = os.path.join(t, "lib", "layers.txt")
        text = open(p, encoding="utf-8").read().replace("\ncore:\n", "\ncore: layout\n")
        open(p, "w", encoding="utf-8").write(text)
        cases.append(("core using layout (a cycle)", check(t)))
        t = copy()  # 3. the reader half reaching the writer half through its line
        p = os.path.join(t, "lib", "layers.txt")
        text = open(p, encoding="utf-8").read().replace("\nreader: layout\n", "\nreader: layout bvh\n")
        open(p, "w", encoding="utf-8").write(text)
        cases.append(("reader using bvh", check(t)))
        for what, problems in cases:
            if not problems:
                failures.append(f"self-test: {what} was not refused")
            else:
                print(f"self-test: {what} refused: {problems[0]}")
    return failures


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", default=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    ap.add_argument("--self-test", action="store_true")
    args = ap.parse_args()
    problems = check(args.root)
    if args.self_test:
        problems += self_test(args.root)
    for p in problems:
        print(p)
    if problems:
        return 1
    print(f"layering: every #include under {os.path.join(args.root, 'lib')} follows lib/layers.txt")
    return 0


if __name__ == "__main__":
    sys.exit(main())
