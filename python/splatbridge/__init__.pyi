"""Type stubs of splatbridge (the extension module ``splatbridge._native``)."""

from os import PathLike
from typing import Any, Literal, Mapping, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "PathLike[str]"]
_Image = npt.NDArray[np.float32]
_Channels = Literal["rgb", "rgba", "rgbaz"]

class Error(Exception):
    """A splatbridge call failed; the message is the CLI's (after ``error: ``)."""

class Camera:
    """A pinhole camera, OpenCV frame (x right, y down, z forward)."""

    def __init__(
        self,
        world_to_camera: npt.ArrayLike,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width: int,
        height: int,
        name: str = "camera",
    ) -> None: ...
    @overload
    @staticmethod
    def from_json(path: _Path, index: None = None) -> list[Camera]: ...
    @overload
    @staticmethod
    def from_json(path: _Path, index: int) -> Camera: ...
    @property
    def world_to_camera(self) -> npt.NDArray[np.float64]: ...
    @property
    def fx(self) -> float: ...
    @property
    def fy(self) -> float: ...
    @property
    def cx(self) -> float: ...
    @property
    def cy(self) -> float: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def centre(self) -> Tuple[float, float, float]: ...
    @property
    def name(self) -> str: ...
    def resized(self, width: int, height: int) -> Camera: ...

_CameraArg = Union[Camera, str]

class Scene:
    """A Gaussian scene; array attributes are read-only views of the static cloud."""

    @property
    def kind(self) -> Literal["3dgs", "2dgs", "points"]:
        """What the Gaussians are, as read (2DGS surfels stay surfels in save and convert)."""
    @property
    def means(self) -> npt.NDArray[np.float32]:
        """(N, 3) positions."""
    @property
    def log_scales(self) -> npt.NDArray[np.float32]:
        """(N, 3) natural log of the standard deviations."""
    @property
    def rotations(self) -> npt.NDArray[np.float32]:
        """(N, 4) quaternions w, x, y, z as stored (a copy)."""
    @property
    def opacities(self) -> npt.NDArray[np.float32]:
        """(N,) opacity logits."""
    @property
    def sh(self) -> npt.NDArray[np.float32]:
        """(N, (degree+1)², 3) SH coefficients, DC first."""
    @property
    def sh_degree(self) -> int: ...
    @property
    def is_dynamic(self) -> bool: ...
    @property
    def time_range(self) -> Tuple[float, float, float]: ...
    @property
    def frame_times(self) -> list[float]: ...
    @property
    def cameras(self) -> list[Camera]: ...
    @property
    def name(self) -> str: ...
    def __len__(self) -> int: ...
    def composite(self, time: float) -> Scene: ...
    def camera(self, spec: str, width: Optional[int] = None, height: Optional[int] = None, *,
               time: Optional[float] = None) -> Camera:
        """The camera a spec names for this scene, resolved once (orbits frame the scene)."""

    @staticmethod
    def from_arrays(
        means: npt.ArrayLike,
        log_scales: npt.ArrayLike,
        rotations: npt.ArrayLike,
        opacities: npt.ArrayLike,
        sh: npt.ArrayLike,
    ) -> Scene: ...

def load(path: _Path, *, drop_invalid: bool = False) -> Scene:
    """Load any format the CLI reads. ``scene = splatbridge.load("scene.ply")``"""

def save(scene: Scene, path: _Path, *, time: Optional[float] = None, spz_version: Optional[int] = None) -> int:
    """Write splats (.ply, .compressed.ply, .splat, .spz, .ksplat, .glb, .gltf); returns bytes."""

def render(
    scene: Scene,
    camera: _CameraArg = "orbit:8:0",
    width: Optional[int] = None,
    height: Optional[int] = None,
    *,
    time: Optional[float] = None,
    background: Tuple[float, float, float] = (0.0, 0.0, 0.0),
    near: float = 0.2,
    extent: Literal["sigma3", "alpha"] = "sigma3",
    alpha_clamp: float = 0.99,
    sh_degree: int = 3,
    channels: _Channels = "rgb",
) -> _Image:
    """Native splatting. ``img = splatbridge.render(scene, "orbit:8:0", 640, 480)``"""

def hybrid(
    scene: Scene,
    camera: _CameraArg = "orbit:8:0",
    width: Optional[int] = None,
    height: Optional[int] = None,
    *,
    time: Optional[float] = None,
    background: Tuple[float, float, float] = (0.0, 0.0, 0.0),
    near: float = 0.2,
    sh_degree: int = 3,
    channels: _Channels = "rgb",
) -> _Image:
    """The GES hybrid. ``img = splatbridge.hybrid(scene, "orbit:8:0", 640, 480)``"""

def trace(
    scene: Union[Scene, _Path],
    camera: _CameraArg = "orbit:8:0",
    width: Optional[int] = None,
    height: Optional[int] = None,
    *,
    time: float = 0.0,
    mode: Optional[Literal["gaussian", "mesh"]] = None,
    profile: Optional[Literal["meshsplats", "rings", "texture"]] = None,
    backend: Literal["obvhs", "embree"] = "obvhs",
    k: int = 16,
    background: Tuple[float, float, float] = (0.0, 0.0, 0.0),
    near: float = 0.2,
    channels: _Channels = "rgb",
) -> _Image:
    """The BVH ray tracer. ``img = splatbridge.trace(scene, "orbit:8:0", 640, 480)``"""

def save_image(image: npt.ArrayLike, path: _Path) -> None:
    """Write a render as the CLI's -o does (.png or .exr)."""

def convert(
    scene: Scene,
    path: _Path,
    *,
    profile: Optional[Literal["meshsplats", "rings", "texture"]] = None,
    distill: Union[None, bool, Mapping[str, Any]] = None,
    splats: bool = False,
    up: Literal["-y", "y", "z"] = "-y",
    color_encoding: Literal["linear", "display"] = "linear",
) -> dict[str, Any]:
    """``splatbridge convert``. ``splatbridge.convert(scene, "scene.glb", profile="texture")``"""

def compare(
    scene: Scene,
    cameras: Union[str, Sequence[_CameraArg]] = "orbit:4",
    *,
    times: Optional[Sequence[float]] = None,
    profiles: Sequence[str] = ("meshsplats", "rings", "texture"),
    width: int = 320,
    height: int = 240,
    backend: Literal["obvhs", "embree"] = "obvhs",
    k: int = 16,
    obj: bool = True,
    out: Optional[_Path] = None,
) -> dict[str, Any]:
    """``splatbridge compare``; returns report.json. ``splatbridge.compare(scene, "orbit:4")``"""
