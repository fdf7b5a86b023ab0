#!/usr/bin/env python3
"""A radius sweep of vcm and upg against a bpt reference, all through `import vmerge`.

Renders a reference with bpt, then each technique at a range of merge radii around the scene's
default, each for the same time budget, measuring the error against the reference as it goes.
Draws two charts: the final error (RMS by default, any of vmerge's measures with --measure)
against the radius, and the error against time at each technique's best radius.

    python examples/radius_sweep.py                          # the README's figure
    python examples/radius_sweep.py --quick -o sweep.png     # a small, short run (CI)
"""

import argparse
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import vmerge  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LABELS = {"mae": "mean absolute error", "rmse": "RMS error", "relmse": "relative MSE",
          "ldr-flip": "LDR-FLIP", "hdr-flip": "HDR-FLIP", "ssim": "1 - SSIM"}


def arguments():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", type=Path, default=ROOT / "scenes" / "caustic" / "scene.toml")
    p.add_argument("--resolution", type=int, default=128, help="square image side in pixels")
    p.add_argument("--reference-iterations", type=int, default=1024)
    p.add_argument("--time", type=float, default=6.0, help="seconds per technique and radius")
    p.add_argument("--radii", type=int, default=7, help="radii, log-spaced")
    p.add_argument("--span", type=float, default=8.0,
                   help="the radii run from the default / span to the default x span")
    p.add_argument("--techniques", nargs="+", default=["vcm", "upg"])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--measure", default="rmse", choices=vmerge.measure_names(),
                   help="the error drawn (ssim as 1 - SSIM)")
    p.add_argument("--quick", action="store_true",
                   help="a small, short run: 32x32, 16 reference iterations, 3 radii, 0.3 s each")
    p.add_argument("-o", "--output", type=Path, default=Path("radius_sweep.png"))
    args = p.parse_args()
    if args.quick:
        args.resolution, args.reference_iterations = 32, 16
        args.time, args.radii = 0.3, 3
    return args


def radii(default, count, span):
    if count == 1:
        return [default]
    return [default * span ** (2 * k / (count - 1) - 1) for k in range(count)]


def main():
    args = arguments()
    scene = vmerge.load_scene(args.scene)
    for w in scene.warnings:
        print(f"warning: {w}", file=sys.stderr)
    size = (args.resolution, args.resolution)
    with tempfile.TemporaryDirectory() as scratch:
        reference = Path(scratch) / "reference.exr"
        ref = vmerge.render(scene, "bpt", iterations=args.reference_iterations,
                            resolution=size, seed=args.seed + 1000, output=reference)
        print(f"reference: bpt, {ref.iterations} iterations, {ref.seconds:.1f} s")
        sweep = {}
        for technique in args.techniques:
            for r in radii(scene.default_radius, args.radii, args.span):
                result = vmerge.render(scene, technique, time=args.time, resolution=size,
                                       seed=args.seed, radius=r, reference=reference)
                final = as_error(args.measure, vmerge.errors(result, ref)[args.measure])
                sweep.setdefault(technique, []).append((r, final, result))
                print(f"{technique} r={r:.4g}: {result.iterations} iterations, "
                      f"{result.seconds:.2f} s, {args.measure} {final:.4g}")
    draw(args, scene, sweep)
    print(f"wrote {args.output}")


def as_error(measure, value):
    """The value as an error that falls to 0 as the image converges: 1 - SSIM for SSIM."""
    return 1.0 - value if measure == "ssim" else value


def draw(args, scene, sweep):
    label = LABELS.get(args.measure, args.measure)
    fig, (by_radius, by_time) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for technique, cells in sweep.items():
        line, = by_radius.plot([r for r, _, _ in cells], [e for _, e, _ in cells], "o-",
                               label=technique)
        r, e, best = min(cells, key=lambda c: c[1])
        errors = best.errors
        # The perceptual measures are recorded at fewer samples than the pixel-wise ones.
        measured = ~np.isnan(errors[args.measure])
        by_time.plot(errors["seconds"][measured],
                     as_error(args.measure, errors[args.measure][measured]),
                     color=line.get_color(), label=f"{technique}, r = {r:.3g}")
    by_radius.axvline(scene.default_radius, color="gray", lw=0.8, ls=":", label="default radius")
    by_radius.set(xscale="log", yscale="log", xlabel="merge radius (world units)",
                  ylabel=f"{label} after equal time",
                  title=f"{args.scene.parent.name}: {args.time:g} s per radius")
    by_time.set(xscale="log", yscale="log", xlabel="render time (s)", ylabel=label,
                title="at each technique's best radius")
    for ax in (by_radius, by_time):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    # Written beside, then renamed: a stopped run never leaves half a figure.
    partial = args.output.with_name(args.output.name + ".partial" + args.output.suffix)
    fig.savefig(partial, dpi=110)
    partial.replace(args.output)


if __name__ == "__main__":
    main()
