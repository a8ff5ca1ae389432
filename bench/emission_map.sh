#!/usr/bin/env bash
# A real model with an emission map, lit as a product shot: the Khronos ToyCar (CC0; 88,837
# triangles read its emission map, most of them black there) under a sun and a uniform sky,
# through its Camera002. Measures rayfarm's efficiency 1 / (relMSE x seconds) against its own
# reference, for this build and, with --before, another rayfarm binary (docs/benchmarks.md,
# "An emission map").
#
#   bench/emission_map.sh [BUILD_DIR] [--model DIR] [--before RAYFARM] [--res WxH] [--spp N]
#                         [--ref-spp N] [--seeds "S1 S2 ..."] [--threads T]
#   nice bench/emission_map.sh build --before /tmp/rayfarm-before
#
# --model: the folder holding ToyCar.gltf and its files (default ../shared/gltf-samples/ToyCar/glTF,
# beside the repository). The model and the scene are copied into BUILD_DIR/bench/emission-map/;
# the reference (--ref-spp, rendered by this build once, then cached there) is shared by both
# binaries: both estimators are unbiased. Each binary renders --spp at each seed, alternating;
# the table gives each render's relMSE (the last row of its error.csv) and time (rayfarm's own
# "time" line: its passes, without reading the scene or building the BVH), and the medians.
set -euo pipefail
cd "$(dirname "$0")/.."
build=build
if [[ $# -gt 0 && "$1" != --* ]]; then build=$1; shift; fi
model=../shared/gltf-samples/ToyCar/glTF
before=""
res=160x100
spp=256
ref_spp=8192
seeds="11 12 13"
threads=2
while [[ $# -gt 0 ]]; do
  case "$1" in
    --model) model="$2"; shift 2 ;;
    --before) before="$2"; shift 2 ;;
    --res) res="$2"; shift 2 ;;
    --spp) spp="$2"; shift 2 ;;
    --ref-spp) ref_spp="$2"; shift 2 ;;
    --seeds) seeds="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    *) echo "emission_map.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
[[ -f "$model/ToyCar.gltf" ]] || { echo "emission_map.sh: no ToyCar.gltf in $model (--model DIR)" >&2; exit 2; }
[[ -z "$before" || -x "$before" ]] || { echo "emission_map.sh: $before is not a program" >&2; exit 2; }

cmake --build "$build" --target rayfarm >/dev/null
after="$build/cli/rayfarm"
dir="$build/bench/emission-map"
mkdir -p "$dir/runs"
cp -u "$model"/* "$dir/"
cat >"$dir/scene.json" <<'EOF'
{
  "format": 1,
  "gltf": {"file": "ToyCar.gltf", "camera": "Camera002"},
  "lights": [
    {"type": "constant", "radiance": [0.45, 0.55, 0.75]},
    {"type": "directional", "direction": [-0.4, -0.8, -0.45], "irradiance": [3.0, 2.8, 2.5]}
  ],
  "render": {"max_depth": 8, "integrator": "mis"}
}
EOF

# render RAYFARM OUT.exr SPP SEED [ARGS...]: prints the render's seconds.
render() {
  local bin=$1 out=$2 n=$3 seed=$4 log="${2%.exr}.log"
  shift 4
  "$bin" render "$dir/scene.json" --res "$res" --threads "$threads" --spp "$n" --seed "$seed" \
    -o "$out" "$@" >"$log" 2>&1 || { echo "render failed ($log):" >&2; tail -5 "$log" >&2; exit 1; }
  sed -n 's/^time \([0-9.]*\) s,.*/\1/p' "$log"
}

ref="$dir/reference-$res-$ref_spp.exr"
if [[ ! -f "$ref" ]]; then
  echo "reference: $ref_spp spp at $res ..."
  render "$after" "$ref" "$ref_spp" 77 >/dev/null
fi
echo "reference: $ref"
echo "binary,seed,rel_mse,seconds" >"$dir/runs/runs.csv"
bins=(after)
[[ -n "$before" ]] && bins=(before after)
for seed in $seeds; do
  for b in "${bins[@]}"; do
    bin=$after
    [[ $b == before ]] && bin=$before
    out="$dir/runs/$b-$seed.exr"
    secs=$(render "$bin" "$out" "$spp" "$seed" --reference "$ref")
    mse=$(tail -1 "${out%.exr}.error.csv" | awk -F, -v col="$(head -1 "${out%.exr}.error.csv" |
          tr , '\n' | grep -n '^ref_rel_mse$' | cut -d: -f1)" '{ print $col }')
    echo "$b,$seed,$mse,$secs" >>"$dir/runs/runs.csv"
    echo "$b seed $seed: relMSE $mse, $secs s"
  done
done
echo
awk -F, 'NR > 1 { m[$1] = m[$1] " " $3; s[$1] = s[$1] " " $4; e[$1] = e[$1] " " 1 / ($3 * $4) }
  function median(list,   a, n, i, j, t) {
    n = split(list, a, " ")
    for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (a[j] + 0 < a[i] + 0) { t = a[i]; a[i] = a[j]; a[j] = t }
    return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
  }
  END {
    printf "%-7s %-34s %-22s %s\n", "binary", "relMSE", "seconds", "efficiency (median)"
    for (b in m) { eff[b] = median(e[b]); printf "%-7s %-34s %-22s %.1f\n", b, m[b], s[b], eff[b] }
    if (("before" in eff) && eff["before"] > 0) printf "ratio after / before: %.2fx\n", eff["after"] / eff["before"]
  }' "$dir/runs/runs.csv"
