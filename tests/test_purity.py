"""The layers point one way: protocol and roles never pull in UI libraries (docs/design.md#layers)."""

import subprocess
import sys

import pytest

FORBIDDEN_PROTOCOL = ("textual", "rich", "pygame", "asyncio", "socket")
FORBIDDEN_ROLES = ("textual", "rich", "pygame")
# the cores are sans-IO: the asyncio shell that runs them lives in roles/runtime
FORBIDDEN_CORES = FORBIDDEN_ROLES + ("asyncio",)
# the one edge out of roles/cores: the fake roboRIO runs a program file in a process of its own
CORES_REACH = {"roles", "roles.runtime", "roles.runtime.program_host"}


def _loaded_after_import(package: str) -> set[str]:
    code = (
        "import sys, importlib, pkgutil\n"
        f"pkg = importlib.import_module({package!r})\n"
        "for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + '.'):\n"
        "    importlib.import_module(m.name)\n"
        "print(' '.join(sorted(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


@pytest.mark.parametrize("package,forbidden", [("protocol", FORBIDDEN_PROTOCOL), ("roles", FORBIDDEN_ROLES),
                                               ("roles.cores", FORBIDDEN_CORES)])
def test_layer_imports_no_ui(package, forbidden):
    loaded = _loaded_after_import(package)
    bad = [m for m in forbidden if m in loaded]
    assert not bad, f"importing {package} pulled in {bad}"


def test_cores_stand_alone():
    """Everything under roles/cores imports no other roles module but the robot program's host."""
    loaded = _loaded_after_import("roles.cores")
    outside = {m for m in loaded if m.startswith("roles") and not m.startswith("roles.cores")}
    assert outside == CORES_REACH, f"importing roles.cores pulled in {sorted(outside - CORES_REACH)}"
