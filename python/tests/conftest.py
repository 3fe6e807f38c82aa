"""Fixtures of the pytest suite: the mcslam CLI (MCSLAM_EXE, set by ctest) and a synthetic
sequence it renders once per session."""
import os
import subprocess

import pytest


@pytest.fixture(scope="session")
def mcslam_exe():
    exe = os.environ.get("MCSLAM_EXE")
    if not exe:
        here = os.path.dirname(os.path.abspath(__file__))
        exe = os.path.join(here, "..", "..", "build", "mcslam")
    assert os.access(exe, os.X_OK), f"the mcslam CLI is not at {exe} (set MCSLAM_EXE)"
    return exe


@pytest.fixture(scope="session")
def synth_sequence(mcslam_exe, tmp_path_factory):
    """30 frames of the synthetic room, with ground truth."""
    out = tmp_path_factory.mktemp("synth") / "room"
    subprocess.run([mcslam_exe, "synth", "--output", str(out), "--frames", "30", "-q"],
                   check=True, stdout=subprocess.DEVNULL)
    return str(out)


@pytest.fixture(scope="session")
def cli_run(mcslam_exe, synth_sequence, tmp_path_factory):
    """`mcslam run --sequential` on the synthetic sequence: its output folder."""
    out = tmp_path_factory.mktemp("cli_run")
    subprocess.run([mcslam_exe, "run", synth_sequence, "--output", str(out), "--sequential",
                    "-q"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return str(out)
