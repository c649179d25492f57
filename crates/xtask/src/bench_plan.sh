#!/bin/sh
# A lent GPU's short session, in one command: the benchmark's open questions first,
# each in its own process and folder under OUT (the first argument; default
# bench-out), so that a time-out keeps what finished. Every run's report is
# OUT/NAME/bench.md; OUT/all.md joins them. About 5 minutes on an NVIDIA H200
# (the glTF scenes took 11-22 s each at 1080p, 13-43 s at 4K, for all their variants).
#
#   ./plan.sh bench-out
#
# Environment: FRAMES (measured frames per run, default 120), RUN_LIMIT (seconds one
# variant may take before the bench gives up on the rest of its scene, default 60),
# SIZE (every run at this size instead: `tiny` to try the plan on a CPU driver).
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-bench-out}
mkdir -p "$out"
: > "$out/all.md"
run() {
    name=$1
    size=$2
    shift 2
    echo "plan.sh: $name ($(date -u +%H:%M:%S))" >&2
    "$here/run.sh" --sizes "${SIZE:-$size}" --frames "${FRAMES:-120}" \
        --run-limit "${RUN_LIMIT:-60}" --out "$out/$name" "$@" > "$out/$name.log" 2>&1
    echo "plan.sh: $name: exit status $?" >&2
    if [ -f "$out/$name/bench.md" ]; then
        { echo "<!-- $name -->"; cat "$out/$name/bench.md"; echo; } >> "$out/all.md"
    fi
}
# Scatter bokeh against Bevy's bokeh (groups of sixteen pixels since 2026-12-05).
run dof-1080p 1080p --scenes dof
# Deferred against forward 4x MSAA at 4K (a single resolve since 2026-12-05).
run showcase-msaa-4k 4k --scenes showcase --variants forward-msaa4,deferred-msaa4
# DF shadows, DFAO and the lighting pass against Bevy's, and Penumbra off.
run showcase-1080p 1080p --scenes showcase
# Never measured on a GPU: the stress scene and the flagship.
run stress-1080p 1080p --scenes stress
run samaritan-1080p 1080p --scenes samaritan
run dof-4k 4k --scenes dof
run cornell-1080p 1080p --scenes cornell
run helmet-1080p 1080p --scenes helmet
echo "plan.sh: done; the reports joined in $out/all.md" >&2
