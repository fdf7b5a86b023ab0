"""Ctrl-C: SIGINT sent to a Python process that renders stops the render at the end of the
iteration it is in, and the render so far comes back whole."""

import json
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from conftest import SCENE

# Renders until interrupted, then reports when it stopped and what it got.
CHILD = textwrap.dedent(
    """
    import json, sys, time
    import numpy as np
    import vmerge

    scene = vmerge.load_scene(sys.argv[1])
    options = dict(iterations=1_000_000, resolution=(96, 96), seed=5)
    steps = None
    try:
        if sys.argv[2] == "progressive":
            steps = vmerge.render_progressive(scene, "bpt", every=1, **options)
            print("started", flush=True)
            for step in steps:
                np.mean(step.image)
        else:
            print("started", flush=True)
            vmerge.render(scene, "bpt", **options)
        print(json.dumps({"interrupted": False}), flush=True)
    except KeyboardInterrupt as e:
        # Raised by the render (Interrupted, with the result), or in the loop's own code.
        r = e.result if isinstance(e, vmerge.Interrupted) else steps.finish()
        caught = time.monotonic()
        mean = (r.sums * (1.0 / r.iterations)).astype(np.float32)
        again = vmerge.continue_render(r, iterations=1)
        print(json.dumps({
            "interrupted": True,
            "caught": caught,
            "iterations": r.iterations,
            "seconds": r.seconds,
            "finite": bool(np.isfinite(r.image).all()),
            # Pixels whose image is not the film's mean, the f64 sums times 1 / iterations
            # rounded to f32, and the largest difference.
            "not_mean": int(np.count_nonzero(r.image != mean)),
            "largest": float(np.abs(r.image - mean).max()),
            "continued": again.iterations,
            "raised": type(e).__name__,
        }), flush=True)
    """
)


@pytest.mark.parametrize("how", ["render", "progressive"])
def test_sigint_stops_within_an_iteration_with_a_valid_result(how):
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(SCENE), how],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(1.5)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 0, err
    report = json.loads(out.strip().splitlines()[-1])
    assert report["interrupted"]
    # A render raises Interrupted; a loop over steps may take the signal in its own code.
    expected = {"Interrupted"} if how == "render" else {"Interrupted", "KeyboardInterrupt"}
    assert report["raised"] in expected
    assert report["iterations"] >= 1
    assert report["finite"] and report["not_mean"] == 0, report
    assert report["continued"] == report["iterations"] + 1
    # The render ran about 1.5 s over its iterations; it stops at the end of the one it is in,
    # so the wait is at most one iteration, plus the time to take the signal.
    per_iteration = report["seconds"] / report["iterations"]
    assert report["caught"] - sent < per_iteration + 0.5, (report, per_iteration)
