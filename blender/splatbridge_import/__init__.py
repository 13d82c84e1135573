"""Blender extension (4.2+; also a legacy add-on for 3.4): File > Import > Gaussian splats.

Any splat scene splatbridge reads (.ply, .spz, .splat, .ksplat, SOG, KHR glTF, a
splatbridge-scene/1 manifest) is converted to a mesh by the bundled `splatbridge` package
(the same conversion as `splatbridge convert`, optionally distilled against native
splatting), imported with Blender's glTF importer (dynamic objects keep their animation, the
scene's cameras come along), and the scene is set up so that it renders like native
splatting (`splat_setup`: colour encoding, Raw view transform, blend mode, Cycles transparent
bounces, black world, the cameras' OpenCV intrinsics). No manual step is left.

Operator: `bpy.ops.import_scene.gaussian_splats(filepath=...)`.
"""
import math
import os
import shutil
import tempfile
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import splat_setup

bl_info = {  # the legacy add-on header (Blender 3.4); extensions read blender_manifest.toml
    "name": "splatbridge: Gaussian splats",
    "blender": (3, 4, 0),
    "category": "Import-Export",
    "location": "File > Import > Gaussian splats",
    "description": "Import Gaussian splat scenes as meshes that render like native splatting",
}

EXTENSIONS = "*.ply;*.spz;*.splat;*.ksplat;*.sog;*.json;*.glb;*.gltf"


def ensure_package():
    """Make the bundled `splatbridge` package importable.

    Blender 4.2+ installs an extension's `wheels` into its own site-packages. A legacy add-on
    (Blender 3.4 to 4.1) gets no such step: the wheel bundled in `wheels/` is unpacked once
    into `_vendor/` beside this file (a wheel is a zip of the installed files; the abi3
    extension module loads in any CPython from 3.9 on) and that folder goes on `sys.path`.
    A `splatbridge` already importable (pip-installed into Blender's Python) is used as is.
    """
    try:
        import splatbridge  # noqa: F401
        return
    except ImportError:
        pass
    import glob
    import sys
    import zipfile

    here = os.path.dirname(os.path.abspath(__file__))
    wheels = sorted(glob.glob(os.path.join(here, "wheels", "splatbridge-*.whl")))
    if not wheels:
        raise ImportError("the splatbridge package is not installed and no wheel is bundled "
                          f"in {os.path.join(here, 'wheels')}")
    vendor = os.path.join(here, "_vendor")
    stamp = os.path.join(vendor, ".wheel")
    wheel = os.path.basename(wheels[-1])
    current = open(stamp).read() if os.path.exists(stamp) else None
    if current != wheel:
        # Unpacked beside, then renamed: an interrupted unpack never looks complete.
        part = vendor + ".part"
        shutil.rmtree(part, ignore_errors=True)
        with zipfile.ZipFile(wheels[-1]) as z:
            z.extractall(part)
        with open(os.path.join(part, ".wheel"), "w") as f:
            f.write(wheel)
        shutil.rmtree(vendor, ignore_errors=True)
        os.replace(part, vendor)
    if vendor not in sys.path:
        sys.path.insert(0, vendor)


def import_splats(context, filepath, profile="texture", distill=False, distill_views=16,
                  distill_seconds=30.0, time_start=None, time_end=None, up="-y",
                  cameras="", samples=splat_setup.DEFAULT_SAMPLES):
    """Import `filepath` into `context.scene`; returns a report (what was set, seconds)."""
    ensure_package()
    import splatbridge  # the bundled wheel

    t0 = time.perf_counter()
    scene = splatbridge.load(filepath)
    tmp = tempfile.mkdtemp(prefix="splatbridge-")
    try:
        glb = os.path.join(tmp, os.path.splitext(os.path.basename(filepath))[0] + ".glb")
        fit = None
        if distill:
            fit = {"views": f"orbit:{distill_views}", "time_budget": float(distill_seconds)}
        converted = splatbridge.convert(scene, glb, profile=profile, distill=fit, up=up,
                                        cameras=cameras or None)
        t1 = time.perf_counter()
        bpy.ops.import_scene.gltf(filepath=glb)
        doc = splat_setup.gltf_json(glb)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    t2 = time.perf_counter()
    bl = context.scene
    report = splat_setup.setup_scene(bl, doc, samples)
    if doc.get("cameras"):
        ob, opencv, cam = splat_setup.pick_camera(doc, 0)
        report["camera"] = splat_setup.setup_camera(bl, ob, opencv, cam, None)
    # The importer keys animations at frame = seconds · fps (frame 0 is t = 0).
    start, end, fps = scene.time_range
    if time_start is not None:
        start = time_start
    if time_end is not None:
        end = time_end
    if scene.is_dynamic:
        bl.render.fps, bl.render.fps_base = max(1, round(fps)), max(1, round(fps)) / fps
        bl.frame_start = math.floor(start * fps)
        bl.frame_end = max(bl.frame_start, math.ceil(end * fps))
        bl.frame_set(bl.frame_start)
    report.update({
        "gaussians": len(scene),
        "triangles": converted.get("triangles"),
        "seconds": {"convert": t1 - t0, "gltf_import": t2 - t1,
                    "total": time.perf_counter() - t0},
        "frames": [bl.frame_start, bl.frame_end],
    })
    return report


class IMPORT_SCENE_OT_gaussian_splats(bpy.types.Operator, ImportHelper):
    """Import a Gaussian splat scene as a mesh set up to render like native splatting"""

    bl_idname = "import_scene.gaussian_splats"
    bl_label = "Import Gaussian splats"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".ply"
    filter_glob: StringProperty(default=EXTENSIONS, options={"HIDDEN"})
    profile: EnumProperty(
        name="Profile",
        items=[("texture", "Texture", "Textured quads (fewest triangles, glTF)"),
               ("meshsplats", "MeshSplats", "Fans with per-vertex alpha"),
               ("rings", "Rings", "Fans with rings of alpha")],
        default="texture")
    distill: BoolProperty(name="Distill", default=False,
                          description="Fit the mesh's colours to native splatting first")
    distill_views: IntProperty(name="Views", default=16, min=1, max=1024,
                               description="Orbit views the fit uses")
    distill_seconds: FloatProperty(name="Time budget (s)", default=30.0, min=1.0,
                                   description="Stop fitting after this many seconds")
    use_time_range: BoolProperty(name="Time range", default=False,
                                 description="Import only this time range of a dynamic scene")
    time_start: FloatProperty(name="Start (s)", default=0.0, min=0.0)
    time_end: FloatProperty(name="End (s)", default=0.0, min=0.0)
    up_axis: EnumProperty(
        name="Up axis",
        items=[("-y", "-Y", "COLMAP and most 3DGS captures (y points down)"),
               ("y", "Y", "Y up"), ("z", "Z", "Z up (photogrammetry tools)")],
        default="-y")
    cameras: StringProperty(name="Cameras", default="",
                            description="Cameras to add (orbit:N, scene, PATH.json); "
                                        "empty: the scene's own")
    samples: IntProperty(name="Samples", default=splat_setup.DEFAULT_SAMPLES, min=1)

    def execute(self, context):
        try:
            report = import_splats(
                context, self.filepath, profile=self.profile, distill=self.distill,
                distill_views=self.distill_views, distill_seconds=self.distill_seconds,
                time_start=self.time_start if self.use_time_range else None,
                time_end=self.time_end if self.use_time_range else None,
                up=self.up_axis, cameras=self.cameras, samples=self.samples)
        except Exception as e:  # splatbridge.Error carries the CLI's message
            self.report({"ERROR"}, f"{self.filepath}: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, "Imported {} Gaussians in {:.1f} s".format(
            report["gaussians"], report["seconds"]["total"]))
        return {"FINISHED"}


def menu_func_import(self, context):
    self.layout.operator(IMPORT_SCENE_OT_gaussian_splats.bl_idname,
                         text="Gaussian splats (.ply, .spz, .splat, .sog, .glb)")


def register():
    bpy.utils.register_class(IMPORT_SCENE_OT_gaussian_splats)
    bpy.types.TOPBAR_MT_file_import.append(menu_func_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_func_import)
    bpy.utils.unregister_class(IMPORT_SCENE_OT_gaussian_splats)
