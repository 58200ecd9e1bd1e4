# Type hints of the package fvr (the implementation: __init__.py over the extension _fvr).
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

Vec3 = Tuple[float, float, float]

def option_args(settings: dict) -> list[str]: ...

class Volume:
    def __init__(
        self,
        array: npt.ArrayLike,
        spacing: Sequence[float] = ...,
        origin: Sequence[float] = ...,
        direction: Sequence[Sequence[float]] = ...,
        units: str = ...,
        name: str = ...,
    ) -> None: ...
    @property
    def shape(self) -> Tuple[int, int, int]: ...
    @property
    def spacing(self) -> Vec3: ...
    @property
    def origin(self) -> Vec3: ...
    @property
    def direction(self) -> Tuple[Vec3, Vec3, Vec3]: ...
    @property
    def units(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def orientation_stated(self) -> bool: ...
    @property
    def array(self) -> npt.NDArray[np.float32]: ...
    @property
    def info(self) -> dict[str, Any]: ...

def load(path: str, series: Optional[str] = ..., **settings: Any) -> Volume: ...

Pair = Union[float, Tuple[float, float]]
Size = Union[int, Tuple[int, int]]

class Camera:
    def __init__(
        self,
        source: Sequence[float],
        detector_centre: Sequence[float],
        u: Sequence[float],
        v: Sequence[float],
        detector: Size,
        pitch: Pair,
        principal_point: Tuple[float, float] = ...,
    ) -> None: ...
    @classmethod
    def carm(
        cls,
        primary: float = ...,
        secondary: float = ...,
        sid: float = ...,
        sod: float = ...,
        isocenter: Optional[Sequence[float]] = ...,
        detector: Size = ...,
        pitch: Optional[Pair] = ...,
        principal_point: Tuple[float, float] = ...,
        volume: Optional[Volume] = ...,
    ) -> Camera: ...
    @classmethod
    def from_matrix(cls, matrix: Any, detector: Size, pitch: Any) -> Camera: ...
    @classmethod
    def read_matrix_file(cls, path: Any) -> List[Camera]: ...
    @classmethod
    def from_dicom(
        cls,
        path: Any,
        frame: int = ...,
        isocenter: Optional[Sequence[float]] = ...,
        volume: Optional[Volume] = ...,
    ) -> Camera: ...
    warnings: list[str]
    isocenter_from: Optional[str]
    @property
    def source(self) -> Vec3: ...
    @property
    def detector_centre(self) -> Vec3: ...
    @property
    def u(self) -> Vec3: ...
    @property
    def v(self) -> Vec3: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def pitch(self) -> Tuple[float, float]: ...
    @property
    def principal_point(self) -> Tuple[float, float]: ...
    @property
    def sid(self) -> float: ...
    @property
    def matrix(self) -> npt.NDArray[np.float64]: ...
    def project(self, points: npt.ArrayLike, depth: bool = ...) -> npt.NDArray[np.float64]: ...
    def pixel_centre(self, col: float, row: float) -> Vec3: ...
    def flat_field(self) -> npt.NDArray[np.float32]: ...

class Renderer:
    volume: Volume
    def __init__(
        self,
        volume: Volume,
        kernel: Optional[str] = ...,
        oversampling: Optional[float] = ...,
        values: Optional[str] = ...,
        voxel_model: Optional[str] = ...,
        threads: Optional[int] = ...,
        progress: Optional[Callable[[float, str], Any]] = ...,
        **settings: Any,
    ) -> None: ...
    @property
    def args(self) -> list[str]: ...
    def render(
        self,
        view: Optional[str] = ...,
        dir: Optional[Sequence[float]] = ...,
        up: Optional[Sequence[float]] = ...,
        size: Optional[int] = ...,
        pixel_size: Optional[float] = ...,
        camera: Optional[Camera] = ...,
        model: Optional[str] = ...,
        step: Optional[float] = ...,
    ) -> npt.NDArray[np.float32]: ...
    def render_many(
        self,
        views: Union[None, Sequence[str], Sequence[Camera], npt.ArrayLike] = ...,
        size: Optional[int] = ...,
        pixel_size: Optional[float] = ...,
        model: Optional[str] = ...,
        step: Optional[float] = ...,
    ) -> npt.NDArray[np.float32]: ...
    def camera(self, **carm: Any) -> Camera: ...
    def views(self, **settings: Any) -> npt.NDArray[np.float64]: ...
    @property
    def settings(self) -> dict[str, Any]: ...
    def transmission(
        self,
        image: npt.ArrayLike,
        energy_kev: Optional[float] = ...,
        mu_water: Optional[float] = ...,
        exposure: Optional[float] = ...,
    ) -> npt.NDArray[np.float32]: ...

def transmission(
    image: npt.ArrayLike,
    energy_kev: Optional[float] = ...,
    mu_water: Optional[float] = ...,
    exposure: Optional[float] = ...,
) -> npt.NDArray[np.float32]: ...
def film(
    image: npt.ArrayLike,
    energy_kev: Optional[float] = ...,
    mu_water: Optional[float] = ...,
    exposure: Optional[float] = ...,
    invert: bool = ...,
) -> npt.NDArray[np.float32]: ...
def read_xray(path: Any) -> npt.NDArray[np.float32]: ...
def run_cli(args: Sequence[str]) -> int: ...
def register(
    volume: Volume,
    images: Union[npt.ArrayLike, Sequence[npt.ArrayLike]],
    cameras: Union[Camera, Sequence[Camera]],
    init: Union[None, npt.ArrayLike, Dict[str, Sequence[float]]] = ...,
    similarity: str = ...,
    levels: Optional[Sequence[Sequence[float]]] = ...,
    global_samples: Optional[int] = ...,
    centre: Optional[Sequence[float]] = ...,
    threads: int = ...,
    masks: Optional[Sequence[npt.ArrayLike]] = ...,
    coverage_mask: bool = ...,
    detector_blur: float = ...,
    progress: Optional[Callable[[str, int, float], None]] = ...,
) -> Dict[str, Any]: ...
