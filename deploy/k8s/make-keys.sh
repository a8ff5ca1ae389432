#!/usr/bin/env bash
# Makes the farm's CURVE keys and stores them in the cluster, for deploy/k8s (docs/deploy.md):
#
#   deploy/k8s/make-keys.sh [--dir DIR] [--namespace NS] [--dry-run]
#
#   Secret    rayfarm-master-key     master.key_secret    the master's secret key
#   Secret    rayfarm-worker-key     worker.key_secret    the workers' secret key (one for the Deployment)
#   ConfigMap rayfarm-master-public  master.key           the master's public key, for workers
#   ConfigMap rayfarm-worker-keys    *.key                the master's allow-list of workers
#   ConfigMap rayfarm-client-keys    *.key                the master's allow-list of clients
#
# Keys are made with `rayfarm keygen` (from $RAYFARM_BIN, ./build or PATH; else in the rayfarm:latest
# image with docker) into DIR (default ./rayfarm-keys; keep it private, outside the repository),
# and never replaced: run it again after adding NAME.key files to DIR/workers or DIR/clients to
# update the allow-lists, which the master reads again within a second of Kubernetes updating the
# mounted files (about a minute). --dry-run prints the objects instead of applying them.
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
dir=rayfarm-keys
namespace=()
dry_run=0
while [ $# -gt 0 ]; do
  case $1 in
    --dir) dir=${2:?--dir needs a folder}; shift 2 ;;
    --namespace|-n) namespace=(--namespace "${2:?--namespace needs a name}"); shift 2 ;;
    --dry-run) dry_run=1; shift ;;
    -h|--help) sed -n '2,18p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-keys: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done

keygen() {  # keygen DIR NAME
  local c
  for c in ${RAYFARM_BIN:+"$RAYFARM_BIN/rayfarm" "$RAYFARM_BIN/cli/rayfarm"} "$repo_root/build/cli/rayfarm"; do
    [ -x "$c" ] && { "$c" keygen -o "$1" --name "$2" >/dev/null; return; }
  done
  if command -v rayfarm >/dev/null; then rayfarm keygen -o "$1" --name "$2" >/dev/null; return; fi
  docker run --rm --user "$(id -u):$(id -g)" -v "$(realpath "$1"):/k" "${RAYFARM_IMAGE:-rayfarm:latest}" \
    rayfarm keygen -o /k --name "$2" >/dev/null
}

mkdir -p "$dir/own" "$dir/workers" "$dir/clients"
chmod 700 "$dir/own"
[ -f "$dir/master.key_secret" ] || keygen "$dir" master
for pair in worker:workers cli:clients; do
  name=${pair%%:*} list=${pair#*:}
  [ -f "$dir/own/$name.key_secret" ] || keygen "$dir/own" "$name"
  [ -f "$dir/$list/$name.key" ] || cp "$dir/own/$name.key" "$dir/$list/"
done

apply() {
  if [ "$dry_run" = 1 ]; then
    cat
    echo "---"
  else
    kubectl "${namespace[@]}" apply -f -
  fi
}
k() { kubectl "${namespace[@]}" create "$@" --dry-run=client -o yaml; }

k secret generic rayfarm-master-key --from-file="$dir/master.key_secret" | apply
k secret generic rayfarm-worker-key --from-file="$dir/own/worker.key_secret" | apply
k configmap rayfarm-master-public --from-file="$dir/master.key" | apply
k configmap rayfarm-worker-keys --from-file="$dir/workers" | apply
k configmap rayfarm-client-keys --from-file="$dir/clients" | apply

echo "make-keys: keys in $dir; the CLI's: RAYFARM_KEY=$dir/own/cli.key_secret RAYFARM_MASTER_KEY=$dir/master.key" >&2
