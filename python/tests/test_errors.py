"""Bad input raises splatbridge.Error with the CLI's message (its `error: ` line without the
prefix), never crashes the interpreter."""
import numpy as np
import pytest

import splatbridge
from conftest import ROOT, cli

MALFORMED = sorted((ROOT / "fixtures" / "malformed").glob("*.ply"))


def cli_error(*args):
    r = cli(*args, check=False)
    assert r.returncode == 2, r.stderr
    line = [l for l in r.stderr.splitlines() if l.startswith("error: ")][0]
    return line[len("error: "):]


@pytest.mark.parametrize("path", MALFORMED[:12], ids=lambda p: p.name)
def test_malformed_files_raise_the_clis_message(path):
    with pytest.raises(splatbridge.Error) as e:
        splatbridge.load(str(path))
    assert str(e.value) == cli_error("info", path)


def test_missing_file(tmp_path):
    missing = tmp_path / "missing.ply"
    with pytest.raises(splatbridge.Error) as e:
        splatbridge.load(str(missing))
    assert str(e.value) == cli_error("info", missing)


def test_bad_options_raise(small, tmp_path):
    scene = splatbridge.load(str(small))
    with pytest.raises(splatbridge.Error) as e:
        splatbridge.render(scene, "orbit:8:9", 32, 24)
    assert "orbit:8:9" in str(e.value)
    with pytest.raises(splatbridge.Error, match="unknown profile"):
        splatbridge.convert(scene, tmp_path / "x.glb", profile="cubes")
    with pytest.raises(splatbridge.Error) as e:
        splatbridge.convert(scene, tmp_path / "x.splat", distill=True)
    assert not (tmp_path / "x.splat").exists()
    with pytest.raises(splatbridge.Error, match="outside"):
        splatbridge.render(scene, "orbit:8:0", 0, 24)
    with pytest.raises(splatbridge.Error):
        splatbridge.save(scene, tmp_path / "x.jpg")
    with pytest.raises(splatbridge.Error, match="shape"):
        splatbridge.Camera(np.eye(3), 100, 100, 16, 12, 32, 24)
    with pytest.raises(splatbridge.Error):
        splatbridge.Camera(np.diag([1.0, 1.0, 1.0, 1.0]) * 2, 100, 100, 16, 12, 32, 24)
    with pytest.raises(splatbridge.Error, match="channels"):
        splatbridge.save_image(np.zeros((4, 4, 2), np.float32), tmp_path / "x.png")
