#!/usr/bin/env bash
# Regenerates the seed corpus in fuzz/corpus/ from the bundled scenes, PLY files written by
# make_ply_seeds.py and, for the wire, text-format messages encoded with protoc; the image seeds
# are written by the build's fuzz_image_seeds (BUILD=folder, default build/;
# cmake --build build --target fuzz_image_seeds).
# Run from anywhere; the seeds are committed.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
c="$here/corpus"
build=${BUILD:-$root/build}
if [ ! -x "$build/fuzz/fuzz_image_seeds" ]; then
  echo "make_seeds: $build/fuzz/fuzz_image_seeds is missing: cmake --build $build --target fuzz_image_seeds" >&2
  exit 1
fi
rm -rf "$c" && mkdir -p "$c"/{scene,obj,ply,wire,bundle,image,gltf}

# Scenes: the bundled ones, one with a mesh and every shape and material, and broken ones.
for s in cornell-box phong furnace animated-box; do cp "$root/scenes/$s/scene.json" "$c/scene/$s.json"; done
cat > "$c/scene/everything.json" <<'JSON'
{"format": 1,
 "camera": {"type": "perspective", "eye": [0, 1, -4], "look_at": [0, 1, 0], "up": [0, 1, 0],
            "fov_y": 40, "aperture_radius": 0.1, "focus_distance": 4},
 "film": {"width": 8, "height": 6},
 "materials": {"d": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5], "emission": [1, 1, 1], "two_sided": true},
               "p": {"type": "phong", "kd": [0.3, 0.3, 0.3], "ks": [0.5, 0.5, 0.5], "exponent": 20},
               "m": {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]},
               "g": {"type": "dielectric", "ior": 1.5, "tint": [1, 1, 1]}},
 "shapes": [{"type": "mesh", "file": "m.obj", "material": "d"}, {"type": "mesh", "file": "m.obj"},
            {"type": "sphere", "center": [0, 1, 0], "radius": 1, "material": "g"},
            {"type": "quad", "corner": [-1, 0, -1], "edge1": [0, 0, 2], "edge2": [2, 0, 0], "material": "p"},
            {"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "material": "m"}],
 "lights": [{"type": "point", "position": [0, 3, 0], "intensity": [5, 5, 5]}],
 "background": [0.1, 0.1, 0.1],
 "render": {"spp": 4, "max_depth": 8, "integrator": "nee", "seed": 3}}
JSON
printf '{"camera": {"eye": [0, 0, 0], "look_at": [0, 0, 1e18], "fov_y": 40}, "film": {"width": 1, "height": 1}, "x": [[[[1]]]]}' > "$c/scene/bad-range.json"
printf '{"camera": {"eye": [0, 0, 0], "look_at": [0, 0, 1], "fov_y": 40}, "film": {"width": 1, "height": 1}, "shapes": [{"type": "mesh", "file": "../m.obj"}]} // c' > "$c/scene/bad-path.json"

# OBJ + NUL + MTL.
obj="$root/scenes/embree-cornell/cornell_box.obj"
{ sed 's/^mtllib .*/mtllib f.mtl/' "$obj"; printf '\0'; cat "$root/scenes/embree-cornell/cornell_box.mtl"; } > "$c/obj/cornell.bin"
printf 'mtllib f.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0 1\nv 1 1 0 0.5 0.5 0.5\nvt 0 0\nvn 0 0 1\no x\ng y\ns 1\nusemtl glass\nf 1/1/1 2/1/1 3/1/1\nf -1 -2 -3 -4\nl 1 2\n\0newmtl glass\nKd 0.5 0.5 0.5\nKs 0.1 0.1 0.1\nNi 1.5\nd 0.5\nTf 1 1 1\nillum 7\nNs 10\nKe 0 0 0\nmap_Kd x.png\n' > "$c/obj/small.bin"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > "$c/obj/plain.bin"

# PLY: the three formats with what the reader skips, and broken files.
python3 "$here/make_ply_seeds.py" "$c/ply"

# Wire messages: type frame, newline, body (protoc --encode of a text-format message).
enc() {  # enc NAME TYPE TEXT
  { printf 'rayfarm.wire.%s\n' "$2"; printf '%s' "$3" | protoc --encode="rayfarm.wire.$2" -I "$root/proto" "$root/proto/rayfarm.proto"; } > "$c/wire/$1.bin"
}
# A 1x1 tile's sums: 3 values, each a one-byte varint 0 (protocol::pack_fixed).
sum3=$(printf 'sum: "%s"' "$(printf '\\000%.0s' $(seq 1 3))")
enc hello Hello 'protocol_version: 1 role: ROLE_WORKER name: "w1" threads: 4 build: "0.1"'
enc welcome Welcome 'protocol_version: 1 heartbeat_interval_ms: 1000 liveness: 3'
enc refusal Refusal 'protocol_version: 1 reason: "old" master_version: 1 peer_version: 0'
enc heartbeat Heartbeat 'protocol_version: 1'
enc error Error 'protocol_version: 1 message: "boom" job_id: "j1" code: UNKNOWN_WORKER'
enc goodbye Goodbye 'protocol_version: 1 reason: "SIGTERM"'
enc work-request WorkRequest 'protocol_version: 1'
enc work-unit WorkUnit 'protocol_version: 1 job_id: "j1" unit_id: 7 tile { x0: 0 y0: 0 x1: 1 y1: 1 } sample_begin: 0 sample_end: 4 settings { spp: 4 max_depth: 8 integrator: INTEGRATOR_MIS seed: 1 } bundle_hash: "0000000000000000000000000000000000000000000000000000000000000000" scene_path: "scene.json" pass: 0'
enc unit-result UnitResult "protocol_version: 1 job_id: \"j1\" unit_id: 7 tile { x0: 0 y0: 0 x1: 1 y1: 1 } sample_begin: 0 sample_end: 4 $sum3 ${sum3/sum:/sum_sq:} nonfinite: 1 rays: 10 render_seconds: 0.5"
enc unit-failed UnitFailed 'protocol_version: 1 job_id: "j1" unit_id: 7 reason: "bad scene"'
enc bundle-request BundleRequest 'protocol_version: 1 hash: "ab"'
enc bundle-reply BundleReply 'protocol_version: 1 hash: "ab" bundle { files { path: "scene.json" data: "{}" } files { path: "m/m.obj" data: "v 0 0 0" } }'
enc submit-job SubmitJob 'protocol_version: 1 bundle { files { path: "s.json" data: "{}" } } scene_path: "s.json" overrides { spp: 16 max_depth: 4 integrator: INTEGRATOR_NEE seed: 2 tile_size: 32 pass_spp: 4 } name: "n"'
enc submit-reply SubmitReply 'protocol_version: 1 job_id: "j1"'
enc status-request StatusRequest 'protocol_version: 1 job_id: "j1"'
enc job-status JobStatus 'protocol_version: 1 job_id: "j1" name: "n" state: JOB_RUNNING width: 4 height: 4 settings { spp: 4 max_depth: 8 integrator: INTEGRATOR_MIS } passes_total: 2 eta_seconds: -1'
enc list-jobs ListJobs 'protocol_version: 1'
enc job-list JobList 'protocol_version: 1 jobs { job_id: "a" state: JOB_DONE } jobs { job_id: "b" state: JOB_FAILED error: "x" }'
enc cancel-job CancelJob 'protocol_version: 1 job_id: "j1"'
enc cancel-reply CancelReply 'protocol_version: 1 job_id: "j1" state: JOB_CANCELLED'
enc fetch-image FetchImage 'protocol_version: 1 job_id: "j1"'
enc image-data ImageData 'protocol_version: 1 job_id: "j1" exr: "x" png: "y" spp_done: 4 state: JOB_DONE'
printf 'rayfarm.wire.Nope\n\x08\x01' > "$c/wire/unknown-type.bin"
printf 'rayfarm.wire.Hello' > "$c/wire/one-frame.bin"

# Bundles: a wire Bundle, and "path<TAB>data" lines.
printf 'files { path: "scene.json" data: "{}" } files { path: "a/b/c.obj" data: "v" }' | protoc --encode=rayfarm.wire.Bundle -I "$root/proto" "$root/proto/rayfarm.proto" > "$c/bundle/wire.bin"
printf 'scene.json\t{}\nmeshes/m.obj\tv 0 0 0\n' > "$c/bundle/lines.txt"
printf '../escape\tx\n' > "$c/bundle/escape.txt"
printf 'a/./b\tx\na\\b\ty\n/abs\tz\n' > "$c/bundle/odd-paths.txt"
# Images: tiny valid PNG, JPEG, OpenEXR and Radiance HDR files, and broken ones.
"$build/fuzz/fuzz_image_seeds" "$c/image"
# glTF: the bundled product shot (.glb) and small text files with data-URI buffers.
cp "$root/scenes/product/product.glb" "$c/gltf/product.glb"
python3 "$here/make_gltf_seeds.py" "$c/gltf"
echo "seeds: $(find "$c" -type f | wc -l) files in $c"
