#!/bin/sh
# Regenerates the committed scenes in samples/generated/ with rtpack-make-scene.
# Usage: samples/generated/make.sh [path/to/rtpack-make-scene]   (default: build/rtpack-make-scene)
# The output is deterministic: same tool, same source meshes, same arguments -> same bytes.
set -eu
root=$(cd "$(dirname "$0")/../.." && pwd)
tool=$(realpath "${1:-$root/build/rtpack-make-scene}")
cd "$root"
"$tool" gallery -o samples/generated/gallery.glb
"$tool" forest --count 3000 --seed 1 --refine 0 -o samples/generated/forest-small.glb
"$tool" far -o samples/generated/far.glb
