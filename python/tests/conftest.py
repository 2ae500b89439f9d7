"""The `simnet` binary the tests compare the package with: $SIMNET_BIN, else the workspace's debug build."""

import os
import subprocess
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli():
    binary = Path(os.environ.get("SIMNET_BIN", ROOT / "target" / "debug" / "simnet"))
    if not binary.is_file():
        pytest.fail(f"{binary}: no simnet binary (run `cargo build` in {ROOT}, or set SIMNET_BIN)")

    # A directory without ./topologies: names resolve to the built-ins, as they do from Python here.
    cwd = tempfile.mkdtemp(prefix="simnet-cli-")

    def run(*args, check=True):
        p = subprocess.run([str(binary), *args], capture_output=True, text=True, cwd=cwd)
        if check and p.returncode != 0:
            raise AssertionError(f"simnet {' '.join(args)} exited {p.returncode}:\n{p.stderr}")
        return p

    return run


@pytest.fixture(autouse=True)
def outside_the_source_tree(tmp_path, monkeypatch):
    """Each test in a directory without ./topologies, like the CLI above: names resolve to the built-ins."""
    monkeypatch.chdir(tmp_path)
