#!/usr/bin/env python3
"""The cost of the binding: the same pt render from Python and from the command line,
interleaved, several rounds.

Each round renders the scene at 64x64 for 64 iterations once each way, in alternating order.
Three times per render: the render loop's own seconds as the EXR records them (what the binding
could slow: the GIL released, a signal check per iteration), the wall time of the whole call
(for the command line: process start, scene load, writing the EXR; for Python: the same scene
load, render and EXR in this process), and the CPU time of the whole call, all threads, which
other work on a shared machine disturbs less than wall time.

    python python/benchmarks/binding_cost.py [--rounds 7] [--vmerge target/release/vmerge]
"""

import argparse
import resource
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
    times = {"python": ([], [], []), "cli": ([], [], [])}
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / "cli.exr"

        def children_cpu():
            usage = resource.getrusage(resource.RUSAGE_CHILDREN)
            return usage.ru_utime + usage.ru_stime

        def cli():
            start, cpu = time.perf_counter(), children_cpu()
            subprocess.run([str(args.vmerge), "render", str(args.scene), "-n", "64",
                            "--resolution", "64x64", "-o", str(out), "--no-png"],
                           check=True, capture_output=True)
            wall, cpu = time.perf_counter() - start, children_cpu() - cpu
            return vmerge.read(out).seconds, wall, cpu

        def python():
            start, cpu = time.perf_counter(), time.process_time()
            scene = vmerge.load_scene(args.scene)
            result = vmerge.render(scene, "pt", iterations=64, resolution=(64, 64))
            return result.seconds, time.perf_counter() - start, time.process_time() - cpu

        python()  # warm the page cache and the module
        for k in range(args.rounds):
            order = [("python", python), ("cli", cli)]
            for name, run in order if k % 2 == 0 else order[::-1]:
                for column, value in zip(times[name], run()):
                    column.append(value)
    print("| s: median [min, max] | render loop | whole call | whole call, CPU |")
    print("|---|---|---|---|")
    for name, columns in times.items():
        cells = [f"{statistics.median(t):.3f} [{min(t):.3f}, {max(t):.3f}]" for t in columns]
        print(f"| {name} | " + " | ".join(cells) + " |")
    print()
    for k, what in enumerate(["render loop", "whole call", "whole call, CPU"]):
        py, cl = times["python"][k], times["cli"][k]
        print(f"python / cli, {what}: {statistics.median(py) / statistics.median(cl):.3f} by the "
              f"medians, {min(py) / min(cl):.3f} by the fastest ({args.rounds} rounds, interleaved)")


if __name__ == "__main__":
    main()
