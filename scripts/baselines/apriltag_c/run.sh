#!/bin/sh
# Tracking per still: pa-track against the AprilTag C library on the same frames (not part of
# CI). Needs Debian's libapriltag-dev and gcc; see ../README.md.
#   scripts/baselines/apriltag_c/run.sh [DIR [FRAMES [REPS]]]
set -eu
root=$(cd "$(dirname "$0")/../../.." && pwd)
dir=${1:-/tmp/pa_apriltag_frames}
frames=${2:-30}
reps=${3:-5}
make -C "$root/scripts/baselines/apriltag_c" -s
ex="$root/target/release/examples/apriltag_compare"
(cd "$root" && cargo build --release -q --example apriltag_compare)
if [ ! -f "$dir/truth.txt" ]; then
    "$ex" render "$dir" --frames "$frames"
fi
bench="$root/scripts/baselines/apriltag_c/apriltag_bench"
"$bench" 2 2 "$reps" "$dir/c_d2.txt" "$dir"/frame_*.pgm
"$bench" 1 2 "$reps" "$dir/c_d1.txt" "$dir"/frame_*.pgm
"$ex" run "$dir" --threads 2 --reps "$reps" \
    --c "C library decimate 2, 2 threads=$dir/c_d2.txt" \
    --c "C library decimate 1, 2 threads=$dir/c_d1.txt"
