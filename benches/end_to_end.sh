#!/usr/bin/env bash
# Issue 16 point 4, end to end: `solve` of the R-S-S-R over 100,000 time points with each
# engine, CSV and JSON written to files, the eight runs interleaved ROUNDS times, then wall and
# CPU time (user + system of mechgen, its writer thread and the solver) and the ratios generic
# over generated. Benchmarks are not tests: it prints what was measured.
#
#   bash benches/end_to_end.sh [MECHGEN] [ROUNDS] [OUTDIR]    # defaults: target/release/mechgen 5 /tmp/e2e
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/mechgen}; rounds=${2:-5}; out=${3:-/tmp/e2e}
mkdir -p "$out"
sed 's/^steps = 1000$/steps = 100000/' benches/rssr_revolution.toml > "$out/rssr100k.toml"
"$bin" solve "$out/rssr100k.toml" --engine generated --format csv -o "$out/warm.csv"
log="$out/times.txt"; : > "$log"
for r in $(seq "$rounds"); do
  for engine in generated generic; do for format in csv json; do
    /usr/bin/time -a -o "$log" -f "$engine $format %e %U %S" \
      "$bin" solve "$out/rssr100k.toml" --engine "$engine" --format "$format" -o "$out/$engine.$format"
  done; done
done
python3 - "$log" <<'PY'
import sys, statistics as st
runs = {}
for line in open(sys.argv[1]):
    e, f, wall, u, s = line.split()
    runs.setdefault((e, f), []).append((float(wall), float(u) + float(s)))
for k in sorted(runs):
    wall = [x[0] for x in runs[k]]; cpu = [x[1] for x in runs[k]]
    print(f"{k[0]} {k[1]}: wall min/median {min(wall):.2f}/{st.median(wall):.2f} s, CPU {min(cpu):.2f}/{st.median(cpu):.2f} s")
for f in ["csv", "json"]:
    g, c = runs[("generated", f)], runs[("generic", f)]
    per = [cc[0] / gg[0] for gg, cc in zip(g, c)]
    print(f"{f}: generic/generated wall {min(x[0] for x in c)/min(x[0] for x in g):.1f}x (min) "
          f"{st.median(x[0] for x in c)/st.median(x[0] for x in g):.1f}x (median), CPU "
          f"{min(x[1] for x in c)/min(x[1] for x in g):.1f}x (min) {st.median(x[1] for x in c)/st.median(x[1] for x in g):.1f}x (median); per round "
          + " ".join(f"{p:.1f}" for p in per))
PY
