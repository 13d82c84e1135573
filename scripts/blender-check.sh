#!/usr/bin/env bash
# Import converter exports into Blender (headless, factory settings) with
# ../shared/tools/blender-check.py and check what a Blender user gets:
#   - one mesh object per glTF mesh node, the cameras present,
#   - a material that is BLEND, unlit/emissive, with the colour attribute wired to both
#     colour and alpha; with --surfels exports, the surfel material ("surfels") is OPAQUE,
#     unlit/emissive, with the colour attribute wired to colour (alpha is 1 and unused),
#   - one action per moving object spanning the scene's time range.
# Usage: scripts/blender-check.sh [FILE.glb ...]
#   Without files, the street fixture is exported with every profile (and with surfels) and
#   checked.
#   Set RENDER=1 to also render through the first camera (Cycles) next to each file.
# Exit status: 0 all checks pass, 1 a check failed, 3 Blender is not installed.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
check_py=${BLENDER_CHECK_PY:-$repo/../shared/tools/blender-check.py}
command -v blender >/dev/null || { echo "blender-check: blender not found" >&2; exit 3; }
[[ -f $check_py ]] || { echo "blender-check: $check_py not found" >&2; exit 3; }

files=("$@")
if (( ${#files[@]} == 0 )); then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
  for p in meshsplats rings texture; do
    (cd "$repo" && cargo run -q --release -p splatbridge-convert --example export_street -- "$out/street-$p.glb" "$p" >/dev/null)
    files+=("$out/street-$p.glb")
  done
  (cd "$repo" && cargo run -q --release -p splatbridge-convert --example export_street -- "$out/street-surfels.glb" texture --surfels >/dev/null)
  files+=("$out/street-surfels.glb")
fi

status=0
for f in "${files[@]}"; do
  extra=()
  [[ ${RENDER:-0} == 1 ]] && extra=(--render "${f%.*}-blender.png" --samples 16)
  line=$(blender -b --factory-startup --python "$check_py" -- "$f" "${extra[@]}" 2>/dev/null | grep '^BLENDER_CHECK ' | head -1 || true)
  if [[ -z $line ]]; then echo "FAIL $f: no BLENDER_CHECK line"; status=1; continue; fi
  python3 - "$f" "${line#BLENDER_CHECK }" <<'PY' || status=1
import json, struct, sys
path, rep = sys.argv[1], json.loads(sys.argv[2])
def gltf_json(p):
    data = open(p, "rb").read()
    if data[:4] == b"glTF":
        n = struct.unpack_from("<I", data, 12)[0]
        return json.loads(data[20:20 + n])
    return json.loads(data)
doc = gltf_json(path)
problems = []
if not rep.get("ok"):
    print("FAIL", path, rep.get("error")); sys.exit(1)
mesh_nodes = [n for n in doc.get("nodes", []) if "mesh" in n]
cam_nodes = [n for n in doc.get("nodes", []) if "camera" in n]
meshes = [o for o in rep["objects"] if o["type"] == "MESH"]
cams = [o for o in rep["objects"] if o["type"] == "CAMERA"]
if len(meshes) != len(mesh_nodes):
    problems.append(f"{len(meshes)} mesh objects for {len(mesh_nodes)} mesh nodes")
if len(cams) != len(cam_nodes):
    problems.append(f"{len(cams)} cameras for {len(cam_nodes)} camera nodes")
for o in meshes:
    if not o.get("materials"):
        problems.append(f"object {o['name']} has no material")
    if not o.get("color_attributes"):
        problems.append(f"object {o['name']} has no colour attribute")
# The surfel material of --surfels exports (glTF name "surfels"; Blender may add ".001").
def is_surfel_material(name):
    return name == "surfels" or name.startswith("surfels.")
gltf_materials = [m.get("name") for m in doc.get("materials", [])]
for m in rep["materials"]:
    blend = m.get("blend_method") == "BLEND" or m.get("surface_render_method") == "BLENDED"
    if is_surfel_material(m["name"]):
        opaque = m.get("blend_method") == "OPAQUE" or m.get("surface_render_method") == "DITHERED"
        checks = [("opaque mode", opaque), ("colour attribute → colour", m["color_attribute_to_color"]),
                  ("unlit/emissive", m["emissive_or_unlit"])]
    else:
        checks = [("alpha blending", blend), ("colour attribute → colour", m["color_attribute_to_color"]),
                  ("colour attribute → alpha", m["color_attribute_to_alpha"]), ("unlit/emissive", m["emissive_or_unlit"])]
    for key, ok in checks:
        if not ok:
            problems.append(f"material {m['name']}: no {key}")
if "surfels" in gltf_materials and not any(is_surfel_material(m["name"]) for m in rep["materials"]):
    problems.append("the file has a surfel material but Blender imported none")
for o in meshes:
    if any(is_surfel_material(n) for n in o.get("materials", [])) and not o.get("color_attributes"):
        problems.append(f"object {o['name']}: surfel material without a colour attribute")
channels = [(a, c) for a in doc.get("animations", []) for c in a["channels"]]
moving = {c["target"]["node"] for _, c in channels if c["target"]["path"] in ("translation", "rotation")}
# Per-frame content (weather particles) is one node per frame shown by a STEP scale 0 <-> 1.
visibility = {c["target"]["node"] for _, c in channels if c["target"]["path"] == "scale"} - moving
for a, c in channels:
    if c["target"]["node"] in visibility and a["samplers"][c["sampler"]].get("interpolation", "LINEAR") != "STEP":
        problems.append(f"node {c['target']['node']}: visibility (scale) animation is not STEP")
meta = doc["asset"].get("extras", {}).get("splatbridge", {})
fps = rep["scene"]["fps"]
animated = [o for o in meshes if o["action"]]
if len(animated) != len(moving) + len(visibility):
    problems.append(f"{len(animated)} animated objects for {len(moving)} moving and {len(visibility)} per-frame nodes")
times = []
for a in doc.get("animations", []):
    for s in a["samplers"]:
        acc = doc["accessors"][s["input"]]
        times += [acc["min"][0], acc["max"][0]]
if times:
    want = (min(times) * fps, max(times) * fps)
    for o in animated:
        act = next(a for a in rep["actions"] if a["name"] == o["action"])
        lo, hi = act["frame_range"]
        # Blender's glTF importer starts actions at frame 1 for t = 0 (keys at 1 + t·fps).
        if abs((hi - lo) - (want[1] - want[0])) > 1.01:
            problems.append(f"action {act['name']} spans frames {lo}..{hi}, expected a span of {want[1] - want[0]:.1f}")
summary = {"file": path, "blender": rep["blender"], "mesh_objects": len(meshes), "cameras": len(cams),
           "actions": [(a["name"], a["frame_range"]) for a in rep["actions"]],
           "materials": [{k: m[k] for k in ("name", "blend_method", "color_attribute_to_color", "color_attribute_to_alpha", "emissive_or_unlit")} for m in rep["materials"]],
           "problems": problems}
print(json.dumps(summary))
sys.exit(1 if problems else 0)
PY
done
exit $status
