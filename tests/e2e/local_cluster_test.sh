#!/usr/bin/env bash
# deploy/local-cluster started and stopped over and over, and made to fail:
#   1. CYCLES start/stop cycles (under CPU load with --load): every start exits 0, prints the line
#      to source and writes env; the CLI reaches the master through env; every stop ends every
#      recorded process and leaves no pid file.
#   2. The master killed while start waits for it: start exits 1 naming the master, its PID and
#      SIGKILL, and leaves nothing running or recorded; the next start works.
#   3. A master that exits by itself (a bad option): start names its exit code and its log.
#   4. What a start cut short leaves running (pid files and env gone): start refuses, naming the
#      processes and `stop`; stop ends them; the next start works.
#
#   tests/e2e/local_cluster_test.sh [--cycles N] [--load] [--only-cycles]
#
# Binaries from $RAYFARM_BIN (a build folder), else build/ of this repository. Any free ports are
# used (--free-ports); every process started is ended by PID, also on failure.
# `tests/e2e/local_cluster_test.sh --cycles 100 --load --only-cycles` is the long run.
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
script="$repo_root/deploy/local-cluster"
export RAYFARM_BIN=${RAYFARM_BIN:-$repo_root/build}
cycles=20
load=0
only_cycles=0
while [ $# -gt 0 ]; do
  case $1 in
    --cycles) cycles=${2:?--cycles needs a number}; shift 2 ;;
    --load) load=1; shift ;;
    --only-cycles) only_cycles=1; shift ;;
    *) echo "usage: $0 [--cycles N] [--load] [--only-cycles]" >&2; exit 2 ;;
  esac
done

tmp=$(mktemp -d "${TMPDIR:-/tmp}/rayfarm-local-cluster.XXXXXX")
load_pids=()
failures=0

cleanup() {
  local pid d
  for d in "$tmp"/c*; do
    [ -d "$d" ] && RAYFARM_BIN="$RAYFARM_BIN" "$script" stop --dir "$d" >/dev/null 2>&1 || true
  done
  for pid in "${load_pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  rm -rf "$tmp"
}
trap cleanup EXIT

fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}

# gone PID: the process has ended (a zombie counts as ended).
gone() {
  local stat=
  kill -0 "$1" 2>/dev/null || return 0
  IFS= read -r stat 2>/dev/null <"/proc/$1/stat" || return 0
  stat=${stat##*) }
  [ "${stat:0:1}" = Z ]
}

# The PIDs recorded in DIR's pid files.
recorded_pids() { cat "$1"/*.pid 2>/dev/null || true; }

# rayfarm list against the cluster in DIR, through its env file.
list_jobs() {
  (
    # shellcheck source=/dev/null
    source "$1/env"
    "$RAYFARM_BIN/cli/rayfarm" list --timeout 20
  )
}

# stop_and_check DIR LABEL: stop exits 0 and every process it had recorded has ended.
stop_and_check() {
  local d=$1 label=$2 pids pid
  pids=$(recorded_pids "$d")
  "$script" stop --dir "$d" >"$tmp/stop.out" 2>&1 || fail "$label: stop exited $?: $(cat "$tmp/stop.out")"
  for pid in $pids; do
    gone "$pid" || fail "$label: pid $pid still runs after stop"
  done
  ! ls "$d"/*.pid >/dev/null 2>&1 || fail "$label: pid files left after stop: $(ls "$d"/*.pid)"
}

if [ "$load" = 1 ]; then
  # One busy process per core: the master and workers start while every core is taken.
  for _ in $(seq "$(nproc)"); do
    bash -c 'while :; do :; done' &
    load_pids+=("$!")
  done
fi

# 1. Start and stop, CYCLES times.
d="$tmp/c-cycles"
for i in $(seq "$cycles"); do
  if ! "$script" start --workers 2 --threads 1 --dir "$d" --free-ports >"$tmp/start.out" 2>&1; then
    fail "cycle $i: start failed: $(cat "$tmp/start.out")"
    tail -5 "$d/master.log" >&2 || true
    "$script" stop --dir "$d" >/dev/null 2>&1 || true
    continue
  fi
  grep -q "source $d/env" "$tmp/start.out" || fail "cycle $i: start does not say to source $d/env"
  [ -f "$d/env" ] || fail "cycle $i: no env written"
  for f in master worker-1 worker-2; do
    pid=$(cat "$d/$f.pid" 2>/dev/null || true)
    [ -n "$pid" ] && ! gone "$pid" || fail "cycle $i: $f is not running after start"
  done
  list_jobs "$d" >"$tmp/list.out" 2>&1 || fail "cycle $i: rayfarm list exited $?: $(cat "$tmp/list.out")"
  stop_and_check "$d" "cycle $i"
done
echo "local-cluster: $cycles start/stop cycles$([ "$load" = 1 ] && echo " under load"), $failures failed"

if [ "$only_cycles" = 0 ]; then
  # 2. The master killed while start waits for it. This rayfarm-master waits for a file that never
  # comes before it runs the real one, so the kill always lands while start is waiting.
  bin="$tmp/bin"
  mkdir -p "$bin"
  cat >"$bin/rayfarm-master" <<EOF
#!/bin/sh
while [ ! -e "$tmp/go" ]; do sleep 0.05; done
exec "$RAYFARM_BIN/master/rayfarm-master" "\$@"
EOF
  chmod +x "$bin/rayfarm-master"
  ln -s "$RAYFARM_BIN/worker/rayfarm-worker" "$bin/rayfarm-worker"
  ln -s "$RAYFARM_BIN/cli/rayfarm" "$bin/rayfarm"
  d="$tmp/c-killed"
  RAYFARM_BIN="$bin" "$script" start --dir "$d" --free-ports >"$tmp/killed.out" 2>"$tmp/killed.err" &
  start_pid=$!
  master_pid=
  for _ in $(seq 400); do  # 20 s
    master_pid=$(cat "$d/master.pid" 2>/dev/null || true)
    [ -n "$master_pid" ] && break
    sleep 0.05
  done
  if [ -z "$master_pid" ]; then
    fail "killed master: start wrote no master.pid within 20 s"
    kill -KILL "$start_pid" 2>/dev/null || true
  else
    kill -KILL "$master_pid"
    rc=0
    wait "$start_pid" || rc=$?
    err=$(cat "$tmp/killed.err")
    [ "$rc" = 1 ] || fail "killed master: start exited $rc, not 1"
    [[ $err == *"the master (pid $master_pid) was killed by SIGKILL"* ]] ||
      fail "killed master: start does not name the cause: $err"
    [ ! -e "$d/master.pid" ] || fail "killed master: master.pid left behind"
    [ ! -e "$d/env" ] || fail "killed master: env written"
    ! ls "$d"/worker-*.pid >/dev/null 2>&1 || fail "killed master: workers were started"
    gone "$master_pid" || fail "killed master: pid $master_pid still runs"
  fi
  # ...and the next start, with the real master, works.
  if "$script" start --dir "$d" --free-ports >"$tmp/after.out" 2>&1; then
    list_jobs "$d" >"$tmp/list.out" 2>&1 || fail "after the killed master: rayfarm list failed: $(cat "$tmp/list.out")"
    stop_and_check "$d" "after the killed master"
  else
    fail "after the killed master: start failed: $(cat "$tmp/after.out")"
  fi

  # 3. A master that exits by itself: its exit code and its own words.
  d="$tmp/c-exits"
  rc=0
  "$script" start --dir "$d" --free-ports --log-level nonsense >"$tmp/exits.out" 2>"$tmp/exits.err" || rc=$?
  err=$(cat "$tmp/exits.err")
  [ "$rc" = 1 ] || fail "master exits: start exited $rc, not 1"
  [[ $err == *"the master (pid "*") exited with code "*"master.log says:"*"nonsense"* ]] ||
    fail "master exits: start does not show why: $err"
  ! ls "$d"/*.pid >/dev/null 2>&1 || fail "master exits: pid files left behind"

  # 4. What a start cut short leaves behind: refused and named; stop ends it.
  d="$tmp/c-orphan"
  if "$script" start --dir "$d" --free-ports >/dev/null 2>&1; then
    pids=$(recorded_pids "$d")
    master_pid=$(cat "$d/master.pid")
    rm -f "$d/env" "$d"/worker-*.pid
    rc=0
    "$script" start --dir "$d" --free-ports >"$tmp/orphan.out" 2>"$tmp/orphan.err" || rc=$?
    err=$(cat "$tmp/orphan.err")
    [ "$rc" = 1 ] || fail "orphans: start exited $rc, not 1"
    [[ $err == *"did not finish and left running master (pid $master_pid)"*"rayfarm-worker (pid "*"no pid file)"*"deploy/local-cluster stop --dir $d"* ]] ||
      fail "orphans: start does not name them: $err"
    "$script" stop --dir "$d" >/dev/null 2>&1 || fail "orphans: stop failed"
    for pid in $pids; do gone "$pid" || fail "orphans: pid $pid still runs after stop"; done
    if "$script" start --dir "$d" --free-ports >/dev/null 2>&1; then
      stop_and_check "$d" "after the orphans"
    else
      fail "orphans: start after stop failed"
    fi
  else
    fail "orphans: the first start failed"
  fi
fi

if [ "$failures" -gt 0 ]; then
  echo "local-cluster test: $failures failure(s)" >&2
  exit 1
fi
echo "local-cluster test: passed"
