"""Type stubs of vmerge's compiled module."""

from os import PathLike
from pathlib import Path
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_Duration = Union[float, int, str]
_Image = Union[npt.NDArray[np.float32], npt.NDArray[np.float64], "Result", _Path]
_Trace = Union[str, Tuple[int, int, int]]

__version__: str
TECHNIQUES: List[str]

class SceneError(ValueError):
    """A scene file that cannot be rendered: the message names the file and the entry."""

class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped a render at the end of an iteration."""

    result: "Result"

class Scene:
    @property
    def path(self) -> Path: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def resolution(self) -> Tuple[int, int]: ...
    @property
    def cameras(self) -> List[str]: ...
    @property
    def triangles(self) -> int: ...
    @property
    def lights(self) -> int: ...
    @property
    def default_radius(self) -> float: ...
    @property
    def accel(self) -> str: ...

class Result:
    @property
    def image(self) -> npt.NDArray[np.float32]: ...
    @property
    def sums(self) -> npt.NDArray[np.float64]: ...
    @property
    def iterations(self) -> int: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def seconds(self) -> float: ...
    @property
    def metadata(self) -> Dict[str, Any]: ...
    @property
    def statistics(self) -> Dict[str, Union[int, float, str]]: ...
    @property
    def errors(self) -> Dict[str, npt.NDArray[Any]]: ...
    def write(self, path: _Path, png: bool = False) -> None: ...

class Step:
    @property
    def image(self) -> npt.NDArray[np.float32]: ...
    iterations: int
    seconds: float
    rmse: Optional[float]
    samples_per_second: float
    rays_per_second: float

class Progressive(Iterator[Step]):
    def __iter__(self) -> "Progressive": ...
    def __next__(self) -> Step: ...
    @property
    def result(self) -> Optional[Result]: ...
    def stop(self) -> None: ...
    def finish(self) -> Result: ...

def load_scene(path: _Path, lenient: bool = False, accel: Optional[str] = None) -> Scene: ...
def render(
    scene: Scene,
    technique: Optional[str] = None,
    *,
    iterations: Optional[int] = None,
    time: Optional[_Duration] = None,
    cpu_time: Optional[_Duration] = None,
    output: Optional[_Path] = None,
    png: bool = False,
    reference: Optional[_Path] = None,
    traces: Optional[List[_Trace]] = None,
    snapshot: Optional[_Duration] = None,
    memory_limit: Optional[int] = None,
    **options: Any,
) -> Result: ...
def render_progressive(
    scene: Scene,
    technique: Optional[str] = None,
    *,
    every: int = 1,
    iterations: Optional[int] = None,
    time: Optional[_Duration] = None,
    cpu_time: Optional[_Duration] = None,
    output: Optional[_Path] = None,
    png: bool = False,
    reference: Optional[_Path] = None,
    traces: Optional[List[_Trace]] = None,
    snapshot: Optional[_Duration] = None,
    memory_limit: Optional[int] = None,
    **options: Any,
) -> Progressive: ...
def continue_render(
    render: Union[Result, _Path],
    *,
    iterations: Optional[int] = None,
    time: Optional[_Duration] = None,
    cpu_time: Optional[_Duration] = None,
    output: Optional[_Path] = None,
    png: bool = False,
    force: bool = False,
    accel: Optional[str] = None,
    snapshot: Optional[_Duration] = None,
    memory_limit: Optional[int] = None,
) -> Result: ...
def option_names() -> List[str]: ...
def set_threads(threads: int) -> None: ...
def read(path: _Path) -> Result: ...
def read_image(path: _Path) -> npt.NDArray[np.float32]: ...
def write_image(path: _Path, image: npt.NDArray[np.float32]) -> None: ...
def merge(renders: Sequence[Union[Result, _Path]], output: Optional[_Path] = None) -> Result: ...
def errors(image: _Image, reference: _Image, pointwise: bool = False) -> Dict[str, float]: ...
def measure_names() -> List[str]: ...
def run_batch(plan: _Path, accel: Optional[str] = None) -> int: ...
def batch_report(plan: _Path) -> Path: ...
