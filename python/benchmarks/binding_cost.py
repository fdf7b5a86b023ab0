#!/usr/bin/env python3
"""The cost of the binding: the same pt render from Python and from the command line,
interleaved, several rounds.

Each round renders the scene at 64x64 for 64 iterations once each way, in alternating order.
Two times per render: the render loop's own seconds as the EXR records them (what the binding
could slow: the GIL released, a signal check per iteration), and the wall time of the whole
call (for the command line: process start, scene load, writing the EXR; for Python: the same
scene load and render in this process).

    python python/benchmarks/binding_cost.py [--rounds 7] [--vmerge target/release/vmerge]
"""

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import vmerge

ROOT = Path(__file__).resolve().parents[2]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=7)
    p.add_argument("--vmerge", type=Path, default=ROOT / "target" / "release" / "vmerge")
    p.add_argument("--scene", type=Path, default=ROOT / "scenes" / "cornell-box" / "scene.toml")
    args = p.parse_args()
    times = {"python": ([], []), "cli": ([], [])}
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / "cli.exr"

        def cli():
            start = time.perf_counter()
            subprocess.run([str(args.vmerge), "render", str(args.scene), "-n", "64",
                            "--resolution", "64x64", "-o", str(out), "--no-png"],
                           check=True, capture_output=True)
            wall = time.perf_counter() - start
            return vmerge.read(out).seconds, wall

        def python():
            start = time.perf_counter()
            scene = vmerge.load_scene(args.scene)
            result = vmerge.render(scene, "pt", iterations=64, resolution=(64, 64))
            return result.seconds, time.perf_counter() - start

        python()  # warm the page cache and the module
        for k in range(args.rounds):
            order = [("python", python), ("cli", cli)]
            for name, run in order if k % 2 == 0 else order[::-1]:
                loop, wall = run()
                times[name][0].append(loop)
                times[name][1].append(wall)
    print("| | render loop (s): median [min, max] | whole call (s): median [min, max] |")
    print("|---|---|---|")
    for name, (loop, wall) in times.items():
        cells = [f"{statistics.median(t):.3f} [{min(t):.3f}, {max(t):.3f}]" for t in (loop, wall)]
        print(f"| {name} | {cells[0]} | {cells[1]} |")
    ratio = statistics.median(times["python"][0]) / statistics.median(times["cli"][0])
    print(f"\npython / cli, render loop: {ratio:.3f} ({args.rounds} rounds, interleaved)")


if __name__ == "__main__":
    main()
