"""The type check: mypy over protocol, roles and fieldbox, as pyproject.toml's [tool.mypy]
configures it (strict for the pure layers), so the test command and CI run it too."""

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CHECKED = ("protocol", "roles", "fieldbox")  # [tool.mypy] files; tests and benchmarks are not checked


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None,
                    reason="mypy is not installed (it is in the test extra: pip install -e '.[test]')")
def test_mypy_passes():
    # The cache is the project's .mypy_cache (gitignored): a second run takes about a second.
    out = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    report = out.stdout + out.stderr
    assert out.returncode == 0, f"mypy found type errors (exit {out.returncode}):\n{report}"
    # Every source file was checked: a configuration that checks nothing also "passes".
    sources = sum(1 for package in CHECKED for _ in (ROOT / package).rglob("*.py"))
    checked = re.search(r"Success: no issues found in (\d+) source files", report)
    assert checked, f"mypy said no success line:\n{report}"
    assert int(checked.group(1)) == sources, f"mypy checked {checked.group(1)} files of {sources}:\n{report}"
