"""vmerge: a physically based renderer (PT, LT, BPT, PPM, BPM, VCM, UPG) driven from Python.

    import vmerge
    scene = vmerge.load_scene("scenes/cornell-box/scene.toml")
    result = vmerge.render(scene, "vcm", iterations=64, radius=0.01, resolution=(256, 256))
    result.image        # float32 numpy array, shape (height, width, 3)

Every render option of the command line is a keyword argument of `render` and
`render_progressive` (`vmerge.option_names()` lists them), validated as the command line
validates it.
"""

from ._vmerge import (
    TECHNIQUES,
    Interrupted,
    Progressive,
    Result,
    Scene,
    SceneError,
    Step,
    __version__,
    batch_report,
    continue_render,
    errors,
    load_scene,
    measure_names,
    merge,
    option_names,
    read,
    read_image,
    render,
    render_progressive,
    run_batch,
    set_threads,
    write_image,
)

__all__ = [
    "TECHNIQUES",
    "Interrupted",
    "Progressive",
    "Result",
    "Scene",
    "SceneError",
    "Step",
    "__version__",
    "batch_report",
    "continue_render",
    "errors",
    "load_scene",
    "measure_names",
    "merge",
    "option_names",
    "read",
    "read_image",
    "render",
    "render_progressive",
    "run_batch",
    "set_threads",
    "write_image",
]
