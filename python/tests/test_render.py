"""Renders from Python against the command line: the same image bit for bit, every option
recorded as given, the command line's refusals, progressive rendering, continue and merge."""

import math
import re

import numpy as np
import pytest

import vmerge
from conftest import CAUSTIC, SCENE, cli_error

SMALL = dict(resolution=(24, 16), seed=7)


@pytest.fixture(scope="module")
def scene():
    return vmerge.load_scene(SCENE)


def as_flags(message):
    """A library message as the command line spells it: `upg_packet` as --upg-packet."""
    return re.sub(r"`([a-z0-9_]+)`", lambda m: "--" + m.group(1).replace("_", "-"), message)


def exact(a, b):
    return a.iterations == b.iterations and np.array_equal(a.sums, b.sums)


@pytest.mark.parametrize(
    "technique, options, flags",
    [
        ("pt", {}, []),
        ("bpt", {"beta": 1.0}, ["--beta", "1"]),
        ("vcm", {"radius": 0.02}, ["--radius", "0.02"]),
        ("upg", {"upg_packet": 8, "sampler": "independent"},
         ["--upg-packet", "8", "--sampler", "independent"]),
    ],
)
def test_a_render_equals_the_command_lines_bit_for_bit(tmp_path, cli, scene, technique, options, flags):
    result = vmerge.render(scene, technique, iterations=3, **SMALL, **options)
    out = tmp_path / "cli.exr"
    cli("render", SCENE, "-t", technique, "-n", 3, "--seed", 7, "--resolution", "24x16",
        *flags, "-o", out, "--no-png")
    expected = vmerge.read(out)
    assert result.image.dtype == np.float32 and result.image.shape == (16, 24, 3)
    assert exact(result, expected)
    assert np.array_equal(result.image, expected.image)
    assert np.array_equal(result.image, vmerge.read_image(out))
    assert result.metadata["options"] == expected.metadata["options"]
    assert result.metadata["scene_hash"] == expected.metadata["scene_hash"]


# One value other than the default for every option, with a technique that takes it.
EXAMPLES = {
    "technique": ("bpt", "bpt"),
    "seed": ("pt", 12345),
    "camera": ("pt", "floor"),
    "resolution": ("pt", (20, 12)),
    "beta": ("bpt", 1.0),
    "radius": ("vcm", 0.02),
    "radius_pixels": ("vcm", 1.5),
    "alpha": ("vcm", 0.5),
    "max_path_length": ("pt", 5),
    "roulette": ("pt", 4),
    "min_path_length": ("bpt", 2),
    "light_paths": ("vcm", 100),
    "no_vc": ("vcm", True),
    "no_vm": ("vcm", True),
    "strategy": ("bpt", (1, 2)),
    "unweighted": ("bpt", True),
    "upg_packet": ("upg", 8),
    "upg_max_trials": ("upg", 500),
    "blend_near": ("vcm-upg", 2.0),
    "blend_far": ("vcm-upg", 8.0),
    "hybrid_roughness": ("upg-hybrid", 0.3),
    "sampler": ("pt", "independent"),
    "no_shading_normals": ("pt", True),
    "density_mis": ("vcm", "vcm+"),
    "density_map_iterations": ("vcm", 3),
    "memory": ("vcm", "one-stage"),
}


def test_every_option_has_an_example():
    assert sorted(EXAMPLES) == sorted(vmerge.option_names())


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_every_option_round_trips_through_a_render(scene, name):
    technique, value = EXAMPLES[name]
    options = {"resolution": (12, 8), name: value}
    options.setdefault("technique", technique)
    result = vmerge.render(scene, iterations=1, **options)
    recorded = result.metadata["options"][name]
    if isinstance(value, float):
        assert recorded == pytest.approx(value, rel=1e-6)
    else:
        assert recorded == value
    # Every other option kept its default.
    default = vmerge.render(scene, technique, iterations=1, resolution=(12, 8)).metadata["options"]
    for other, v in result.metadata["options"].items():
        if other not in (name, "technique", "resolution"):
            assert v == default[other], other


@pytest.mark.parametrize(
    "technique, options, flags",
    [
        ("upg", {"upg_packet": 3}, ["--upg-packet", "3"]),
        ("pt", {"radius": 0.1}, ["--radius", "0.1"]),
        ("vcm", {"alpha": 1.5}, ["--alpha", "1.5"]),
        ("bpt", {"strategy": (0, 1)}, ["--strategy", "0,1"]),
        ("vcm", {"no_vm": True, "density_mis": "vcm*"}, ["--no-vm", "--density-mis", "vcm*"]),
    ],
)
def test_a_bad_option_raises_the_command_lines_message(tmp_path, cli, scene, technique, options, flags):
    with pytest.raises(ValueError) as raised:
        vmerge.render(scene, technique, iterations=1, **options)
    done = cli("render", SCENE, "-t", technique, "-n", 1, *flags, "-o", tmp_path / "x.exr",
               check=False)
    assert as_flags(str(raised.value)) == cli_error(done)
    assert f"`{next(iter(options))}`" in str(raised.value) or "`density_mis`" in str(raised.value)


@pytest.mark.parametrize(
    "name, value, flag, text",
    [
        ("resolution", "0x5", "0x5", "'0x5' has a zero side"),
        ("roulette", -1, "-1", "is not in 0..="),
        ("sampler", "sobolx", "sobolx", None),
        ("technique", "vmc", "vmc", None),
    ],
)
def test_an_unreadable_value_names_the_option(tmp_path, cli, scene, name, value, flag, text):
    with pytest.raises(ValueError) as raised:
        vmerge.render(scene, iterations=1, **{name: value})
    message = str(raised.value)
    assert message.startswith(f"`{name}` ")
    done = cli("render", SCENE, "-n", 1, "--" + name.replace("_", "-") + "=" + flag,
               "-o", tmp_path / "x.exr", check=False)
    assert done.returncode == 2
    if text is not None:
        assert text in message and text in done.stderr


def test_unknown_keywords_and_wrong_types_raise_type_errors(scene):
    with pytest.raises(TypeError, match="radiuss"):
        vmerge.render(scene, iterations=1, radiuss=0.1)
    with pytest.raises(TypeError, match="`no_vc`"):
        vmerge.render(scene, "vcm", iterations=1, no_vc=1)
    with pytest.raises(ValueError, match="iterations"):
        vmerge.render(scene, iterations=0)
    with pytest.raises(ValueError, match="say when to stop"):
        vmerge.render(scene)


BAD_SCENES = {
    "missing mesh": '[[camera]]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nup = [0, 1, 0]\n'
                    'fov = 40.0\n[[mesh]]\nfile = "nowhere.obj"\n',
    "bad number": '[[camera]]\nposition = [0, 1, "x"]\nlook_at = [0, 1, 0]\nup = [0, 1, 0]\n'
                  'fov = 40.0\n',
    "no lights": '[[camera]]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nup = [0, 1, 0]\n'
                 'fov = 40.0\n[[sphere]]\ncenter = [0, 1, 0]\nradius = 0.5\n',
}


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_a_bad_scene_raises_the_command_lines_message(tmp_path, cli, case):
    path = tmp_path / "scene.toml"
    path.write_text(BAD_SCENES[case])
    with pytest.raises(vmerge.SceneError) as raised:
        vmerge.load_scene(path)
    assert isinstance(raised.value, ValueError)
    done = cli("render", path, "-n", 1, "-o", tmp_path / "x.exr", check=False)
    assert str(raised.value) == cli_error(done)
    assert str(path) in str(raised.value)


def test_lenient_loading_returns_warnings(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(
        '[[camera]]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nup = [0, 1, 0]\nfov = 40.0\n'
        '[[sphere]]\ncenter = [0, 1, 0]\nradius = 0.5\nmaterial = "hot"\n'
        '[material.hot]\ntype = "phong"\nkd = [0.8, 0.8, 0.8]\nks = [0.5, 0.5, 0.5]\n'
        'emission = [1, 1, 1]\n'
    )
    with pytest.raises(vmerge.SceneError):
        vmerge.load_scene(path)
    scene = vmerge.load_scene(path, lenient=True)
    assert scene.warnings and all(isinstance(w, str) for w in scene.warnings)


def test_the_progressive_iterators_last_image_equals_a_one_shot_render(scene):
    options = dict(iterations=7, radius=0.02, **SMALL)
    steps = vmerge.render_progressive(scene, "vcm", every=3, **options)
    images = [(s.iterations, s.image) for s in steps]
    assert [n for n, _ in images] == [3, 6, 7]
    once = vmerge.render(scene, "vcm", **options)
    assert np.array_equal(images[-1][1], once.image)
    assert exact(steps.result, once)
    # The intermediate images are the renders of that many iterations.
    three = vmerge.render(scene, "vcm", **dict(options, iterations=3))
    assert np.array_equal(images[0][1], three.image)


@pytest.mark.parametrize("budget", ["time", "cpu_time"])
def test_a_time_budget_renders_until_it_is_spent(scene, budget):
    result = vmerge.render(scene, resolution=(16, 16), **{budget: 0.3})
    assert result.iterations >= 1
    spent = result.seconds if budget == "time" else result.metadata["cpu_seconds"]
    # No iteration starts that is predicted to end past the budget: the render stops within
    # about one iteration of it, on either side.
    mean = spent / result.iterations
    assert 0.3 - 2 * mean <= spent < 5


def test_continue_and_merge_equal_the_command_lines(tmp_path, cli, scene):
    first = tmp_path / "first.exr"
    cli("render", SCENE, "-n", 3, "--seed", 1, "--resolution", "24x16", "-o", first, "--no-png")
    cli("continue", first, "-n", 2, "-o", tmp_path / "continued.exr", "--no-png")
    second = tmp_path / "second.exr"
    cli("render", SCENE, "-n", 4, "--seed", 2, "--resolution", "24x16", "-o", second, "--no-png")
    cli("merge", tmp_path / "merged.exr", first, second)

    a = vmerge.render(scene, iterations=3, seed=1, resolution=(24, 16))
    continued = vmerge.continue_render(a, iterations=2)
    assert continued.iterations == 5
    assert exact(continued, vmerge.read(tmp_path / "continued.exr"))
    from_file = vmerge.continue_render(first, iterations=2)
    assert exact(from_file, continued)
    b = vmerge.render(scene, iterations=4, seed=2, resolution=(24, 16))
    merged = vmerge.merge([a, b], output=tmp_path / "py-merged.exr")
    expected = vmerge.read(tmp_path / "merged.exr")
    assert exact(merged, expected)
    assert merged.statistics == expected.statistics
    assert exact(vmerge.read(tmp_path / "py-merged.exr"), expected)
    with pytest.raises(ValueError, match="the same samples would count twice"):
        vmerge.merge([a, a])


def test_written_renders_read_back_exactly(tmp_path, scene):
    result = vmerge.render(scene, "bpt", iterations=2, **SMALL)
    result.write(tmp_path / "r.exr", png=True)
    back = vmerge.read(tmp_path / "r.exr")
    assert exact(back, result)
    assert back.metadata == result.metadata
    assert (tmp_path / "r.png").is_file()
    vmerge.write_image(tmp_path / "plain.exr", result.image)
    assert np.array_equal(vmerge.read_image(tmp_path / "plain.exr"), result.image)
    with pytest.raises(ValueError, match="not a vmerge render"):
        vmerge.read(tmp_path / "plain.exr")
    with pytest.raises(OSError, match="nowhere.exr"):
        vmerge.read(tmp_path / "nowhere.exr")


def test_errors_equal_the_command_lines(tmp_path, cli, scene):
    options = dict(resolution=(40, 32), seed=7)
    a = vmerge.render(scene, iterations=1, **options)
    b = vmerge.render(scene, iterations=2, **dict(options, seed=8))
    a.write(tmp_path / "a.exr")
    b.write(tmp_path / "b.exr")
    lines = cli("errors", tmp_path / "a.exr", tmp_path / "b.exr").stdout.split("\n")
    expected = {name: float(value) for name, value in (l.split() for l in lines if l)}
    measured = vmerge.errors(a.image, b)
    assert measured == expected
    assert sorted(measured) == sorted(vmerge.measure_names())
    assert vmerge.errors(tmp_path / "a.exr", b.image.astype(np.float64)) == measured
    pointwise = vmerge.errors(a, b, pointwise=True)
    assert pointwise == {k: measured[k] for k in ("mae", "rmse", "relmse")}
    assert math.isclose(measured["mae"], float(np.mean(np.abs(a.image - b.image))), rel_tol=1e-5)


def test_a_reference_gives_an_error_series(tmp_path, scene):
    reference = vmerge.render(scene, iterations=8, **dict(SMALL, seed=99))
    reference.write(tmp_path / "ref.exr")
    result = vmerge.render(scene, "pt", iterations=4, reference=tmp_path / "ref.exr",
                           traces=[(12, 8, 4)], **SMALL)
    errors = result.errors
    # Measured at every power of two, and at the end.
    assert list(errors["iterations"]) == [1, 2, 4]
    assert errors["traces"].shape == (3, 1, 2)
    assert errors["rmse"][-1] == pytest.approx(
        vmerge.errors(result, reference)["rmse"], rel=1e-12)
    assert set(vmerge.measure_names()) <= set(errors)


def test_a_batch_plan_runs_and_reports(tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text(
        f'output = "{tmp_path / "results"}"\nresolution = [16, 16]\niterations = 2\n'
        f'[[scene]]\nfile = "{CAUSTIC}"\n'
        'reference = { technique = "bpt", iterations = 4 }\n'
        '[[group]]\ntechniques = ["vcm", "upg"]\nradius = [0.02, 0.04]\n'
    )
    assert vmerge.run_batch(plan) == 5
    assert vmerge.run_batch(plan) == 0
    assert vmerge.batch_report(plan).is_file()
