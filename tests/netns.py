"""Run a probe script in a private network namespace of the test's own (``unshare -rn``):
there, fixed ports (1742, 1750, 1110...) and addresses such as 10.0.100.5 belong to the test
alone, and no traffic can leave the machine. Skips, with the reason, where Linux, the tools or
the permission to make a namespace are missing."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def run_in_netns(tmp_path: Path, probe: str, *args: str, tools: tuple[str, ...] = (), timeout: float = 90) -> dict:
    """Run ``probe`` (Python source) with ``args`` in a new network namespace, the project
    root on its path; the JSON object its last line of output prints."""
    missing = [tool for tool in ("unshare", *tools) if shutil.which(tool) is None]
    if not sys.platform.startswith("linux") or missing:
        pytest.skip(f"needs Linux and {', '.join(('unshare', *tools))}")
    ok = subprocess.run(["unshare", "-rn", "true"], capture_output=True)
    if ok.returncode != 0:
        pytest.skip(f"cannot make a private network namespace here: {ok.stderr.decode().strip()}")
    path = tmp_path / "probe.py"
    path.write_text(probe)
    out = subprocess.run(["unshare", "-rn", sys.executable, str(path), *args], cwd=ROOT, capture_output=True,
                         text=True, timeout=timeout, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])
