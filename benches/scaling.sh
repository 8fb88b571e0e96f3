#!/usr/bin/env bash
# The targets of issue 16 point 3, measured side by side in one script run: every generated
# solver timed by `mechgen bench` (min and median ns per step over the repeats), then the
# ratios the targets are stated in. The descriptions under benches/scale/ are the families of
# codegen/src/scale.rs (a unit test keeps them equal). Benchmarks are not tests: nothing here
# fails on a missed target, it prints what was measured.
#
#   bash benches/scaling.sh [REPEATS]        # default 20 passes per mechanism
#
# The first run builds every solver in mechgen's cache (chain_100 takes the longest); the
# build times are printed by `mechgen scaling --bodies 10,100`.
set -euo pipefail
cd "$(dirname "$0")/.."
repeats=${1:-20}
# BIN=PATH times another mechgen binary (say main's, for a before/after) without building.
if [ -z "${BIN:-}" ]; then cargo build --release -q -p codegen --features cli; fi
bin=${BIN:-target/release/mechgen}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

bench() { # NAME FILE TOLERANCE
    "$bin" bench "$2" --engine generated --tolerance "$3" --repeats "$repeats" --format json \
        > "$tmp/$1.json"
    jq -r --arg n "$1" '"\($n): \(.ns_per_step.min | floor) ns/step min, \(.ns_per_step.median | floor) median, \(.iterations_per_step) iterations/step"' \
        "$tmp/$1.json"
}
min() { jq '.ns_per_step.min' "$tmp/$1.json"; }
median() { jq '.ns_per_step.median' "$tmp/$1.json"; }

for m in chain_10 chain_100 arms_1x6 arms_10x6 rssr_loops_1 rssr_loops_34; do
    bench "$m" "benches/scale/$m.toml" 1e-10
done
bench rssr benches/rssr_revolution.toml 1e-12

ratio() { # LABEL NUMERATOR DENOMINATOR SCALE TARGET
    for stat in min median; do
        python3 -c "import sys; n, d, s = map(float, sys.argv[1:4]); print(f'{sys.argv[4]} ({sys.argv[5]}): {n / (s * d):.2f} (target {sys.argv[6]})')" \
            "$($stat "$2")" "$($stat "$3")" "$4" "$1" "$stat" "$5"
    done
}
echo
ratio "chain_100 / chain_10" chain_100 chain_10 1 "<= 20"
ratio "arms_10x6 / arms_1x6" arms_10x6 arms_1x6 1 "<= 12"
ratio "rssr_loops_34 / (34 x rssr_loops_1)" rssr_loops_34 rssr_loops_1 34 "<= 1.5"
echo "chain_100: $(min chain_100 | cut -d. -f1) ns/step min (target <= 100000)"
echo "R-S-S-R at 1e-12: $(min rssr | cut -d. -f1) ns/step min (target <= 160)"
