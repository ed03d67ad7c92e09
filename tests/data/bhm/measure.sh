#!/bin/sh
# Peak memory and CPU of the BHM scaling experiments (issue 19 §5), one run each, niced:
#   sh tests/data/bhm/measure.sh OUT_DIR [NAMES...]   (NAMES: sandbox 1.5x1 3x2 10x10)
# Writes OUT_DIR/NAME.time (GNU time -v) and OUT_DIR/NAME/ (the run's results).
set -u
out=$1; shift
here=$(dirname "$0")
mkdir -p "$out"
[ $# -gt 0 ] || set -- sandbox 1.5x1 3x2 10x10
for name in "$@"; do
  nice -n 10 /usr/bin/time -v -o "$out/$name.time" \
    hapticframe run "$here/search-$name.yaml" --out "$out/$name" --overwrite --quiet
done
