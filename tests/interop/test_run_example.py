"""The ``fieldbox run`` example (docs/examples/auto.fbx) drives WPILib's simulated robot
(docs/examples/auto_robot.py, started by ``--launch``) through an autonomous period and
checks what it printed: what a mentor runs in CI for robot code."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from .test_wpilib_sim import _extension, _ports_free, _unavailable

pytestmark = pytest.mark.interop

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "docs" / "examples"


def test_the_example_script_drives_wpilibs_simulator_through_auto(tmp_path):
    extension = _extension()
    if extension is None:
        _unavailable("wpilib and robotpy-halsim-ds-socket are not installed (pip install -e '.[interop]')")
    if not _ports_free():
        _unavailable("UDP 1110 or TCP 1740 is taken on this machine: the simulator needs them")
    report = tmp_path / "auto.xml"
    launch = f"{sys.executable} -m robotpy --main {EXAMPLES / 'auto_robot.py'} run"
    done = subprocess.run([sys.executable, "-m", "fieldbox", "run", str(EXAMPLES / "auto.fbx"), "--roles", "ds",
                           "--robot", "127.0.0.1", "--no-log-files", "--launch", launch, "--junit", str(report)],
                          cwd=tmp_path, env=dict(os.environ, HALSIM_EXTENSIONS=extension),  # robotpy writes here
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "ok 6 - expect console auto started within 2" in done.stdout
    assert "ok 7 - expect console auto: drove forward within 3" in done.stdout
    suite = ET.parse(report).getroot()
    assert suite.get("failures") == "0" and suite.get("tests") == "10"
