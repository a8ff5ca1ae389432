#!/usr/bin/env bash
# Samples per second on scenes that tell the BVH's two builds apart (renderer/embree/build_choice.h:
# one tree over every triangle, or a tree per geometry under one over those): the bundled Cornell
# box and blocks (walls that are geometries of their own), and three generated rooms, the Cornell
# walls with
#   spheres  two tessellated spheres, 80,000 triangles, each sphere a mesh (built apart);
#   shared2  two meshes of 10,000 small triangles each, both scattered through the whole room
#            (their boxes overlap: built as one tree);
#   shared400  400 meshes of 50 such triangles (likewise).
# With two build folders it alternates them, round by round, and prints the second's speed over
# the first's (a before/after comparison: bench/bvh_build.sh BEFORE AFTER).
#
# Usage: bench/bvh_build.sh [BUILD_DIR [OTHER_BUILD_DIR]] [--rounds R] [--threads T]
set -euo pipefail
cd "$(dirname "$0")/.."
builds=()
rounds=5
threads=2
while [[ $# -gt 0 ]]; do
  case "$1" in
    --rounds) rounds="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    -*) echo "bvh_build.sh: unknown option $1" >&2; exit 2 ;;
    *) builds+=("$1"); shift ;;
  esac
done
[[ ${#builds[@]} -gt 0 ]] || builds=(build)
for b in "${builds[@]}"; do
  [[ -x "$b/bench/render_throughput" ]] || { echo "build $b/bench/render_throughput first" >&2; exit 2; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

python3 - "$work" <<'EOF'
import json, math, random, sys
out = sys.argv[1]
walls = [
    {"type": "quad", "corner": [0, 0, 0], "edge1": [0, 0, 559.2], "edge2": [556, 0, 0], "material": "white"},
    {"type": "quad", "corner": [0, 548.8, 0], "edge1": [556, 0, 0], "edge2": [0, 0, 559.2], "material": "white"},
    {"type": "quad", "corner": [0, 0, 559.2], "edge1": [0, 548.8, 0], "edge2": [556, 0, 0], "material": "white"},
    {"type": "quad", "corner": [556, 0, 0], "edge1": [0, 0, 559.2], "edge2": [0, 548.8, 0], "material": "red"},
    {"type": "quad", "corner": [0, 0, 0], "edge1": [0, 548.8, 0], "edge2": [0, 0, 559.2], "material": "green"},
    {"type": "quad", "corner": [213, 548.7, 227], "edge1": [130, 0, 0], "edge2": [0, 0, 105], "material": "light"},
]
base = {
    "format": 1,
    "camera": {"type": "perspective", "eye": [278, 273, -800], "look_at": [278, 273, 0],
               "up": [0, 1, 0], "fov_y": 37},
    "film": {"width": 64, "height": 64},
    "materials": {
        "white": {"type": "diffuse", "albedo": [0.75, 0.75, 0.75]},
        "red": {"type": "diffuse", "albedo": [0.63, 0.065, 0.05]},
        "green": {"type": "diffuse", "albedo": [0.14, 0.45, 0.09]},
        "light": {"type": "diffuse", "albedo": [0.78, 0.78, 0.78], "emission": [17, 12, 4]}},
    "background": [0, 0, 0],
    "render": {"spp": 16, "max_depth": 16, "integrator": "mis", "seed": 0},
}

def write_obj(path, vertices, faces):
    with open(path, "w") as f:
        for v in vertices: f.write("v %.4f %.4f %.4f\n" % tuple(v))
        for t in faces: f.write("f %d %d %d\n" % tuple(i + 1 for i in t))

def sphere(centre, radius, n):
    v, f = [], []
    for i in range(n + 1):
        th = math.pi * i / n
        for j in range(2 * n):
            ph = math.pi * j / n
            v.append([centre[0] + radius * math.sin(th) * math.cos(ph), centre[1] + radius * math.cos(th),
                      centre[2] + radius * math.sin(th) * math.sin(ph)])
    for i in range(n):
        for j in range(2 * n):
            a, b = i * 2 * n + j, i * 2 * n + (j + 1) % (2 * n)
            f += [(a, a + 2 * n, b), (b, a + 2 * n, b + 2 * n)]
    return v, f

def scattered(count, rng):
    v, f = [], []
    for _ in range(count):
        c = [rng.uniform(20, 530), rng.uniform(5, 500), rng.uniform(20, 540)]
        f.append((len(v), len(v) + 1, len(v) + 2))
        v += [[c[k] + rng.uniform(-4, 4) for k in range(3)] for _ in range(3)]
    return v, f

def scene(name, meshes):
    shapes = list(walls)
    for i, (v, f) in enumerate(meshes):
        write_obj(f"{out}/{name}{i}.obj", v, f)
        shapes.append({"type": "mesh", "file": f"{name}{i}.obj", "material": "white"})
    s = dict(base, shapes=shapes)
    json.dump(s, open(f"{out}/{name}.json", "w"))

scene("spheres", [sphere([185, 100, 170], 100, 100), sphere([370, 150, 370], 120, 100)])
rng = random.Random(2)
scene("shared2", [scattered(10000, rng) for _ in range(2)])
scene("shared400", [scattered(50, rng) for _ in range(400)])
EOF

scenes=(scenes/cornell-box/scene.json scenes/cornell-blocks/scene.json "$work/spheres.json"
        "$work/shared2.json" "$work/shared400.json")
for s in "${scenes[@]}"; do
  name=$(basename "$s" .json)
  [[ $name == scene ]] && name=$(basename "$(dirname "$s")")
  declare -A figures=()
  for ((r = 1; r <= rounds; r++)); do
    for b in "${builds[@]}"; do
      f=$("$b/bench/render_throughput" "$s" --spp 16 --runs 3 --threads "$threads" 2>/dev/null |
          awk '/^median:/{print $2}')
      figures[$b]="${figures[$b]-} $f"
    done
  done
  line="$name:"
  for b in "${builds[@]}"; do
    m=$(tr ' ' '\n' <<<"${figures[$b]}" | grep . | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
    line="$line  $b ${m} spp/s"
    meds+=("$m")
  done
  if [[ ${#builds[@]} -eq 2 ]]; then
    line="$line  ratio $(awk -v a="${meds[-1]}" -v b="${meds[-2]}" 'BEGIN{printf "%.2f", a/b}')"
  fi
  echo "$line"
  unset figures
done
