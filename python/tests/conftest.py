"""Shared fixtures: the repository's scenes and the `vmerge` command line to compare with."""

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "cornell-box" / "scene.toml"
CAUSTIC = ROOT / "scenes" / "caustic" / "scene.toml"


def cli_path():
    """The command line built from this checkout: $VMERGE_BIN, else target/release/vmerge."""
    given = os.environ.get("VMERGE_BIN")
    if given:
        return Path(given)
    return ROOT / "target" / "release" / "vmerge"


@pytest.fixture(scope="session")
def cli():
    path = cli_path()
    if not path.is_file():
        pytest.skip(f"{path} is not built (cargo build --release builds it)")

    def run(*args, check=True):
        done = subprocess.run(
            [str(path), *map(str, args)], capture_output=True, text=True
        )
        if check and done.returncode != 0:
            raise AssertionError(f"vmerge {' '.join(map(str, args))}: {done.stderr}")
        return done

    return run


def cli_error(done):
    """The message of a refused command line: what follows `error: `, to the end."""
    assert done.returncode == 2, done.stderr
    at = done.stderr.find("error: ")
    assert at >= 0, done.stderr
    return done.stderr[at + len("error: "):].rstrip("\n")
