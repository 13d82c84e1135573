"""Shared fixtures: the CLI the package is compared with, and small inputs cut from the
repository's real capture (fixtures/real/fourth_st.spz) and street fixture."""
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
CLI = os.environ.get("SPLATBRIDGE_CLI") or str(ROOT / "target" / "release" / "splatbridge")
FOURTH_ST = ROOT / "fixtures" / "real" / "fourth_st.spz"
STREET = ROOT / "fixtures" / "street" / "scene.json"
STREET_CAMERAS = ROOT / "fixtures" / "street" / "cameras.json"


def cli(*args, check=True):
    """Run the splatbridge CLI; the completed process (stdout and stderr as text)."""
    r = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"splatbridge {' '.join(map(str, args))}: exit {r.returncode}\n{r.stderr}")
    return r


@pytest.fixture(scope="session")
def small(tmp_path_factory):
    """The first 3,000 Gaussians of fourth_st as a 3DGS PLY (SH degree 3), written by the CLI."""
    out = tmp_path_factory.mktemp("small") / "small.ply"
    cli("convert", FOURTH_ST, "--first", "3000", "-o", out)
    return out
