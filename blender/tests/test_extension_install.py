"""The packaged extension end to end, as a user installs it: `scripts/blender-extension.sh`
builds target/blender/splatbridge-VERSION.zip with the wheel bundled; a fresh Blender (the
`bpy` module, its user folder in a temporary directory) installs it through Blender's own
extension installer, enables it, and imports the street through the registered operator
using the splatbridge package Blender unpacked from the bundled wheel, not the one the test
environment has."""
import os
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("bpy")

from conftest import ROOT  # noqa: E402

STREET = ROOT / "fixtures" / "street" / "scene.json"

# Runs in a child process: Blender's user folder is fixed when bpy is first imported.
CHILD = textwrap.dedent("""
    import json, sys
    import bpy
    zip_path, street = sys.argv[1], sys.argv[2]
    r = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                 enable_on_install=True)
    assert r == {"FINISHED"}, r
    # Hide the test environment's own splatbridge: the import must use the bundled wheel.
    sys.path[:] = [p for p in sys.path if not (p.endswith("site-packages") and "extensions" not in p)]
    sys.modules.pop("splatbridge", None)
    r = bpy.ops.import_scene.gaussian_splats(filepath=street, samples=4)
    import splatbridge
    print("RESULT " + json.dumps({
        "import": sorted(r),
        "addons": sorted(bpy.context.preferences.addons.keys()),
        "package": splatbridge.__file__,
        "meshes": sum(o.type == "MESH" for o in bpy.context.scene.objects),
        "cameras": sum(o.type == "CAMERA" for o in bpy.context.scene.objects),
        "animated": sum(bool(o.animation_data and o.animation_data.action)
                        for o in bpy.context.scene.objects),
    }))
""")


def test_packaged_extension_installs_and_imports(tmp_path):
    wheels = sorted((ROOT / "target" / "wheels").glob("splatbridge-*.whl"))
    if not wheels:
        pytest.skip("no wheel in target/wheels (scripts/python-wheel.sh builds it)")
    out = subprocess.run([str(ROOT / "scripts" / "blender-extension.sh"), str(wheels[-1])],
                         check=True, capture_output=True, text=True).stdout.split()[0]
    user = tmp_path / "user"
    user.mkdir()
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(user))
    child = subprocess.run([sys.executable, "-c", CHILD, out, str(STREET)], env=env,
                           capture_output=True, text=True, timeout=600)
    line = [ln for ln in child.stdout.splitlines() if ln.startswith("RESULT ")]
    assert child.returncode == 0 and line, child.stdout[-2000:] + child.stderr[-2000:]
    import json
    got = json.loads(line[-1][len("RESULT "):])
    assert got["import"] == ["FINISHED"]
    assert "bl_ext.user_default.splatbridge_import" in got["addons"]
    # The package came from the wheel Blender unpacked into its extensions' site-packages.
    assert str(user / "extensions") in got["package"], got["package"]
    assert got["meshes"] >= 1 and got["cameras"] >= 1 and got["animated"] >= 2, got
