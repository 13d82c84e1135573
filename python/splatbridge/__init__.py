"""splatbridge: trained Gaussian splatting scenes as NumPy arrays.

Load any splat format, render it with native 3DGS splatting, the BVH ray tracer or the
surfel hybrid, convert it to meshes or other splat files, and measure every export against
native splatting::

    import splatbridge
    scene = splatbridge.load("scene.ply")
    image = splatbridge.render(scene, "orbit:8:0", 640, 480)   # (480, 640, 3) float32

Every function calls the library the ``splatbridge`` command line calls: the same options,
defaults, outputs (byte for byte) and error messages (raised as :class:`Error`). Long calls
release the GIL and stop on Ctrl-C.
"""

from ._native import (
    Camera,
    Error,
    Scene,
    __version__,
    compare,
    convert,
    hybrid,
    load,
    render,
    save,
    save_image,
    trace,
)

__all__ = [
    "Camera",
    "Error",
    "Scene",
    "__version__",
    "compare",
    "convert",
    "hybrid",
    "load",
    "render",
    "save",
    "save_image",
    "trace",
]
