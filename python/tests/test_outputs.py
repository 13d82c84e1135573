"""Outputs equal the CLI's byte for byte: splat files, glTF splats and meshes, and images of
every renderer (PNG, and EXR for the float planes)."""
import json

import numpy as np
import pytest

import splatbridge
from conftest import STREET, STREET_CAMERAS, cli


@pytest.mark.parametrize("ext", [".ply", ".compressed.ply", ".splat", ".spz", ".ksplat"])
def test_save_writes_the_clis_splat_files(small, tmp_path, ext):
    scene = splatbridge.load(small)
    ours, theirs = tmp_path / f"py{ext}", tmp_path / f"cli{ext}"
    n = splatbridge.save(scene, ours)
    cli("convert", small, "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    assert n == theirs.stat().st_size


def test_save_glb_is_convert_splats(small, tmp_path):
    scene = splatbridge.load(str(small))
    splatbridge.save(scene, tmp_path / "py.glb")
    cli("convert", small, "--splats", "-o", tmp_path / "cli.glb")
    assert (tmp_path / "py.glb").read_bytes() == (tmp_path / "cli.glb").read_bytes()


@pytest.mark.parametrize("profile,ext", [(None, ".glb"), ("rings", ".glb"), ("meshsplats", ".obj"), ("rings", ".ply")])
def test_convert_writes_the_clis_meshes(small, tmp_path, profile, ext):
    scene = splatbridge.load(str(small))
    # One name in two folders: an OBJ names its .mtl.
    (tmp_path / "py").mkdir()
    (tmp_path / "cli").mkdir()
    ours, theirs = tmp_path / "py" / f"out{ext}", tmp_path / "cli" / f"out{ext}"
    report = splatbridge.convert(scene, ours, profile=profile)
    args = ["convert", small, "-o", theirs, "--json"] + (["--profile", profile] if profile else [])
    expected = json.loads(cli(*args).stdout)
    assert ours.read_bytes() == theirs.read_bytes()
    assert report["triangles"] == expected["triangles"]


def test_convert_of_a_dynamic_scene_with_cameras(tmp_path):
    scene = splatbridge.load(str(STREET))
    splatbridge.convert(scene, tmp_path / "py.glb", cameras="orbit:2")
    cli("convert", STREET, "-o", tmp_path / "cli.glb", "--camera", "orbit:2")
    assert (tmp_path / "py.glb").read_bytes() == (tmp_path / "cli.glb").read_bytes()


CAM = ["--camera", "orbit:8:1", "--width", "96", "--height", "72"]


@pytest.mark.parametrize("fn,command,extra", [
    (splatbridge.render, "render", []),
    (splatbridge.hybrid, "hybrid", []),
    (splatbridge.trace, "trace", ["--mode", "gaussian"]),
])
def test_images_equal_the_clis(small, tmp_path, fn, command, extra):
    scene = splatbridge.load(str(small))
    img = fn(scene, "orbit:8:1", 96, 72)
    assert img.shape == (72, 96, 3) and img.dtype == np.float32
    splatbridge.save_image(img, tmp_path / "py.png")
    cli(command, small, *CAM, *extra, "-o", tmp_path / "cli.png")
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()


def test_float_planes_equal_the_clis_exr(small, tmp_path):
    scene = splatbridge.load(str(small))
    img = splatbridge.render(scene, "orbit:8:1", 96, 72, channels="rgbaz", background=(0.1, 0.2, 0.3))
    assert img.shape == (72, 96, 5)
    splatbridge.save_image(img, tmp_path / "py.exr")
    cli("render", small, *CAM, "--background", "0.1,0.2,0.3", "-o", tmp_path / "cli.exr")
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()


def test_trace_of_an_export_equals_the_clis(small, tmp_path):
    glb = tmp_path / "mesh.glb"
    cli("convert", small, "-o", glb, "--camera", "orbit:8:1")
    img = splatbridge.trace(str(glb), "scene:0", 96, 72)
    splatbridge.save_image(img, tmp_path / "py.png")
    cli("trace", glb, "--camera", "scene:0", "--width", "96", "--height", "72", "-o", tmp_path / "cli.png")
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()


def test_cameras_from_training_code_equal_the_json_spec(tmp_path):
    """A 3DGS cameras.json camera, as Camera.from_json and as an OpenCV 4×4 with intrinsics,
    renders the CLI's image of `--camera cameras.json:0` (the dynamic street, at a time)."""
    scene = splatbridge.load(str(STREET))
    cam = splatbridge.Camera.from_json(STREET_CAMERAS, 0)
    w2c = cam.world_to_camera
    assert w2c.shape == (4, 4)
    np.testing.assert_allclose(w2c[:3, :3] @ w2c[:3, :3].T, np.eye(3), atol=1e-12)
    again = splatbridge.Camera(w2c, cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)
    np.testing.assert_allclose(again.centre, cam.centre, rtol=0, atol=1e-9)
    cli("render", STREET, "--camera", f"{STREET_CAMERAS}:0", "--width", "80", "--height", "60",
        "--time", "1.5", "-o", tmp_path / "cli.png")
    for i, c in enumerate([cam, again, f"{STREET_CAMERAS}:0"]):
        img = splatbridge.render(scene, c, 80, 60, time=1.5)
        splatbridge.save_image(img, tmp_path / f"py{i}.png")
        assert (tmp_path / f"py{i}.png").read_bytes() == (tmp_path / "cli.png").read_bytes(), i


def test_compare_returns_the_clis_figures(small, tmp_path):
    scene = splatbridge.load(str(small))
    report = splatbridge.compare(scene, "orbit:2", profiles=["texture"], width=64, height=48,
                                 obj=False, out=tmp_path / "py")
    cli("compare", small, "--cameras", "orbit:2", "--profiles", "texture", "--width", "64",
        "--height", "48", "--no-obj", "-o", tmp_path / "cli")
    theirs = json.loads((tmp_path / "cli" / "report.json").read_text())

    def figures(records):
        return [(r["renderer"], r["profile"], r["format"], r["camera"], r["psnr"], r["ssim"])
                for r in records]

    assert figures(report["records"]) == figures(theirs)
    assert len(theirs) >= 4


def write_2dgs_ply(path, scene):
    """A 2DGS PLY (two scales, no third; SH degree 0) of `scene`'s first Gaussians, written
    with NumPy as 2DGS's `save_ply` lays it out."""
    n = 500
    means, ls = scene.means[:n], scene.log_scales[:n]
    rot, op, dc = scene.rotations[:n], scene.opacities[:n], scene.sh[:n, 0, :]
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "rot_0", "rot_1", "rot_2", "rot_3"]
    cols = np.concatenate([means, np.zeros((n, 3), np.float32), dc, op[:, None], ls[:, :2], rot],
                          axis=1).astype("<f4")
    header = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n
    header += "".join(f"property float {p}\n" for p in names) + "end_header\n"
    path.write_bytes(header.encode() + cols.tobytes())


@pytest.mark.parametrize("ext", [".ply", ".glb"])
def test_2dgs_surfels_stay_surfels_as_the_cli_keeps_them(small, tmp_path, ext):
    src = tmp_path / "surfels.ply"
    write_2dgs_ply(src, splatbridge.load(small))
    scene = splatbridge.load(src)
    assert scene.kind == "2dgs"
    ours, theirs = tmp_path / f"py{ext}", tmp_path / f"cli{ext}"
    if ext == ".ply":
        # save: a 2DGS PLY again (two scales), the bytes of `convert IN -o OUT.ply`.
        splatbridge.save(scene, ours)
        header = ours.read_bytes().split(b"end_header")[0]
        assert b"scale_1" in header and b"scale_2" not in header
    else:
        # convert: fans in the surfels' plane, the bytes of `convert IN -o OUT.glb`.
        splatbridge.convert(scene, ours)
    cli("convert", src, "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    # A 3D scene made from the same arrays is not a surfel scene.
    assert splatbridge.load(small).kind == "3dgs"
