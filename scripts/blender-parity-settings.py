"""Render settings for comparing a Cycles render of an export with native splatting.

Run before ../shared/tools/blender-check.py in the same Blender process:
  blender -b --factory-startup --python scripts/blender-parity-settings.py \
          --python ../shared/tools/blender-check.py -- FILE --render OUT.png ...
It registers a persistent render_pre handler (it survives the check script's factory reset
and import) that sets what a glTF file cannot carry:
  - view transform Standard (Blender 3.4's default Filmic tone-maps; native splatting writes
    the display values as they are),
  - a black world (the native renderer's default background),
  - transparent bounces from SPLATBRIDGE_TRANSPARENT_BOUNCES (default 1024; Cycles' default 8
    stops a ray after 8 splat layers and leaves the rest black).
"""
import os

import bpy


@bpy.app.handlers.persistent
def parity_settings(scene, *_):
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.sequencer_colorspace_settings.name = "sRGB"
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.world.use_nodes = False
    scene.world.color = (0.0, 0.0, 0.0)
    if scene.render.engine == "CYCLES":
        scene.cycles.transparent_max_bounces = int(os.environ.get("SPLATBRIDGE_TRANSPARENT_BOUNCES", "1024"))
    print("PARITY_SETTINGS", scene.view_settings.view_transform, tuple(scene.world.color),
          getattr(scene.cycles, "transparent_max_bounces", None))


bpy.app.handlers.render_pre.append(parity_settings)
