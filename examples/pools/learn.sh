#!/bin/sh
# The shipped pick-and-place pools learned again from nothing: `besman learn` with its defaults on the 15
# shared DFKI recordings, one pool per robot (about 5 minutes each on 2 cores). A pool's work files would
# let the learn resume, so each pool folder is removed first.
# Usage: examples/pools/learn.sh [RECORDINGS]
set -e
cd "$(dirname "$0")/../.."
recordings=${1:-../shared/data/dfki_pick_and_place}
for robot in aila ur5e openarm examples/robots/widowx_ai examples/robots/widowx_ai_pair; do
    pool="examples/pools/pick_place_$(basename "$robot")"
    rm -rf "$pool"
    besman learn --demos "$recordings" --robot "$robot" --out "$pool"
done
