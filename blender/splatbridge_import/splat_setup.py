"""Blender set up for splat meshes: what a glTF file cannot carry and Blender's defaults get
wrong, set on an imported splatbridge export (the import operator of this extension and
`scripts/blender-splat-setup.py` both call it). Works in Blender 3.4 and newer.

Blender's defaults are wrong for splats in four ways, each set here:
  - Order. EEVEE's "Alpha Blend" sorts whole objects, not triangles, so the back of a splat
    cloud is drawn over its front. "Alpha Hashed" is order-independent (each sample keeps a
    triangle with probability alpha) and converges to the ordered composite with enough
    samples: materials get blend_method HASHED, no shadows, both faces. For one camera,
    `sort_back_to_front` orders the triangles instead (BLEND, painter's algorithm).
    Cycles stops a ray after `transparent_max_bounces` layers (default 8; splat meshes stack
    hundreds) and shows black behind: it is raised to Cycles' maximum, 1024.
  - Colour. 3D Gaussian splatting composites the *display* (sRGB-encoded) colours it was
    trained on, and writes the composite as it is. glTF's COLOR_0 is linear, so Blender blends
    linear values in linear light, which darkens every partly covered pixel. Each material's
    colour is re-encoded with the exact sRGB curve before the emission shader (a no-op for
    files written with `--color-encoding display`, which is read from the file's metadata),
    and the view transform is Raw (Blender's default Filmic/AgX tone-maps; Standard would
    encode the display values a second time). The composite is then native splatting's.
  - Background. Native renders have a black background: the world is black, film opaque.
  - Camera. Exported cameras carry OpenCV intrinsics (`extras.opencv`: size, fx, fy, cx, cy);
    the chosen camera gets the same focal length, principal point (lens shift) and pixel size,
    and the pixel filter is narrowed to the pixel centre, where native splatting evaluates.
"""
import json
import math
import struct

import bpy

try:  # Debian's Blender 3.4 importer still uses numpy.bool, which numpy 1.24 removed.
    import numpy

    if "bool" not in numpy.__dict__:
        numpy.bool = bool
except ImportError:
    pass

# Cycles' largest transparent bounce count (its UI and RNA limit).
CYCLES_MAX_TRANSPARENT = 1024
# Samples when none are asked for: HASHED transparency is a Monte Carlo estimate of the
# ordered composite; 64 samples is where the issue measured EEVEE at 28.6 dB on fourth_st.
DEFAULT_SAMPLES = 64
# Pixel filter width (pixels) so samples stay at the pixel centre like native splatting
# (Blender's default 1.5 px Blackman-Harris blurs edges); Blender's minimum is 0.01.
FILTER_WIDTH = 0.01


def gltf_json(path):
    """The glTF JSON of a GLB or .gltf file (the importer keeps no extras of the asset)."""
    with open(path, "rb") as f:
        head = f.read(20)
        if head[:4] == b"glTF":
            n, kind = struct.unpack_from("<II", head, 12)
            if kind != 0x4E4F534A:
                raise ValueError("the first GLB chunk is not JSON")
            return json.loads(f.read(n))
        return json.loads(head + f.read())


# --- colour -----------------------------------------------------------------------------

def srgb_encode_group():
    """A node group applying the exact sRGB transfer function (IEC 61966-2-1) per channel."""
    name = "splatbridge_srgb_encode"
    if name in bpy.data.node_groups:
        return bpy.data.node_groups[name]
    g = bpy.data.node_groups.new(name, "ShaderNodeTree")
    if hasattr(g, "interface"):  # Blender 4.0+
        g.interface.new_socket("Color", in_out="INPUT", socket_type="NodeSocketColor")
        g.interface.new_socket("Color", in_out="OUTPUT", socket_type="NodeSocketColor")
    else:
        g.inputs.new("NodeSocketColor", "Color")
        g.outputs.new("NodeSocketColor", "Color")
    n, link = g.nodes, g.links.new
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    sep, comb = n.new("ShaderNodeSeparateRGB"), n.new("ShaderNodeCombineRGB")
    link(sep.inputs[0], gin.outputs[0])

    def math(op, a, b=None, c=None):
        m = n.new("ShaderNodeMath")
        m.operation = op
        for i, v in enumerate((a, b, c)):
            if v is None:
                continue
            if isinstance(v, float):
                m.inputs[i].default_value = v
            else:
                link(m.inputs[i], v)
        return m.outputs[0]

    for ch in range(3):
        c = math("MAXIMUM", sep.outputs[ch], 0.0)
        low = math("MULTIPLY", c, 12.92)
        high = math("MULTIPLY_ADD", math("POWER", c, 1.0 / 2.4), 1.055, -0.055)
        is_low = math("LESS_THAN", c, 0.0031308)  # 1 below the threshold, else 0
        # is_low·low + (1 − is_low)·high, exact for a 0/1 weight.
        out = math("ADD", math("MULTIPLY", is_low, low),
                   math("MULTIPLY", math("SUBTRACT", 1.0, is_low), high))
        link(comb.inputs[ch], out)
    link(gout.inputs[0], comb.outputs[0])
    return g


def feeds_emission_color(nt):
    """The (from_socket, to_socket) links into Emission colour inputs of a material."""
    return [l for l in nt.links if l.to_node.bl_idname == "ShaderNodeEmission"
            and l.to_socket.name == "Color"]


def setup_material(m, encode):
    """Order-independent transparency, no shadows, both faces; display-space colour."""
    done = {"name": m.name, "blend_method": m.blend_method, "encoded": False}
    if m.blend_method != "OPAQUE":
        m.blend_method = "HASHED"
    if hasattr(m, "shadow_method"):  # Blender < 4.2; EEVEE Next sets shadows per object
        m.shadow_method = "NONE"
    m.use_backface_culling = False
    done["blend_method"] = m.blend_method
    if encode and m.use_nodes and m.node_tree is not None:
        nt = m.node_tree
        for l in feeds_emission_color(nt):
            if l.from_node.bl_idname == "ShaderNodeGroup" and l.from_node.node_tree is not None \
                    and l.from_node.node_tree.name.startswith("splatbridge_srgb_encode"):
                done["encoded"] = True  # set up already
                continue
            src, dst = l.from_socket, l.to_socket
            node = nt.nodes.new("ShaderNodeGroup")
            node.node_tree = srgb_encode_group()
            node.location = (dst.node.location.x - 200, dst.node.location.y - 150)
            nt.links.remove(l)
            nt.links.new(node.inputs[0], src)
            nt.links.new(dst, node.outputs[0])
            done["encoded"] = True
        if not done["encoded"]:
            # A constant colour (no link): encode the default value itself.
            for node in nt.nodes:
                if node.bl_idname == "ShaderNodeEmission" and not node.inputs["Color"].is_linked:
                    rgba = list(node.inputs["Color"].default_value)
                    node.inputs["Color"].default_value = [srgb(x) for x in rgba[:3]] + rgba[3:]
                    done["encoded"] = True
    return done


def srgb(x):
    x = max(x, 0.0)
    return 12.92 * x if x < 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055


def sort_back_to_front(scene, cam_ob):
    """EEVEE render from one camera: join every mesh object into one (at the current frame,
    animation removed) and order its faces back to front along the camera's view axis, with
    materials in BLEND mode drawn without a depth pre-pass ("show backface"): the GPU blends a
    draw call's triangles in index order, so this is the painter's algorithm per triangle.
    HASHED transparency is view-independent but biased on stacked, nearly coplanar splats:
    its noise is a hash of the position, so layers at one spot share a threshold and the
    nearest-surviving test under-counts coverage (measured 2.8 dB darker on the street)."""
    import bmesh
    from mathutils import Vector

    meshes = [o for o in scene.objects if o.type == "MESH"]
    if not meshes:
        return 0
    bpy.ops.object.select_all(action="DESELECT")
    for o in meshes:
        # Freeze the pose of this frame: the joined object must not move.
        mw = o.matrix_world.copy()
        o.animation_data_clear()
        o.parent = None
        o.matrix_world = mw
        o.select_set(True)
    bpy.context.view_layer.objects.active = meshes[0]
    if len(meshes) > 1:
        bpy.ops.object.join()
    ob = bpy.context.view_layer.objects.active
    mw = ob.matrix_world
    forward = cam_ob.matrix_world.to_quaternion() @ Vector((0.0, 0.0, -1.0))
    eye = cam_ob.matrix_world.translation
    bm = bmesh.new()
    bm.from_mesh(ob.data)
    bm.faces.sort(key=lambda f: -(mw @ f.calc_center_median() - eye).dot(forward))
    bm.faces.index_update()
    bm.to_mesh(ob.data)
    bm.free()
    for m in ob.data.materials:
        if m is not None and m.blend_method != "OPAQUE":
            m.blend_method = "BLEND"
            if hasattr(m, "show_transparent_back"):
                m.show_transparent_back = True
            if hasattr(m, "use_transparency_overlap"):  # its name in Blender 4.2+
                m.use_transparency_overlap = True
    return len(ob.data.polygons)


def setup_colour_management(scene):
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Raw"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.view_settings.use_curve_mapping = False
    scene.sequencer_colorspace_settings.name = "sRGB"


def setup_world(scene):
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.world.use_nodes = False
    scene.world.color = (0.0, 0.0, 0.0)
    scene.render.film_transparent = False


def setup_engines(scene, samples):
    ee = scene.eevee
    ee.taa_render_samples = samples
    ee.taa_samples = max(16, min(samples, 64))
    for flag in ("use_bloom", "use_gtao", "use_ssr", "use_motion_blur", "use_soft_shadows",
                 "use_volumetric_lights", "use_volumetric_shadows"):
        if hasattr(ee, flag):
            setattr(ee, flag, False)
    scene.render.filter_size = FILTER_WIDTH
    cy = scene.cycles
    cy.samples = samples
    cy.preview_samples = max(16, min(samples, 64))
    cy.transparent_max_bounces = CYCLES_MAX_TRANSPARENT
    # Unlit emission: no light bounces are needed, only transparency.
    cy.max_bounces = 0
    for b in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(cy, b, 0)
    cy.use_denoising = False  # Debian's build has no OpenImageDenoise; keep it exact anyway
    cy.use_preview_denoising = False
    cy.filter_width = FILTER_WIDTH
    cy.device = "CPU"
    cy.seed = 0


# --- camera -----------------------------------------------------------------------------

def gltf_cameras(doc):
    """[(node name, camera index, extras.opencv or None)] in glTF camera order."""
    nodes = doc.get("nodes", [])
    out = []
    for ci, cam in enumerate(doc.get("cameras", [])):
        node = next((n for n in nodes if n.get("camera") == ci), None)
        if node is None:
            continue
        out.append((node.get("name"), ci, (cam.get("extras") or {}).get("opencv"), cam))
    return out


def pick_camera(doc, index):
    cams = gltf_cameras(doc)
    if not 0 <= index < len(cams):
        raise ValueError(f"camera {index}: the file has {len(cams)} camera(s)")
    name, ci, opencv, cam = cams[index]
    objs = [o for o in bpy.data.objects if o.type == "CAMERA"]
    ob = next((o for o in objs if name and o.name == name), None)
    if ob is None and len(objs) == len(cams):
        ob = objs[index]  # unnamed nodes: the importer creates cameras in file order
    if ob is None:
        raise ValueError(f"camera {index}: camera node {name!r} not found after import")
    return ob, opencv, cam


def setup_camera(scene, ob, opencv, cam, size):
    """Blender intrinsics equal to the OpenCV camera's (resized to `size` like `render`)."""
    data = ob.data
    if opencv:
        w0, h0 = int(opencv["width"]), int(opencv["height"])
        w, h = size or (w0, h0)
        sx, sy = w / w0, h / h0
        fx, fy = opencv["fx"] * sx, opencv["fy"] * sy
        cx, cy = opencv["cx"] * sx, opencv["cy"] * sy
    else:
        persp = cam.get("perspective", {})
        aspect = persp.get("aspectRatio") or 4 / 3
        w, h = size or (round(480 * aspect), 480)
        fy = h / 2 / math.tan(persp.get("yfov", 0.8) / 2)
        fx, cx, cy = fy, w / 2, h / 2
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    # Blender's view plane (BKE_camera_params_compute_viewplane) with a horizontal sensor fit:
    # the width spans sensor_width/lens, a pixel is ycor = aspect_y/aspect_x times as tall as
    # wide, and lens shift is in units of the image width. A pixel spans 1/fx by 1/fy, so
    # ycor = fx/fy (both aspects must be ≥ 1).
    ycor = fx / fy
    scene.render.pixel_aspect_x = max(1.0, 1.0 / ycor)
    scene.render.pixel_aspect_y = max(1.0, ycor)
    data.type = "PERSP"
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = 36.0
    data.lens = fx / w * data.sensor_width
    # OpenCV's y points down, Blender's up: a principal point below the centre shifts the
    # view plane down.
    data.shift_x = (w / 2 - cx) / w
    data.shift_y = (cy - h / 2) * ycor / w
    scene.camera = ob
    return {"name": ob.name, "width": w, "height": h, "fx": fx, "fy": fy, "cx": cx, "cy": cy}


# --- the scene --------------------------------------------------------------------------

def setup_scene(scene, doc, samples):
    """Everything but the camera; returns a report."""
    meta = (doc.get("asset", {}).get("extras") or {}).get("splatbridge") or {}
    # Files without our metadata follow glTF's rule: COLOR_0 is linear.
    encoding = meta.get("colorEncoding", "linear")
    encode = encoding != "display"
    mats = [setup_material(m, encode) for m in bpy.data.materials if m.users]
    for ob in scene.objects:
        if ob.type == "MESH" and hasattr(ob, "visible_shadow"):  # Blender 4.2+: per object
            ob.visible_shadow = False
    setup_colour_management(scene)
    setup_world(scene)
    setup_engines(scene, samples)
    return {"color_encoding": encoding, "materials": mats,
            "view_transform": scene.view_settings.view_transform,
            "transparent_max_bounces": scene.cycles.transparent_max_bounces,
            "samples": samples, "blender": bpy.app.version_string}
