#!/usr/bin/env bash
# Time to a clean image: rayfarm against Blender Cycles at equal time (docs/benchmarks.md,
# "Efficiency against Blender Cycles").
#
#   bench/efficiency.sh [BUILD_DIR] [--size N] [--rounds R] [--scenes S.json ...] [--threads T]
#                       [--top-seconds T] [--steps K] [--ref-seconds T] [--seeds K]
#                       [-- extra rayfarm render args]
#   nice bench/efficiency.sh build
#   nice bench/efficiency.sh build --scenes scenes/cornell-blocks/scene.json -- --integrator nee
#
# Per scene, for each renderer (rayfarm, and Blender Cycles when `blender` is on PATH):
#  * its reference: --seeds independent renders of about --ref-seconds in all (sized by a short
#    calibration render), their mean and the variance of that mean (so the reference's own noise
#    is subtracted from every relMSE); their times give its seconds per spp. Each
#    renderer is measured against its OWN reference: Cycles renders the scene through
#    scripts/blender_reference.py --approximate (UV spheres, Glossy and Glass BSDFs), which is not
#    exactly our scene, and that difference must not count as error;
#  * --rounds rounds, alternating the renderers (and which goes first), of a ladder of --steps
#    sample counts (powers of 2) whose top render takes about --top-seconds: both ladders span
#    the same times;
#  * every image's relMSE against the reference: mean over pixels and channels of
#    (x - ref)^2 / (ref^2 + 1e-2), as `rayfarm render --reference` reports it.
# bench/efficiency_tool prints per renderer and spp the median time, median relMSE and their
# product, the efficiency 1 / (relMSE x time) (median product over the ladder's upper half, where
# it is flat) and the ratio rayfarm / Cycles, and draws relMSE against time (log-log).
#
# Times are wall seconds of the render itself: rayfarm's printed "time" (its passes, without
# reading the scene, building the BVH or writing files); Cycles' render_pre to render_post
# (its scene sync, BVH and sampling, without Blender's start or the file write). The CPU column
# is the whole rayfarm process's CPU seconds, and Cycles' process CPU over its render.
# Cycles keeps its normal light sampling (each emitter's sample_as_light on).
#
# References and their seconds per spp are cached in BUILD_DIR/bench/efficiency-data/<scene>-<size>-<key>/
# (key: a hash of the scene file, the extra rayfarm arguments and the settings that shape them);
# delete that folder after a change to either renderer. The runs of the last invocation are in
# its runs/ folder, the plots in BUILD_DIR/bench/efficiency-data/<scene>-efficiency.png.
set -euo pipefail
cd "$(dirname "$0")/.."
build=build
if [[ $# -gt 0 && "$1" != --* ]]; then build=$1; shift; fi
size=128
rounds=3
threads=2
top_seconds=16
steps=7
ref_seconds=200
seeds=4
scenes=()
extra=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --size) size="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --top-seconds) top_seconds="$2"; shift 2 ;;
    --steps) steps="$2"; shift 2 ;;
    --ref-seconds) ref_seconds="$2"; shift 2 ;;
    --seeds) seeds="$2"; shift 2 ;;
    --scenes)
      shift
      while [[ $# -gt 0 && "$1" != --* ]]; do scenes+=("$1"); shift; done ;;
    --) shift; extra=("$@"); break ;;
    *) echo "efficiency.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
[[ ${#scenes[@]} -gt 0 ]] || scenes=(scenes/cornell-box/scene.json scenes/cornell-blocks/scene.json)
for n in "$size" "$rounds" "$threads" "$steps" "$seeds"; do
  [[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "efficiency.sh: $n is not a positive integer" >&2; exit 2; }
done
[[ $seeds -ge 2 ]] || { echo "efficiency.sh: --seeds must be at least 2" >&2; exit 2; }
for s in "${scenes[@]}"; do [[ -f "$s" ]] || { echo "efficiency.sh: no scene $s" >&2; exit 2; }; done

cmake --build "$build" --target rayfarm efficiency_tool >/dev/null
rayfarm="$build/cli/rayfarm"
tool="$build/bench/efficiency_tool"
data="$build/bench/efficiency-data"
mkdir -p "$data"
have_blender=0
if command -v blender >/dev/null; then
  have_blender=1
  echo "Blender: $(blender --version 2>/dev/null | head -1)"
else
  echo "no blender on PATH: measuring rayfarm alone (no ratio)"
fi
echo "size ${size}x${size}, $threads threads, $rounds rounds, $steps steps up to ~${top_seconds} s," \
     "references ~${ref_seconds} s in $seeds seeds; rayfarm args: ${extra[*]:-(none)}"

# The power of 2 nearest (in log) to x, at least 1.
pow2() { awk -v x="$1" 'BEGIN { k = (x <= 1) ? 0 : int(log(x) / log(2) + 0.5); print 2 ^ k }'; }

# rayfarm_render OUT.exr SPP SEED: renders, removes the side files, prints "seconds cpu_seconds".
rayfarm_render() {
  local out=$1 spp=$2 seed=$3 log="${1%.exr}.log" t
  t=$( { TIMEFORMAT='%U %S'; time "$rayfarm" render "$scene" --res "${size}x${size}" --threads "$threads" \
         --spp "$spp" --seed "$seed" -o "$out" ${extra[@]+"${extra[@]}"} >"$log" 2>&1; } 2>&1 ) || {
    echo "rayfarm render failed ($log):" >&2; tail -5 "$log" >&2; exit 1; }
  rm -f "${out%.exr}.png" "${out%.exr}.error.csv" "${out%.exr}.error.png"
  local secs
  secs=$(sed -n 's/^time \([0-9.]*\) s,.*/\1/p' "$log")
  [[ -n "$secs" ]] || { echo "no render time in $log" >&2; exit 1; }
  echo "$secs $(awk -v u="${t% *}" -v s="${t#* }" 'BEGIN { print u + s }')"
}

# cycles OUT ARGS...: runs scripts/blender_reference.py with --approximate at our size and threads.
cycles() {
  local out=$1; shift
  blender -b --factory-startup --python scripts/blender_reference.py -- "$scene" "$out" \
    --approximate --res "${size}x${size}" --threads "$threads" "$@" >"${out%.exr}.log" 2>&1 || {
    echo "Blender failed (${out%.exr}.log):" >&2; tail -5 "${out%.exr}.log" >&2; exit 1; }
}

# ladder SECONDS_PER_SPP: the spp ladder whose top render takes about --top-seconds.
ladder() {
  local top k out=()
  top=$(pow2 "$(awk -v t="$top_seconds" -v p="$1" 'BEGIN { print t / p }')")
  for ((k = steps - 1; k >= 0; k--)); do
    local s=$((top >> k))
    [[ $s -ge 1 && " ${out[*]-} " != *" $s "* ]] && out+=("$s")
  done
  echo "${out[*]}"
}

for scene in "${scenes[@]}"; do
  name=$(basename "$(dirname "$scene")")
  key=$({ cat "$scene"; echo "size=$size threads=$threads seeds=$seeds ref=$ref_seconds extra=${extra[*]-}"; } |
        sha256sum | cut -c1-12)
  dir="$data/$name-$size-$key"
  mkdir -p "$dir"
  echo
  echo "== $scene ($dir)"
  renderers=(rayfarm)
  [[ $have_blender -eq 1 ]] && renderers+=(cycles)

  echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"

  # References: --seeds independent renders each, their mean and the variance of that mean, sized
  # by a short calibration render; their own times (seconds per spp) size the ladders below.
  declare -A per_spp=()
  for r in "${renderers[@]}"; do
    ref="$dir/$r-reference.exr"
    if [[ -f "$ref" && -f "$dir/$r-per-spp.txt" ]]; then
      echo "$r reference: $ref (cached)"
      per_spp[$r]=$(cat "$dir/$r-per-spp.txt")
      continue
    fi
    if [[ $r == rayfarm ]]; then
      res=$(rayfarm_render "$dir/rayfarm-calibration.exr" 256 7)
      calibration=$(awk -v s="${res% *}" 'BEGIN { print s / 256 }')
    else
      cycles "$dir/cycles-calibration.exr" --ladder 64 --seed 7
      calibration=$(awk -F, 'NR == 2 { print $4 / 64 }' "$dir/cycles-calibration.csv")
    fi
    each=$(pow2 "$(awk -v t="$ref_seconds" -v k="$seeds" -v p="$calibration" 'BEGIN { print t / k / p }')")
    echo "$r reference: $seeds x $each spp (about $(awk -v a="$each" -v k="$seeds" -v p="$calibration" \
         'BEGIN { printf "%.0f", a * k * p }') s) ..."
    if [[ $r == rayfarm ]]; then
      parts=()
      total=0
      for ((k = 0; k < seeds; k++)); do
        res=$(rayfarm_render "$dir/rayfarm-reference-$k.exr" "$each" $((1000 + k)))
        total=$(awk -v a="$total" -v b="${res% *}" 'BEGIN { print a + b }')
        parts+=("$dir/rayfarm-reference-$k.exr")
      done
      "$tool" reference "$ref" "${parts[@]}" >/dev/null
      rm -f "${parts[@]}"
    else
      cycles "$ref" --spp $((each * seeds)) --seeds "$seeds" --seed 1000
      total=$(awk '/"render_only_seconds"/ { on = 1; next } on && /]/ { on = 0 }
                   on { gsub(/[ ,]/, ""); t += $0 } END { print t }' "${ref%.exr}.json")
    fi
    awk -v t="$total" -v n=$((each * seeds)) 'BEGIN { print t / n }' >"$dir/$r-per-spp.txt"
    per_spp[$r]=$(cat "$dir/$r-per-spp.txt")
    echo "$r reference made: $(cat "$dir/$r-per-spp.txt") s per spp"
  done

  # Rounds: each renderer's ladder, alternating which goes first.
  runs="$dir/runs"
  rm -rf "$runs"
  mkdir -p "$runs"
  echo "renderer,round,spp,seconds,cpu_seconds,image" >"$runs/runs.csv"
  declare -A ladders=()
  for r in "${renderers[@]}"; do
    ladders[$r]=$(ladder "${per_spp[$r]}")
    echo "$r ladder (spp): ${ladders[$r]}"
  done
  for ((round = 1; round <= rounds; round++)); do
    order=("${renderers[@]}")
    if [[ $((round % 2)) -eq 0 && ${#order[@]} -eq 2 ]]; then order=("${order[1]}" "${order[0]}"); fi
    for r in "${order[@]}"; do
      if [[ $r == rayfarm ]]; then
        for spp in ${ladders[rayfarm]}; do
          img="rayfarm-r$round-${spp}spp.exr"
          res=$(rayfarm_render "$runs/$img" "$spp" $((100 + round)))
          read -r secs cpu <<<"$res"
          echo "rayfarm,$round,$spp,$secs,$cpu,$img" >>"$runs/runs.csv"
        done
      else
        cycles "$runs/cycles-r$round.exr" --ladder "$(tr ' ' , <<<"${ladders[cycles]}")" --seed $((100 + round))
        awk -F, -v r="$round" 'NR > 1 { print "cycles," r "," $1 "," $4 "," $5 "," $6 }' \
          "$runs/cycles-r$round.csv" >>"$runs/runs.csv"
      fi
      echo "round $round: $r done"
    done
  done

  echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
  refs=()
  for r in "${renderers[@]}"; do refs+=(--reference "$r=$dir/$r-reference.exr"); done
  "$tool" analyse "$runs/runs.csv" "${refs[@]}" --csv "$runs/results.csv" \
    --plot "$data/$name-efficiency.png" \
    --title "$name ${size}x${size}, $threads threads: relMSE against render time"
done
