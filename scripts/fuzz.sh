#!/usr/bin/env bash
# Bounded-time fuzzing of everything that reads untrusted bytes (docs/stability.md): the scene
# parser (JSON, OBJ + MTL, PLY and glTF), every wire message the master and workers decode with
# the conversions behind them, scene bundles, and image files (PNG, JPEG, OpenEXR, Radiance HDR).
# Builds the libFuzzer targets with clang under AddressSanitizer + UndefinedBehaviorSanitizer in
# build-fuzz/, runs each for SECONDS seconds (default 60) from the seed corpus in fuzz/corpus/,
# and prints executions, time and coverage. Exits non-zero when a target finds a crash, a leak or
# undefined behaviour (the input is left in build-fuzz/findings/).
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]   TARGET: scene obj ply gltf mitsuba wire bundle image (default all)
#   JOBS=2 scripts/fuzz.sh 300 wire         build parallelism (default 2)
# Needs clang-14 and libclang-rt-14-dev (apt-get install clang-14 libclang-rt-14-dev).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene obj ply gltf mitsuba wire bundle image)
build=build-fuzz
cxx=${CXX_FUZZ:-clang++-14}

mkdir -p "$build"
if [ ! -f "$build/build.ninja" ]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link" \
    -DRAYFARM_SANITIZE=ON -DRAYFARM_FUZZ=ON -DRAYFARM_BUILD_BENCH=OFF > "$build/configure.log"
fi
ninja -C "$build" -j "${JOBS:-2}" $(printf 'fuzz_%s ' "${targets[@]}")

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
mkdir -p "$build/findings"
status=0
summary=()
for t in "${targets[@]}"; do
  work="$build/corpus/$t"
  mkdir -p "$work"
  log="$build/fuzz_$t.log"
  start=$(date +%s)
  # -rss_limit_mb: a target may use at most 2 GiB; -timeout: one input at most 10 s.
  if ! "$build/fuzz/fuzz_$t" "$work" "fuzz/corpus/$t" -max_total_time="$seconds" \
      -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 -artifact_prefix="$build/findings/$t-" \
      > "$log" 2>&1; then
    status=1
    echo "fuzz_$t: FINDING, see $log and $build/findings/" >&2
  fi
  elapsed=$(( $(date +%s) - start ))
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  done_line=$(grep -E '^#[0-9]+[[:space:]]+DONE' "$log" | tail -1 || true)
  cov=$(echo "$done_line" | sed -n 's/.*cov: \([0-9]*\).*/\1/p')
  ft=$(echo "$done_line" | sed -n 's/.*ft: \([0-9]*\).*/\1/p')
  corp=$(echo "$done_line" | sed -n 's/.*corp: \([0-9]*\).*/\1/p')
  rate=$(echo "$done_line" | sed -n 's/.*exec\/s: \([0-9]*\).*/\1/p')
  summary+=("$(printf '%-8s %12s %8s %8s %8s %8s %8s' "$t" "${runs:-?}" "${elapsed}s" "${rate:-?}" "${cov:-?}" "${ft:-?}" "${corp:-?}")")
done
printf '%-8s %12s %8s %8s %8s %8s %8s\n' target executions time exec/s cov ft corpus
printf '%s\n' "${summary[@]}"
exit $status
