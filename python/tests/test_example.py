"""The radius-sweep example runs through the module, small and short, and draws its figure."""

import subprocess
import sys

from conftest import ROOT


def test_the_radius_sweep_example_draws_its_figure(tmp_path):
    figure = tmp_path / "sweep.png"
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "radius_sweep.py"), "--quick", "-o", str(figure)],
        capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lines = [line for line in done.stdout.splitlines() if " r=" in line]
    assert len(lines) == 6, done.stdout
