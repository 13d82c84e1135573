"""Import a splatbridge export into Blender and set the scene up the way splat meshes need
(the set-up itself is the Blender extension's, blender/splatbridge_import/splat_setup.py; its
docstring says what is set and why).

Usage (Blender 3.4 or newer; EEVEE needs a display, e.g. `xvfb-run`):
  blender --factory-startup --python scripts/blender-splat-setup.py -- FILE.glb
          [--render OUT.png] [--engine eevee|cycles] [--camera N] [--size WxH] [--samples N]
          [--time SECONDS] [--eevee-order sorted|hashed] [--save OUT.blend]
Without --render the scene is left open (or saved with --save) ready to look at: the same
settings apply to the viewport's rendered mode and to F12. With the extension installed,
File > Import > Gaussian splats does the same from any splat file.

Prints `SPLAT_SETUP {json}` with what was set. Exit status 0 done, 1 failed.
"""
import json
import math
import os
import struct
import sys

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "blender",
                                "splatbridge_import"))
from splat_setup import (  # noqa: E402
    DEFAULT_SAMPLES, gltf_json, pick_camera, setup_camera, setup_scene, sort_back_to_front)


def parse_args(argv):
    argv = argv[argv.index("--") + 1:] if "--" in argv else []
    opts = {"file": None, "render": None, "engine": "eevee", "camera": "0", "size": None,
            "samples": str(DEFAULT_SAMPLES), "time": "0", "eevee-order": "sorted", "save": None}
    it = iter(argv)
    for a in it:
        if a.startswith("--"):
            key = a[2:]
            if key not in opts or key == "file":
                raise SystemExit(f"error: unknown option {a}")
            try:
                opts[key] = next(it)
            except StopIteration:
                raise SystemExit(f"error: {a} needs a value")
        elif opts["file"] is None:
            opts["file"] = a
        else:
            raise SystemExit(f"error: unexpected argument {a}")
    if opts["engine"] not in ("eevee", "cycles"):
        raise SystemExit(f"error: --engine: expected eevee or cycles, got {opts['engine']}")
    return opts


def main():
    o = parse_args(sys.argv)
    if o["file"] is None:
        raise SystemExit("error: no input file")
    path = o["file"]
    try:
        doc = gltf_json(path)
    except (OSError, ValueError, struct.error) as e:
        raise SystemExit(f"error: {path}: not a readable glTF/GLB: {e}")
    try:
        samples = int(o["samples"])
        assert samples > 0
    except (ValueError, AssertionError):
        raise SystemExit(f"error: --samples: expected a positive integer, got {o['samples']}")
    size = None
    if o["size"]:
        try:
            w, h = (int(x) for x in o["size"].lower().split("x"))
            assert 0 < w <= 16384 and 0 < h <= 16384
            size = (w, h)
        except (ValueError, AssertionError):
            raise SystemExit(f"error: --size: expected WxH (1..16384), got {o['size']}")
    try:
        index = int(o["camera"])
    except ValueError:
        raise SystemExit(f"error: --camera: expected a camera index, got {o['camera']}")

    try:
        time = float(o["time"])
        assert math.isfinite(time)
    except (ValueError, AssertionError):
        raise SystemExit(f"error: --time: expected seconds, got {o['time']}")

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    scene = bpy.context.scene
    report = setup_scene(scene, doc, samples)
    scene.render.engine = "CYCLES" if o["engine"] == "cycles" else "BLENDER_EEVEE"
    if o["render"] or doc.get("cameras"):
        try:
            ob, opencv, cam = pick_camera(doc, index)
        except ValueError as e:
            raise SystemExit(f"error: --{e}")
        report["camera"] = setup_camera(scene, ob, opencv, cam, size)
    report["engine"] = scene.render.engine
    # The importer keys animations at frame = seconds · fps (frame 0 is t = 0).
    frame = time * scene.render.fps / scene.render.fps_base
    scene.frame_set(math.floor(frame), subframe=frame - math.floor(frame))
    report["frame"] = frame
    if o["render"] and o["engine"] == "eevee" and o["eevee-order"] == "sorted":
        report["eevee_order"] = "sorted"
        report["sorted_faces"] = sort_back_to_front(scene, scene.camera)
    if o["render"]:
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_mode = "RGB"
        scene.render.image_settings.color_depth = "8"
        scene.render.filepath = os.path.abspath(o["render"])
        bpy.ops.render.render(write_still=True)
        report["rendered"] = o["render"]
    if o["save"]:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(o["save"]))
    print("SPLAT_SETUP " + json.dumps(report), flush=True)


if __name__ == "__main__":
    main()
