#!/usr/bin/env bash
# Soak test of the farm's durability (not part of CI): many jobs, workers killed all the time, the
# master restarted mid-run, and every image checked bit for bit.
#
#   scripts/soak.sh [--jobs N] [--sequences K] [--workers W] [--size PX] [--spp N]
#                   [--kill-every S] [--timeout S] [--build DIR] [--keep]
#
# Defaults: 50 jobs submitted at once to a master with 4 workers (1 thread each) on loopback
# (--insecure), 64x64 images at 256 spp in 16x16 tiles and passes of 16 (256 units a job); every
# S = 3 seconds one worker is hit, in turn killed with SIGKILL and started again, or frozen with
# SIGSTOP for 2 s (long enough to be declared lost) and thawed; the master is killed with
# SIGKILL once a third of the units are merged and stopped with SIGTERM at two thirds, each time
# started again on the same data dir. The jobs use 5 distinct settings (two scenes, three seeds, one
# with a target error), so that 5 `rayfarm render`s give the reference of every job, and every
# job's final EXR is compared with its reference by `rayfarm compare` (exit 0 = bit-identical).
# Submitted at the same time, K = 2 sequences of scenes/animated-box (`submit --frames`, same size,
# spp and layout, own seeds; in turn 1-48:6, 4-48:6 with nee and a target error of 0.02 (reached at
# 64x64, unlike the jobs' 0.002, so its tiles stop adaptively), 2-47:5 with max depth 4) live
# through the same kills and restarts; every frame is fetched (`fetch SEQ --all`) and compared with
# `rayfarm render --frame N` of its settings (the thirds of the master's kill and stop count the
# frames, a frame being as many units as a job). Prints the figures: jobs, sequences and frames,
# units, kills, freezes, restarts, duplicates dropped, units requeued, stragglers, jobs resumed from
# checkpoints, lost (jobs or frames not done or not bit-identical; must be 0) and the wall time.
# Exit 0 when nothing is lost. Binaries from ./build (or $RAYFARM_BIN).
#
# With --duration SECONDS (e.g. 3600) it soaks for that long instead, in rounds, each submitting
# new work (--jobs N still jobs, one per setting in turn, default 5; --sequences K short
# sequences, default 1) and ending once that work is done, checked bit for bit and removed:
#
#   scripts/soak.sh --duration S [--long-frames N] [--disk-mb MB] [--disk-full-seconds S]
#                   [--pollers P] [--poll-interval S] [--rss-bound-mb MB]
#                   [--no-worker-kills] [--no-freezes] [--no-master-restarts] [--no-disk-full]
#                   [--no-http] [--no-keys] [--no-long-sequence]   (and the options above)
#
# Throughout, every --kill-every S a random worker is killed (SIGKILL) and restarted, or frozen
# (SIGSTOP, 2 s: declared lost) and thawed. Rounds take turns: a quiet one, the master killed
# (SIGKILL), the disk filled, the master stopped (SIGTERM); the master restarts on the same data
# dir. The data dir is a tmpfs of --disk-mb (96) that the script mounts (as root; otherwise the
# disk phase is skipped, saying so): a filler file takes every free byte for --disk-full-seconds
# (15), a submission meanwhile must be refused, then the filler goes and every job must finish.
# The master runs with CURVE keys and --private-jobs: two client keys (alice, bob) submit in turn,
# and each round `list`, `status` and the HTTP API (with each key's token, and anonymously) must
# show a key none of the other's jobs. P = 3 pollers curl /api/jobs, /api/workers, /metrics and
# the jobs' images, one request every --poll-interval (0.5) s each. One long sequence of
# --long-frames (200) frames of 32x32 at 16 spp runs across the rounds. Every image (job and
# frame) is compared with `rayfarm render`; the master's RSS is sampled after each round and must
# stay within --rss-bound-mb (64) of the first round's. Exit 0 when nothing is lost, every image
# is identical, no key saw another's job, no HTTP request got a 500, and the RSS stayed flat.
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jobs=50
sequences=2
workers=4
size=64
spp=256
kill_every=3
timeout=600
build="${RAYFARM_BIN:-$repo_root/build}"
keep=0
duration=""
long_frames=200
disk_mb=96
disk_full_seconds=15
pollers=3
poll_interval=0.5
rss_bound_mb=64
do_kills=1
do_freezes=1
do_restarts=1
do_disk=1
do_keys=1
jobs_given=0
sequences_given=0
for a in "$@"; do
  [ "$a" = --jobs ] && jobs_given=1
  [ "$a" = --sequences ] && sequences_given=1
done

while [ $# -gt 0 ]; do
  case $1 in
    --jobs) jobs=$2; shift 2 ;;
    --sequences) sequences=$2; shift 2 ;;
    --workers) workers=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --kill-every) kill_every=$2; shift 2 ;;
    --timeout) timeout=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    --duration) duration=$2; shift 2 ;;
    --long-frames) long_frames=$2; shift 2 ;;
    --disk-mb) disk_mb=$2; shift 2 ;;
    --disk-full-seconds) disk_full_seconds=$2; shift 2 ;;
    --pollers) pollers=$2; shift 2 ;;
    --poll-interval) poll_interval=$2; shift 2 ;;
    --rss-bound-mb) rss_bound_mb=$2; shift 2 ;;
    --no-worker-kills) do_kills=0; shift ;;
    --no-freezes) do_freezes=0; shift ;;
    --no-master-restarts) do_restarts=0; shift ;;
    --no-disk-full) do_disk=0; shift ;;
    --no-http) pollers=0; shift ;;
    --no-keys) do_keys=0; shift ;;
    --no-long-sequence) long_frames=0; shift ;;
    -h|--help) sed -n '2,49p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "soak: unknown option '$1'" >&2; exit 2 ;;
  esac
done

bin() {
  local c
  for c in "$build/$2/$1" "$build/$1"; do [ -x "$c" ] && { echo "$c"; return; }; done
  echo "soak: cannot find $1 under $build (build first, or --build DIR)" >&2
  exit 1
}
work=$(mktemp -d "${TMPDIR:-/tmp}/rayfarm-soak.XXXXXX")
mkdir "$work/bin" "$work/logs" "$work/out"
# Copies, so that a rebuild during the soak cannot mix two versions.
cp "$(bin rayfarm cli)" "$(bin rayfarm-master master)" "$(bin rayfarm-worker worker)" "$work/bin/"
rayfarm="$work/bin/rayfarm"

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}
wport=$(free_port)
cport=$(free_port)
hport=$(free_port)
export RAYFARM_MASTER="tcp://127.0.0.1:$cport"
# The master's and workers' security: plain on loopback, unless the duration mode sets up keys.
master_auth=(--insecure)
secure=0

master_pid=""
declare -a worker_pids
declare -a ref_pids=()
declare -a poller_pids=()
mounted=""
cleanup() {
  local p
  [ ${#poller_pids[@]} = 0 ] || touch "$work/stop-pollers"
  for p in "${worker_pids[@]}"; do kill -CONT "$p" 2>/dev/null || true; done
  for p in "${worker_pids[@]}" $master_pid; do kill -KILL "$p" 2>/dev/null || true; done
  for p in "${ref_pids[@]}" "${poller_pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  if [ -n "$mounted" ]; then
    umount "$mounted" 2>/dev/null || umount -l "$mounted" 2>/dev/null ||
      echo "soak: cannot unmount $mounted" >&2
  fi
  if [ "$keep" = 1 ]; then echo "soak: kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

start_master() {
  "$work/bin/rayfarm-master" "${master_auth[@]}" --worker-endpoint "tcp://127.0.0.1:$wport" \
    --client-endpoint "tcp://127.0.0.1:$cport" --http-endpoint "127.0.0.1:$hport" --data-dir "$work/data" \
    --heartbeat-ms 250 --liveness 4 --checkpoint-interval-ms 1000 --max-queued-jobs 1000 \
    >>"$work/logs/master.log" 2>&1 &
  master_pid=$!
  local i
  for i in $(seq 300); do
    grep -q "master listening" "$work/logs/master.log" 2>/dev/null &&
      [ "$(grep -c 'master listening' "$work/logs/master.log")" -ge "$1" ] && return
    sleep 0.1
  done
  echo "soak: the master did not start" >&2
  exit 1
}
start_worker() {
  local auth=(--insecure)
  [ "$secure" = 0 ] || auth=(--key "$work/keys/own/w$1.key_secret" --master-key "$work/keys/master.key")
  "$work/bin/rayfarm-worker" "${auth[@]}" --master "tcp://127.0.0.1:$wport" --threads 1 \
    --cache-dir "$work/cache-$1" --name "w$1" --heartbeat-ms 250 --liveness 4 \
    --reconnect-max-ms 1000 >>"$work/logs/worker-$1.log" 2>&1 &
  worker_pids[$1]=$!
}

# Job settings: scene, size and the options; job k uses setting k % 5.
prepare_scene() {
  local name=$1
  mkdir -p "$work/scenes/$name"
  cp -r "$repo_root/scenes/$name/." "$work/scenes/$name/"
  python3 - "$work/scenes/$name/scene.json" "$size" <<'EOF'
import json, sys
path, size = sys.argv[1], int(sys.argv[2])
scene = json.load(open(path))
scene["film"] = {"width": size, "height": size}
json.dump(scene, open(path, "w"), indent=2)
EOF
}
prepare_scene cornell-box
prepare_scene embree-cornell
prepare_scene animated-box
settings=(
  "$work/scenes/cornell-box/scene.json|--spp $spp --seed 1"
  "$work/scenes/cornell-box/scene.json|--spp $spp --seed 2 --integrator nee"
  "$work/scenes/embree-cornell/scene.json|--spp $spp --seed 3"
  "$work/scenes/embree-cornell/scene.json|--spp $spp --seed 4 --max-depth 4"
  "$work/scenes/cornell-box/scene.json|--spp $spp --seed 5 --target-error 0.002 --min-passes 2"
)
layout="--tile 16 --pass-spp 16"
# Sequences: frames and options; sequence s uses setting (s - 1) % 3 and seed 10 + s.
seq_scene="$work/scenes/animated-box/scene.json"
seq_settings=(
  "1-48:6|--spp $spp"
  "4-48:6|--spp $spp --integrator nee --target-error 0.02 --min-passes 2"
  "2-47:5|--spp $spp --max-depth 4"
)
declare -a seq_frames seq_opts
frames_total=0
for s in $(seq 1 "$sequences"); do
  IFS='|' read -r range opts <<<"${seq_settings[$(( (s - 1) % 3 ))]}"
  seq_frames[s]=$range
  seq_opts[s]="$opts --seed $((10 + s))"
  # A-B:STEP -> the frame numbers.
  IFS='-:' read -r a b step <<<"$range"
  frames_total=$(( frames_total + ( b - a ) / step + 1 ))
done
frame_list() { local a b step; IFS='-:' read -r a b step <<<"${seq_frames[$1]}"; seq "$a" "$step" "$b"; }

# ------------------------------------------------------------------------------------------------
# --duration: rounds until the time is spent (see the header). Ends the script.
run_duration() {
  [ "$jobs_given" = 1 ] || jobs=5
  [ "$sequences_given" = 1 ] || sequences=1
  local t0 deadline
  t0=$(date +%s)
  deadline=$(( t0 + duration ))
  now() { date +%s; }
  say() { printf 'soak: [%5d s] %s\n' "$(( $(now) - t0 ))" "$*"; }

  # Keys: the master's, one per worker, two clients. --private-jobs makes each client's jobs its own.
  if [ "$do_keys" = 1 ]; then
    secure=1
    mkdir -p "$work/keys/own" "$work/keys/workers" "$work/keys/clients"
    "$rayfarm" keygen -o "$work/keys" --name master >/dev/null
    local w c
    for w in $(seq 1 "$workers"); do
      "$rayfarm" keygen -o "$work/keys/own" --name "w$w" >/dev/null
      cp "$work/keys/own/w$w.key" "$work/keys/workers/"
    done
    for c in alice bob; do
      "$rayfarm" keygen -o "$work/keys/own" --name "$c" >/dev/null
      cp "$work/keys/own/$c.key" "$work/keys/clients/"
    done
    master_auth=(--key "$work/keys/master.key_secret" --worker-keys "$work/keys/workers"
                 --client-keys "$work/keys/clients" --private-jobs)
    clients=(alice bob)
  else
    clients=(plain)
  fi
  nclients=${#clients[@]}

  # The data dir: a small tmpfs of its own, so that it can be filled.
  mkdir -p "$work/data"
  disk_note=""
  if [ "$do_disk" = 1 ]; then
    if [ "$(id -u)" != 0 ]; then
      do_disk=0; disk_note="skipped: not root, so no tmpfs can be mounted"
    elif mount -t tmpfs -o "size=${disk_mb}m,mode=0700" rayfarm-soak "$work/data"; then
      mounted="$work/data"
    else
      do_disk=0; disk_note="skipped: mounting a tmpfs failed"
    fi
    [ -z "$disk_note" ] || echo "soak: the disk-full phase is $disk_note" >&2
  fi

  # References: every job setting, every sequence variant (its frames in one render), the long
  # sequence (scenes/animated-box made --long-frames long, 32x32 at 16 spp).
  declare -gA ref_pid_of=()
  local i v opts scene range
  for i in 0 1 2 3 4; do
    IFS='|' read -r scene opts <<<"${settings[$i]}"
    # shellcheck disable=SC2086
    "$rayfarm" render "$scene" -o "$work/out/ref-$i.exr" --threads 1 $opts $layout \
      >"$work/logs/ref-$i.log" 2>&1 &
    ref_pids+=($!); ref_pid_of[job$i]=$!
  done
  for v in 0 1 2; do
    IFS='|' read -r range opts <<<"${seq_settings[$v]}"
    # shellcheck disable=SC2086
    "$rayfarm" render "$seq_scene" --frames "$range" -o "$work/out/ref-seq$v.####.exr" --threads 1 \
      $opts --seed $((11 + v)) $layout >"$work/logs/ref-seq$v.log" 2>&1 &
    ref_pids+=($!); ref_pid_of[seq$v]=$!
  done
  long_scene="$work/scenes/long-box/scene.json"
  long_opts="--spp 16 --seed 21"
  if [ "$long_frames" -gt 0 ]; then
    mkdir -p "$work/scenes/long-box"
    cp -r "$repo_root/scenes/animated-box/." "$work/scenes/long-box/"
    python3 - "$long_scene" "$long_frames" <<'EOF'
import json, sys
path, frames = sys.argv[1], int(sys.argv[2])
scene = json.load(open(path))
scene["film"] = {"width": 32, "height": 32}
scene["animation"]["frames"] = [1, max(frames, scene["animation"]["frames"][1])]
json.dump(scene, open(path, "w"), indent=2)
EOF
    # shellcheck disable=SC2086
    "$rayfarm" render "$long_scene" --frames "1-$long_frames" -o "$work/out/ref-long.####.exr" \
      --threads 1 $long_opts $layout >"$work/logs/ref-long.log" 2>&1 &
    ref_pids+=($!); ref_pid_of[long]=$!
  fi

  # What was submitted: id -> owner, kind (job, seq, long), setting, round.
  declare -gA item_own item_kind item_ref round_of frames_of
  n_jobs=0; n_seqs=0; n_long=0; n_frames=0
  declare -gA by_owner=()
  unexpected_refusals=0
  submit() {  # submit CLIENT KIND SETTING NAME ARGS...: records the id in $sub_id, "" if refused
    local c=$1 k=$2 st=$3 name=$4 out
    shift 4
    sub_id=""
    if out=$(rf "$c" submit "$@" $layout --name "$name" --timeout 60 2>"$work/out/submit-$name.err"); then
      sub_id=$(head -n1 <<<"$out")
      item_own[$sub_id]=$c; item_kind[$sub_id]=$k; item_ref[$sub_id]=$st; round_of[$sub_id]=$round
      by_owner[$c]=$(( ${by_owner[$c]:-0} + 1 ))
      return 0
    fi
    return 1
  }
  rf() {  # rf CLIENT ARGS...: the CLI as that client
    local c=$1
    shift
    if [ "$secure" = 1 ]; then
      RAYFARM_KEY="$work/keys/own/$c.key_secret" RAYFARM_MASTER_KEY="$work/keys/master.key" "$rayfarm" "$@"
    else
      "$rayfarm" "$@" --insecure
    fi
  }

  # Events.
  kills=0; freezes=0; events=0; frozen=""; thaw_at=0
  next_kill=$(( $(now) + kill_every ))
  tick_workers() {
    local w
    if [ -n "$frozen" ] && [ "$(now)" -ge "$thaw_at" ]; then
      kill -CONT "${worker_pids[$frozen]}" 2>/dev/null || true
      frozen=""
    fi
    [ "$do_kills" = 1 ] || [ "$do_freezes" = 1 ] || return 0
    [ "$(now)" -ge "$next_kill" ] || return 0
    next_kill=$(( $(now) + kill_every ))
    w=$(( RANDOM % workers + 1 ))
    events=$((events + 1))
    if [ "$do_kills" = 1 ] && { [ "$do_freezes" = 0 ] || [ $((events % 2)) = 1 ] || [ -n "$frozen" ]; }; then
      [ "$w" = "$frozen" ] && { kill -CONT "${worker_pids[$w]}" 2>/dev/null || true; frozen=""; }
      kill -KILL "${worker_pids[$w]}" 2>/dev/null || true
      wait "${worker_pids[$w]}" 2>/dev/null || true
      kills=$((kills + 1))
      start_worker "$w"
    elif [ -z "$frozen" ]; then
      kill -STOP "${worker_pids[$w]}" 2>/dev/null || true
      frozen=$w
      thaw_at=$(( $(now) + 2 ))
      freezes=$((freezes + 1))
    fi
  }
  master_starts=0
  restarts_kill=0; restarts_term=0; term_slow=0; term_rc_bad=0
  restart_master() {  # restart_master KILL|TERM
    local sig=$1 i rc=0
    kill "-$sig" "$master_pid" 2>/dev/null || true
    for i in $(seq 600); do kill -0 "$master_pid" 2>/dev/null || break; sleep 0.1; done
    if kill -0 "$master_pid" 2>/dev/null; then
      say "the master did not stop within 60 s of SIGTERM: killed (see logs/master.log)"
      term_slow=$((term_slow + 1))
      kill -KILL "$master_pid" 2>/dev/null || true
    fi
    wait "$master_pid" 2>/dev/null || rc=$?
    if [ "$sig" = TERM ]; then
      restarts_term=$((restarts_term + 1))
      [ "$rc" = 0 ] || { term_rc_bad=$((term_rc_bad + 1)); say "the master exited $rc after SIGTERM"; }
    else
      restarts_kill=$((restarts_kill + 1))
    fi
    master_starts=$((master_starts + 1))
    start_master "$master_starts"
  }
  disk_episodes=0; disk_refused=0; disk_accepted=0; full_until=0
  fill_disk() { cat /dev/zero >>"$work/data/filler" 2>/dev/null || true; }
  start_disk_full() {
    fill_disk
    full_until=$(( $(now) + disk_full_seconds ))
    disk_episodes=$((disk_episodes + 1))
    say "disk full: $(df -m --output=used,size "$work/data" | tail -n1 | awk '{print $1 " of " $2 " MB used"}')"
    # A submission now must be refused; one accepted must be kept and finished like any other.
    local c=${clients[$((round % nclients))]} sc so
    IFS='|' read -r sc so <<<"${settings[0]}"
    # shellcheck disable=SC2086
    if submit "$c" job 0 "soak-r$round-full" "$sc" $so; then
      disk_accepted=$((disk_accepted + 1)); round_ids+=("$sub_id"); n_jobs=$((n_jobs + 1))
      say "a submission on the full disk was accepted ($sub_id): it must finish"
    else
      disk_refused=$((disk_refused + 1))
      say "a submission on the full disk was refused: $(tail -n1 "$work/out/submit-soak-r$round-full.err")"
    fi
  }
  tick_disk() {
    [ "$full_until" -gt 0 ] || return 0
    if [ "$(now)" -ge "$full_until" ]; then
      rm -f "$work/data/filler"
      full_until=0
      say "disk freed"
    else
      fill_disk   # what the master freed meanwhile (a failed temporary file) is taken again
    fi
  }

  # Finished (done, failed or cancelled) jobs and sequences, as their owners list them.
  finished_now() {
    local c
    for c in "${clients[@]}"; do
      rf "$c" list --timeout 5 2>/dev/null || true
    done | awk '$1 ~ /^j[0-9]+$/ && / (done|failed|cancelled) / {print $1}'
  }

  # Privacy: no key sees another's job, by list, status or the HTTP API; anonymous HTTP sees none.
  privacy_checks=0; privacy_violations=0
  declare -gA token=()
  check_privacy() {
    [ "$secure" = 1 ] || return 0
    local c other id l ids body any=0
    for c in alice bob; do
      other=$([ "$c" = alice ] && echo bob || echo alice)
      l=$(rf "$c" list --timeout 5 2>/dev/null) || return 1
      ids=$(awk '$1 ~ /^j[0-9]+$/ {print $1}' <<<"$l")
      body=$(curl -s --max-time 10 -H "Authorization: Bearer ${token[$c]}" "http://127.0.0.1:$hport/api/jobs") || return 1
      ids="$ids $(grep -oE '"j[0-9]{4,}"' <<<"$body" | tr -d '"' || true)"
      for id in $ids; do
        if [ "${item_own[$id]:-$c}" != "$c" ]; then
          say "PRIVACY: $c sees $id, a job of ${item_own[$id]}"; privacy_violations=$((privacy_violations + 1))
        fi
      done
      for id in "${!item_own[@]}"; do
        [ "${item_own[$id]}" = "$other" ] && [ "${round_of[$id]}" = "$round" ] || continue
        any=1
        if rf "$c" status "$id" --timeout 5 >/dev/null 2>"$work/out/privacy.err"; then
          say "PRIVACY: $c gets the status of $id, a job of $other"; privacy_violations=$((privacy_violations + 1))
        elif ! grep -q "unknown job" "$work/out/privacy.err"; then
          say "privacy: status of $other's $id as $c: $(tail -n1 "$work/out/privacy.err")"
        fi
        break
      done
    done
    body=$(curl -s --max-time 10 "http://127.0.0.1:$hport/api/jobs") || return 1
    if grep -qE '"j[0-9]{4,}"' <<<"$body"; then
      say "PRIVACY: the anonymous /api/jobs shows jobs: ${body:0:200}"; privacy_violations=$((privacy_violations + 1))
    fi
    privacy_checks=$((privacy_checks + 1))
    [ "$any" = 1 ] || say "privacy: no job of the other key to ask about this round"
    return 0
  }

  # HTTP pollers: a bounded rate of requests against the dashboard's API, /metrics and images.
  poller() {
    local n=$1 tok=$2 path id code k=0
    local auth=()
    local paths=(/api/jobs /api/workers /metrics image)
    [ -z "$tok" ] || auth=(-H "Authorization: Bearer $tok")
    trap 'exit 0' TERM
    while [ ! -e "$work/stop-pollers" ]; do
      path=${paths[$((k % 4))]}
      k=$((k + 1))
      if [ "$path" = image ]; then
        id=$(grep -oE '"j[0-9]{4,}"' "$work/logs/http-$n.body" 2>/dev/null | tr -d '"' | shuf -n1 || true)
        if [ -n "$id" ]; then path="/api/jobs/$id/image.png"; else path=/api/session; fi
      fi
      code=$(curl -s -o "$work/logs/http-$n.tmp" -w '%{http_code}' --max-time 10 "${auth[@]}" \
               "http://127.0.0.1:$hport$path" 2>/dev/null || true)
      [ "$path" != /api/jobs ] || mv -f "$work/logs/http-$n.tmp" "$work/logs/http-$n.body" 2>/dev/null || true
      echo "$(date +%s) ${code:-000} $path" >>"$work/logs/http-$n.log"
      sleep "$poll_interval"
    done
  }

  # RSS of the master after each round.
  declare -ga rss_kb=()
  rss_now() { awk '/^VmRSS/ {print $2}' "/proc/$master_pid/status" 2>/dev/null || echo 0; }

  # Checks, once a job or sequence is finished: every image against its reference, then removed.
  checked=0; identical=0; differing=0; lost=0; frames_checked=0
  # Waits once for a reference render; then forgets its PID, which the system reuses in a long
  # soak (a live process of that PID would hold every later check for 10 minutes).
  wait_ref() {
    local p=${ref_pid_of[$1]:-} i
    [ -n "$p" ] || return 0
    for i in $(seq 1200); do kill -0 "$p" 2>/dev/null || break; sleep 0.5; done
    ref_pid_of[$1]=""
  }
  check_image() {  # check_image WHAT OUT REF
    checked=$((checked + 1))
    if [ ! -s "$2" ]; then
      say "LOST: $1 is not done or cannot be fetched"; lost=$((lost + 1))
    elif [ ! -s "$3" ]; then
      say "LOST: $1 has no reference ($3)"; lost=$((lost + 1))
    elif "$rayfarm" compare "$2" "$3" >/dev/null 2>&1; then
      identical=$((identical + 1))
    else
      say "DIFFERS: $1 differs from its reference"; differing=$((differing + 1))
    fi
  }
  verify() {
    local id=$1 c=${item_own[$1]} k=${item_kind[$1]} st=${item_ref[$1]} n f prefix status
    case $k in
      job)
        wait_ref "job$st"
        status=$(rf "$c" status "$id" --timeout 10 2>&1 | head -n 3 || true)
        rm -f "$work/out/$id.exr"
        if grep -q "done" <<<"$status"; then
          rf "$c" fetch "$id" -o "$work/out/$id.exr" --timeout 30 >/dev/null 2>&1 || true
        else
          say "job $id is not done: $(tr '\n' ' ' <<<"$status")"
        fi
        check_image "job $id ($c)" "$work/out/$id.exr" "$work/out/ref-$st.exr"
        ;;
      seq|long)
        if [ "$k" = long ]; then wait_ref long; prefix="$work/out/ref-long"
        else wait_ref "seq$st"; prefix="$work/out/ref-seq$st"; fi
        mkdir -p "$work/out/$id"
        rf "$c" fetch "$id" --all -o "$work/out/$id/frame.####.exr" --timeout 60 \
          >"$work/out/$id/fetch.out" 2>&1 || say "sequence $id: fetch --all: $(tail -n1 "$work/out/$id/fetch.out")"
        for n in ${frames_of[$id]}; do
          f=$(printf %04d "$n")
          check_image "frame $n of $id ($c)" "$work/out/$id/frame.$f.exr" "$prefix.$f.exr"
          frames_checked=$((frames_checked + 1))
        done
        ;;
    esac
    rf "$c" rm "$id" --timeout 10 >/dev/null 2>&1 || say "cannot remove $id: $(rf "$c" rm "$id" --timeout 10 2>&1 | tail -n1)"
    unset "item_own[$id]" "item_kind[$id]" "item_ref[$id]" "round_of[$id]" "frames_of[$id]"
    rm -rf "$work/out/$id" "$work/out/$id.exr" "$work/out/$id.png"
  }

  # wait_round EVENT_AT EVENT DRAIN: waits until every id in round_ids (and the round's event; with
  # DRAIN 1, the long sequence too) is finished, ticking the events; then checks them. The long
  # sequence is checked in whichever round it finishes.
  wait_round() {
    local limit=$(( $(now) + timeout )) fin id pending event_at=$1 event=$2 drain=$3 privacy_done=0
    while :; do
      sleep 1
      tick_workers
      tick_disk
      if [ -n "$event" ] && [ "$(now)" -ge "$event_at" ]; then
        case $event in
          kill) say "master killed (SIGKILL)"; restart_master KILL ;;
          term) say "master stopped (SIGTERM)"; restart_master TERM ;;
          disk) start_disk_full ;;
        esac
        event=""
      fi
      [ "$privacy_done" = 1 ] || { check_privacy && privacy_done=1; }
      fin=$(finished_now)
      pending=0
      for id in "${round_ids[@]}"; do grep -qx "$id" <<<"$fin" || pending=$((pending + 1)); done
      if [ -n "$long_id" ] && grep -qx "$long_id" <<<"$fin"; then
        say "the long sequence $long_id is finished: checking its $long_frames frames"
        verify "$long_id"; long_id=""
      fi
      if [ "$pending" = 0 ] && [ -z "$event" ] && [ "$full_until" = 0 ]; then
        [ "$drain" = 1 ] && [ -n "$long_id" ] || break
      fi
      if [ "$(now)" -ge "$limit" ]; then
        say "round $round: $pending jobs not finished after $timeout s"
        break
      fi
    done
    [ "$full_until" = 0 ] || { rm -f "$work/data/filler"; full_until=0; }
    [ -z "$frozen" ] || { kill -CONT "${worker_pids[$frozen]}" 2>/dev/null || true; frozen=""; }
    for id in "${round_ids[@]}"; do verify "$id"; done
  }

  start=$(date +%s.%N)
  master_starts=1
  start_master 1
  for w in $(seq 1 "$workers"); do start_worker "$w"; done
  for c in "${clients[@]}"; do
    token[$c]=$(rf "$c" token --timeout 30 2>/dev/null | head -n1 || true)
  done
  : >"$work/logs/http-0.log"
  local p
  for p in $(seq 1 "$pollers"); do
    local tok=""
    # Each client's token in turn; the last of several pollers reads anonymously.
    if [ "$secure" = 1 ] && { [ "$p" -lt "$pollers" ] || [ "$pollers" = 1 ]; }; then
      tok=${token[${clients[$(( (p - 1) % nclients ))]}]}
    fi
    poller "$p" "$tok" &
    poller_pids+=($!)
  done

  local kinds=(quiet kill disk term) ev jn=0 sn=0 k name sc so a b step
  declare -gA kind_count=()
  long_id=""
  round=0
  while [ "$(now)" -lt "$deadline" ]; do
    round=$((round + 1))
    ev=${kinds[$(( (round - 1) % 4 ))]}
    { [ "$ev" = kill ] || [ "$ev" = term ]; } && [ "$do_restarts" = 0 ] && ev=quiet
    [ "$ev" = disk ] && [ "$do_disk" = 0 ] && ev=quiet
    kind_count[$ev]=$(( ${kind_count[$ev]:-0} + 1 ))
    local rstart
    rstart=$(now)
    round_ids=()
    for k in $(seq 1 "$jobs"); do
      c=${clients[$((jn % nclients))]}
      i=$((jn % 5)); jn=$((jn + 1))
      IFS='|' read -r sc so <<<"${settings[$i]}"
      # shellcheck disable=SC2086
      if submit "$c" job "$i" "soak-r$round-$k" "$sc" $so; then
        round_ids+=("$sub_id"); n_jobs=$((n_jobs + 1))
      else
        unexpected_refusals=$((unexpected_refusals + 1))
        say "submission refused: $(tail -n1 "$work/out/submit-soak-r$round-$k.err")"
      fi
    done
    for k in $(seq 1 "$sequences"); do
      c=${clients[$(( (sn + 1) % nclients ))]}
      v=$((sn % 3)); sn=$((sn + 1))
      IFS='|' read -r range so <<<"${seq_settings[$v]}"
      # shellcheck disable=SC2086
      if submit "$c" seq "$v" "soak-r$round-seq$k" "$seq_scene" --frames "$range" $so --seed $((11 + v)); then
        round_ids+=("$sub_id"); n_seqs=$((n_seqs + 1))
        IFS='-:' read -r a b step <<<"$range"
        frames_of[$sub_id]=$(seq "$a" "$step" "$b" | tr '\n' ' ')
        n_frames=$(( n_frames + (b - a) / step + 1 ))
      else
        unexpected_refusals=$((unexpected_refusals + 1))
        say "submission refused: $(tail -n1 "$work/out/submit-soak-r$round-seq$k.err")"
      fi
    done
    if [ "$round" = 1 ] && [ "$long_frames" -gt 0 ]; then
      c=${clients[$((1 % nclients))]}
      # shellcheck disable=SC2086
      if submit "$c" long 0 soak-long "$long_scene" --frames "1-$long_frames" $long_opts; then
        long_id=$sub_id; n_long=1; n_frames=$((n_frames + long_frames))
        frames_of[$sub_id]=$(seq 1 "$long_frames" | tr '\n' ' ')
        say "long sequence $long_id submitted by $c: $long_frames frames of 32x32 at 16 spp"
      else
        unexpected_refusals=$((unexpected_refusals + 1))
        say "the long sequence was refused: $(tail -n1 "$work/out/submit-soak-long.err")"
      fi
    fi
    say "round $round ($ev): ${#round_ids[@]} submitted (${round_ids[*]})"
    if [ "$ev" = quiet ]; then
      wait_round 0 "" 0
    else
      wait_round $(( $(now) + 2 + RANDOM % 4 )) "$ev" 0
    fi
    rss_kb+=("$(rss_now)")
    say "round $round ($ev) done in $(( $(now) - rstart )) s; checked so far $checked (identical $identical, differing $differing, lost $lost); master RSS $(awk -v k="${rss_kb[-1]}" 'BEGIN {printf "%.1f", k / 1024}') MB"
  done
  # The long sequence, if it is still running.
  if [ -n "$long_id" ]; then
    say "time is up: waiting for the long sequence $long_id"
    round_ids=()
    wait_round 0 "" 1
    if [ -n "$long_id" ]; then
      say "LOST: the long sequence $long_id did not finish"
      verify "$long_id"
    fi
    rss_kb+=("$(rss_now)")
  fi
  end=$(date +%s.%N)

  touch "$work/stop-pollers"
  for p in "${poller_pids[@]}"; do wait "$p" 2>/dev/null || true; done
  poller_pids=()

  # Figures.
  local log="$work/logs/master.log" first max last r http_total http_5xx http_500 http_000 http_404 http_2xx codes
  count() { grep -c -- "$1" "$log" || true; }
  first=${rss_kb[0]}; max=$first; last=${rss_kb[-1]}
  for r in "${rss_kb[@]}"; do [ "$r" -le "$max" ] || max=$r; done
  rss_flat=1
  [ $(( max - first )) -le $(( rss_bound_mb * 1024 )) ] || rss_flat=0
  cat "$work"/logs/http-[0-9]*.log >"$work/logs/http-all.log" 2>/dev/null || true
  http_total=$(wc -l <"$work/logs/http-all.log")
  http_2xx=$(awk '$2 ~ /^2/' "$work/logs/http-all.log" | wc -l)
  http_404=$(awk '$2 == 404' "$work/logs/http-all.log" | wc -l)
  http_5xx=$(awk '$2 ~ /^5/' "$work/logs/http-all.log" | wc -l)
  http_500=$(awk '$2 == 500' "$work/logs/http-all.log" | wc -l)
  http_000=$(awk '$2 == "000"' "$work/logs/http-all.log" | wc -l)
  codes=$(awk '{n[$2]++} END {for (c in n) printf "%s %d, ", c, n[c]}' "$work/logs/http-all.log" | sed 's/, $//')
  requeued=$({ grep -o 'requeued [0-9]* unit' "$log" || true; } | awk '{s += $2} END {print s + 0}')
  mb() { awk -v k="$1" 'BEGIN {printf "%.1f", k / 1024}'; }
  local per_round="" result=PASS
  for r in "${rss_kb[@]}"; do per_round="$per_round $(mb "$r")"; done
  if [ "$lost" != 0 ] || [ "$differing" != 0 ] || [ "$rss_flat" = 0 ] || [ "$privacy_violations" != 0 ] ||
     [ "$http_500" != 0 ] || [ "$checked" = 0 ]; then result=FAIL; fi

  printf 'soak summary (%s)\n' "$(date -u +%Y-%m-%dT%H:%MZ)"
  printf '  duration              %d s asked, %.0f s run; %d rounds (%d quiet, %d master SIGKILL, %d disk full, %d master SIGTERM)\n' \
    "$duration" "$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }')" "$round" \
    "${kind_count[quiet]:-0}" "${kind_count[kill]:-0}" "${kind_count[disk]:-0}" "${kind_count[term]:-0}"
  printf '  submitted             %d jobs, %d sequences, %d long sequence; %d frames (%s)\n' "$n_jobs" "$n_seqs" "$n_long" "$n_frames" \
    "$(for c in "${clients[@]}"; do printf '%s %d ' "$c" "${by_owner[$c]:-0}"; done | sed 's/ $//')"
  printf '  images checked        %d (%d jobs, %d frames): %d identical, %d differing, %d lost\n' \
    "$checked" "$((checked - frames_checked))" "$frames_checked" "$identical" "$differing" "$lost"
  printf '  workers               %d x 1 thread; %d killed (SIGKILL) and restarted, %d frozen 2 s (SIGSTOP)\n' "$workers" "$kills" "$freezes"
  printf '  master restarts       %d (%d SIGKILL, %d SIGTERM; %d slow to stop, %d exits not 0)\n' \
    "$((restarts_kill + restarts_term))" "$restarts_kill" "$restarts_term" "$term_slow" "$term_rc_bad"
  if [ -n "$disk_note" ]; then
    printf '  disk full             %s\n' "$disk_note"
  else
    printf '  disk full             %d episodes of %d s on a %d MB tmpfs; submissions meanwhile %d refused, %d accepted; %d storage errors logged\n' \
      "$disk_episodes" "$disk_full_seconds" "$disk_mb" "$disk_refused" "$disk_accepted" "$(count 'No space left')"
  fi
  if [ "$secure" = 1 ]; then
    printf '  keys, private jobs    CURVE, 2 client keys; %d checks (list, status, /api/jobs per key, anonymous), %d violations\n' "$privacy_checks" "$privacy_violations"
  fi
  printf '  HTTP                  %d requests by %d pollers: %d 2xx, %d 404, %d 5xx (%d of them 500), %d unanswered (master down); codes: %s\n' \
    "$http_total" "$pollers" "$http_2xx" "$http_404" "$http_5xx" "$http_500" "$http_000" "${codes:-none}"
  printf '  master RSS            first %s MB, max %s MB, last %s MB (bound: first + %d MB); per round:%s\n' \
    "$(mb "$first")" "$(mb "$max")" "$(mb "$last")" "$rss_bound_mb" "$per_round"
  printf '  jobs resumed          %d from a checkpoint, %d from the start, %d queued again\n' "$(count 'resumed from checkpoint at')" "$(count 'restarted from the beginning')" "$(count 'queued again')"
  printf '  duplicates dropped    %d; units requeued %d; stragglers %d; checkpoints unusable %d\n' \
    "$(count 'duplicate result')" "$requeued" "$(count 'is a straggler')" "$(count 'cannot use checkpoint')"
  [ "$unexpected_refusals" = 0 ] || printf '  refused submissions   %d (not while the disk was full)\n' "$unexpected_refusals"
  printf '  lost                  %d\n' "$lost"
  printf '  result                %s\n' "$result"
  [ "$result" = PASS ]
}
if [ -n "$duration" ]; then
  run_duration && exit 0
  exit 1
fi

start=$(date +%s.%N)
start_master 1
for w in $(seq 1 "$workers"); do start_worker "$w"; done

# Submit every job at once.
declare -a sub_pids
for k in $(seq 1 "$jobs"); do
  IFS='|' read -r scene opts <<<"${settings[$(( (k - 1) % 5 ))]}"
  # shellcheck disable=SC2086
  "$rayfarm" submit "$scene" $opts $layout --name "soak-$k" --timeout 60 --insecure \
    >"$work/out/submit-$k.out" 2>"$work/out/submit-$k.err" &
  sub_pids+=($!)
done
for s in $(seq 1 "$sequences"); do
  # shellcheck disable=SC2086
  "$rayfarm" submit "$seq_scene" --frames "${seq_frames[s]}" ${seq_opts[s]} $layout \
    --name "soak-seq-$s" --timeout 60 --insecure \
    >"$work/out/seq-submit-$s.out" 2>"$work/out/seq-submit-$s.err" &
  sub_pids+=($!)
done
for p in "${sub_pids[@]}"; do wait "$p" || { echo "soak: a submission failed" >&2; cat "$work/out"/*submit-*.err >&2; exit 1; }; done
submitted=$(cat "$work/out"/submit-*.out | grep -c '^j[0-9]')
echo "soak: $submitted jobs submitted"
if [ "$sequences" -gt 0 ]; then
  echo "soak: $(cat "$work/out"/seq-submit-*.out | grep -c '^j[0-9]') sequences submitted ($frames_total frames)"
fi

# References, while the farm works (they share the machine, which only slows things down).
for i in 0 1 2 3 4; do
  IFS='|' read -r scene opts <<<"${settings[$i]}"
  # shellcheck disable=SC2086
  "$rayfarm" render "$scene" -o "$work/out/ref-$i.exr" --threads 1 $opts $layout \
    >"$work/logs/ref-$i.log" 2>&1 &
  ref_pids+=($!)
done
# A sequence's references, one frame after the other (killed with the subshell on exit).
render_frames() {
  local s=$1 n child=""
  trap '[ -z "$child" ] || kill -KILL "$child" 2>/dev/null; exit 1' TERM
  for n in $(frame_list "$s"); do
    # shellcheck disable=SC2086
    "$rayfarm" render "$seq_scene" --frame "$n" -o "$work/out/ref-seq-$s.$(printf %04d "$n").exr" \
      --threads 1 ${seq_opts[s]} $layout >>"$work/logs/ref-seq-$s.log" 2>&1 &
    child=$!
    wait "$child" || echo "soak: reference of frame $n of sequence $s failed" >>"$work/logs/ref-seq-$s.log"
  done
}
for s in $(seq 1 "$sequences"); do
  render_frames "$s" &
  ref_pids+=($!)
done

units_total=$(( jobs * (size / 16) * (size / 16) * (spp / 16) ))
units_frames=$(( frames_total * (size / 16) * (size / 16) * (spp / 16) ))
kills=0
freezes=0
events=0
frozen=""
thaw_at=0
restarts=0
phase=0
next_kill=$(( $(date +%s) + kill_every ))
deadline=$(( $(date +%s) + timeout ))
while :; do
  sleep 0.5
  list=$("$rayfarm" list --timeout 5 --insecure 2>/dev/null || true)
  # A sequence is one line of the list, its frames done / total in the SPP column ("3/8 fr").
  read -r done_jobs done_seqs frames_done < <(awk '
    $1 ~ /^j[0-9]+$/ { seq = 0
      for (i = 2; i <= NF; i++) if ($i == "fr") { seq = 1; split($(i - 1), f, "/"); frames += f[1] }
      if (/ done /) { if (seq) seqs++; else stills++ } }
    END { print stills + 0, seqs + 0, frames + 0 }' <<<"$list")
  [ "$done_jobs" -ge "$jobs" ] && [ "$done_seqs" -ge "$sequences" ] && break
  if [ "$(date +%s)" -ge "$deadline" ]; then echo "soak: timeout" >&2; break; fi
  # Units merged so far, from the master's pass lines is too coarse: use the share of the done
  # jobs and frames (a frame is as many units as a job).
  merged_share=$(( (done_jobs + frames_done) * 3 / (jobs + frames_total) ))
  done_note=""
  [ "$sequences" -gt 0 ] && done_note=" and $frames_done of $frames_total frames"
  if [ "$phase" = 0 ] && [ "$merged_share" -ge 1 ]; then
    echo "soak: master killed (SIGKILL) with $done_jobs jobs$done_note done"
    kill -KILL "$master_pid"; wait "$master_pid" 2>/dev/null || true
    restarts=$((restarts + 1)); phase=1
    start_master $((restarts + 1))
  elif [ "$phase" = 1 ] && [ "$merged_share" -ge 2 ]; then
    echo "soak: master stopped (SIGTERM) with $done_jobs jobs$done_note done"
    kill -TERM "$master_pid"; wait "$master_pid" 2>/dev/null || true
    restarts=$((restarts + 1)); phase=2
    start_master $((restarts + 1))
  fi
  if [ -n "$frozen" ] && [ "$(date +%s)" -ge "$thaw_at" ]; then
    kill -CONT "${worker_pids[$frozen]}" 2>/dev/null || true
    frozen=""
  fi
  if [ "$(date +%s)" -ge "$next_kill" ]; then
    w=$(( RANDOM % workers + 1 ))
    events=$((events + 1))
    if [ $((events % 2)) = 1 ] || [ -n "$frozen" ]; then
      [ "$w" = "$frozen" ] && { kill -CONT "${worker_pids[$w]}" 2>/dev/null || true; frozen=""; }
      kill -KILL "${worker_pids[$w]}" 2>/dev/null || true
      wait "${worker_pids[$w]}" 2>/dev/null || true
      kills=$((kills + 1))
      start_worker "$w"
    else
      kill -STOP "${worker_pids[$w]}" 2>/dev/null || true
      frozen=$w
      thaw_at=$(( $(date +%s) + 2 ))
      freezes=$((freezes + 1))
    fi
    next_kill=$(( $(date +%s) + kill_every ))
  fi
done
[ -n "$frozen" ] && kill -CONT "${worker_pids[$frozen]}" 2>/dev/null || true
end=$(date +%s.%N)
wait_refs=0
for i in 0 1 2 3 4; do
  while [ ! -s "$work/out/ref-$i.exr" ] && [ $wait_refs -lt 600 ]; do sleep 0.5; wait_refs=$((wait_refs + 1)); done
done
for s in $(seq 1 "$sequences"); do
  for n in $(frame_list "$s"); do
    ref="$work/out/ref-seq-$s.$(printf %04d "$n").exr"
    while [ ! -s "$ref" ] && [ $wait_refs -lt 600 ]; do sleep 0.5; wait_refs=$((wait_refs + 1)); done
  done
done
sleep 1

# Every job: done, and bit-identical to its reference.
lost=0
identical=0
for k in $(seq 1 "$jobs"); do
  id=$(head -n1 "$work/out/submit-$k.out")
  i=$(( (k - 1) % 5 ))
  if ! "$rayfarm" fetch "$id" -o "$work/out/$id.exr" --timeout 30 --insecure >/dev/null 2>&1; then
    echo "soak: job $id ($k) cannot be fetched" >&2; lost=$((lost + 1)); continue
  fi
  state=$("$rayfarm" status "$id" --timeout 10 --insecure 2>/dev/null | head -n 3 || true)
  if ! grep -q "done" <<<"$state"; then
    echo "soak: job $id is not done: $state" >&2; lost=$((lost + 1)); continue
  fi
  if "$rayfarm" compare "$work/out/$id.exr" "$work/out/ref-$i.exr" >/dev/null 2>&1; then
    identical=$((identical + 1))
  else
    echo "soak: job $id differs from its reference" >&2; lost=$((lost + 1))
  fi
done

# Every frame of every sequence: done, and bit-identical to `rayfarm render --frame N`.
frames_identical=0
for s in $(seq 1 "$sequences"); do
  id=$(head -n1 "$work/out/seq-submit-$s.out")
  mkdir -p "$work/out/$id"
  "$rayfarm" status "$id" --json --timeout 10 --insecure >"$work/out/$id/status.json" 2>/dev/null || true
  if ! "$rayfarm" fetch "$id" --all -o "$work/out/$id/frame.####.exr" --timeout 30 --insecure \
      >"$work/out/$id/fetch.out" 2>&1; then
    echo "soak: sequence $id ($s): fetch --all failed: $(tail -n1 "$work/out/$id/fetch.out")" >&2
  fi
  # frames_done/frames_total and the frames not done, from the master.
  summary=$(python3 - "$work/out/$id/status.json" <<'EOF'
import json, sys
try:
    j = json.loads(open(sys.argv[1]).readline())
    rest = ["%d:%s" % (f["frame"], f["state"]) for f in j["frames"] if f["state"] != "done"]
    print(j["frames_done"], j["frames_total"], " ".join(rest))
except (OSError, ValueError, KeyError, TypeError):
    print("? ? (no status)")
EOF
)
  read -r fdone ftotal fnotdone <<<"$summary"
  expected=$(frame_list "$s" | wc -l)
  if [ "$ftotal" != "$expected" ]; then
    echo "soak: sequence $id ($s) has $ftotal frames, $expected submitted" >&2
  fi
  if [ "$fdone" != "$ftotal" ]; then
    echo "soak: sequence $id ($s): $fdone of $ftotal frames done; not done: $fnotdone" >&2
  fi
  for n in $(frame_list "$s"); do
    f=$(printf %04d "$n")
    out="$work/out/$id/frame.$f.exr"
    ref="$work/out/ref-seq-$s.$f.exr"
    if [ ! -s "$out" ]; then
      echo "soak: frame $n of $id ($id.$f) is not done or cannot be fetched" >&2; lost=$((lost + 1))
    elif [ ! -s "$ref" ]; then
      echo "soak: frame $n of $id has no reference (logs/ref-seq-$s.log)" >&2; lost=$((lost + 1))
    elif "$rayfarm" compare "$out" "$ref" >/dev/null 2>&1; then
      frames_identical=$((frames_identical + 1))
    else
      echo "soak: frame $n of $id ($id.$f) differs from rayfarm render --frame $n" >&2
      lost=$((lost + 1))
    fi
  done
done

log="$work/logs/master.log"
count() { grep -c -- "$1" "$log" || true; }
requeued=$({ grep -o 'requeued [0-9]* unit' "$log" || true; } | awk '{s += $2} END {print s + 0}')
printf 'soak figures (%s)\n' "$(date -u +%Y-%m-%dT%H:%MZ)"
printf '  jobs                  %d submitted, %d done and bit-identical to rayfarm render\n' "$jobs" "$identical"
if [ "$sequences" -gt 0 ]; then
  printf '  sequences             %d submitted, %d frames; %d frames done and bit-identical to rayfarm render --frame N\n' "$sequences" "$frames_total" "$frames_identical"
  printf '  units                 %d (%d in frames; the target-error jobs and frames need fewer)\n' "$((units_total + units_frames))" "$units_frames"
else
  printf '  units                 %d (the target-error jobs need fewer)\n' "$units_total"
fi
printf '  workers               %d x 1 thread; %d killed with SIGKILL and restarted, %d frozen 2 s with SIGSTOP\n' "$workers" "$kills" "$freezes"
printf '  master restarts       %d (one SIGKILL, one SIGTERM)\n' "$restarts"
printf '  jobs resumed          %d from a checkpoint, %d from the start (running, no checkpoint yet), %d queued again\n' "$(count 'resumed from checkpoint at')" "$(count 'restarted from the beginning')" "$(count 'queued again')"
printf '  checkpoints unusable  %d\n' "$(count 'cannot use checkpoint')"
printf '  duplicates dropped    %d\n' "$(count 'duplicate result')"
printf '  units requeued        %d\n' "$requeued"
printf '  stragglers            %d\n' "$(count 'is a straggler')"
printf '  lost                  %d\n' "$lost"
printf '  wall time             %.1f s\n' "$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }')"
[ "$lost" = 0 ]
