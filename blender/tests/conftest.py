"""The Blender extension's tests run in the `bpy` module (Blender as a Python module, from
PyPI) with the extension's folder importable as the package `splatbridge_import`."""
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "blender"))
sys.path.insert(0, str(ROOT / "python" / "tests"))
