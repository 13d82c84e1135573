"""Scenes as arrays: shapes, zero-copy read-only views, values against an independent
NumPy parse of the PLY (the slow reference of the views), and from_arrays."""
import numpy as np
import pytest

import splatbridge
from conftest import STREET


def parse_ply(path):
    """A binary little-endian 3DGS PLY parsed with NumPy alone (float properties only)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    names, n = [], 0
    for line in data[:end].decode().splitlines():
        parts = line.split()
        if parts[:2] == ["element", "vertex"]:
            n = int(parts[2])
        elif parts[:2] == ["property", "float"]:
            names.append(parts[2])
    rec = np.frombuffer(data[end:], dtype=np.dtype([(k, "<f4") for k in names]), count=n)
    return rec


def test_arrays_match_an_independent_parse_of_the_ply(small):
    scene = splatbridge.load(small)
    rec = parse_ply(small)
    n = len(rec)
    assert len(scene) == n == 3000
    np.testing.assert_array_equal(scene.means, np.stack([rec["x"], rec["y"], rec["z"]], 1))
    np.testing.assert_array_equal(
        scene.log_scales, np.stack([rec[f"scale_{i}"] for i in range(3)], 1))
    np.testing.assert_array_equal(
        scene.rotations, np.stack([rec[f"rot_{i}"] for i in range(4)], 1))
    np.testing.assert_array_equal(scene.opacities, rec["opacity"])
    assert scene.sh_degree == 3 and scene.sh.shape == (n, 16, 3)
    np.testing.assert_array_equal(scene.sh[:, 0], np.stack([rec[f"f_dc_{i}"] for i in range(3)], 1))
    # f_rest is channel-major in the PLY: 15 red coefficients, then green, then blue.
    rest = np.stack([rec[f"f_rest_{i}"] for i in range(45)], 1).reshape(n, 3, 15)
    np.testing.assert_array_equal(scene.sh[:, 1:], rest.transpose(0, 2, 1))


def test_views_share_the_scene_memory_and_are_read_only(small):
    scene = splatbridge.load(small)
    for name in ("means", "log_scales", "opacities", "sh"):
        a, b = getattr(scene, name), getattr(scene, name)
        assert a.dtype == np.float32 and a.flags.c_contiguous
        # Two reads are views of one buffer: no copy was made.
        assert np.shares_memory(a, b), name
        assert not a.flags.writeable, name
        with pytest.raises(ValueError):
            a[0] = 1.0
    means = scene.means
    del scene  # the view keeps the scene alive
    assert np.isfinite(means).all()


def test_from_arrays_round_trips_and_checks_its_input(small, tmp_path):
    scene = splatbridge.load(small)
    again = splatbridge.Scene.from_arrays(
        scene.means, scene.log_scales, scene.rotations, scene.opacities, scene.sh)
    splatbridge.save(again, tmp_path / "again.ply")
    assert (tmp_path / "again.ply").read_bytes() == small.read_bytes()
    # Degree 0 as (N, 3); float64 input is accepted (converted).
    dc = splatbridge.Scene.from_arrays(
        scene.means.astype(np.float64), scene.log_scales, scene.rotations, scene.opacities,
        scene.sh[:, 0])
    assert dc.sh_degree == 0
    bad = scene.means.copy()
    bad[7, 1] = np.nan
    with pytest.raises(splatbridge.Error, match="Gaussian 7"):
        splatbridge.Scene.from_arrays(bad, scene.log_scales, scene.rotations, scene.opacities, scene.sh)
    with pytest.raises(splatbridge.Error, match="rotations has shape"):
        splatbridge.Scene.from_arrays(
            scene.means, scene.log_scales, scene.rotations[:, :3], scene.opacities, scene.sh)
    with pytest.raises(splatbridge.Error, match="coefficients per channel"):
        splatbridge.Scene.from_arrays(
            scene.means, scene.log_scales, scene.rotations, scene.opacities, scene.sh[:, :5])


def test_a_dynamic_scene_has_its_time_range_cameras_and_composites():
    scene = splatbridge.load(STREET)
    assert scene.is_dynamic
    start, end, fps = scene.time_range
    assert end > start and fps > 0
    assert len(scene.cameras) >= 1
    frame = scene.composite(0.5 * (start + end))
    assert not frame.is_dynamic and len(frame) == len(scene)
    # Objects move: the composite differs between two times.
    other = scene.composite(start)
    assert not np.array_equal(frame.means, other.means)
