"""The layers point one way: protocol and roles never pull in UI libraries (docs/design.md#layers)."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import roles.cores

FORBIDDEN_PROTOCOL = ("textual", "rich", "pygame", "asyncio", "socket")
FORBIDDEN_ROLES = ("textual", "rich", "pygame")
# The cores are sans-IO: the shell that runs them, its sockets, processes and threads, and the
# robot program's host all live in roles/runtime. (threading is not in the loaded list: the
# standard library's logging imports it; the source scan below refuses it in the cores' own code.)
IO_MODULES = ("socket", "subprocess", "threading", "multiprocessing", "selectors", "asyncio")
FORBIDDEN_CORES = FORBIDDEN_ROLES + tuple(m for m in IO_MODULES if m != "threading")
CORES = Path(roles.cores.__file__).resolve().parent
# Calls a core must not make: files, code from text, and clocks (time comes in as ``now``).
FORBIDDEN_CALLS = {
    "open", "exec", "eval", "compile", "__import__", "input",
    "os.open", "os.read", "os.write", "os.remove", "os.unlink", "os.rename", "os.replace", "os.listdir",
    "os.scandir", "os.walk", "os.mkdir", "os.makedirs", "os.rmdir", "os.stat", "os.system", "os.popen",
    "os.fork", "os.kill", "os.killpg", "os.waitid", "os.waitpid",
    "time.time", "time.monotonic", "time.perf_counter", "time.sleep", "time.time_ns", "time.monotonic_ns",
    "time.perf_counter_ns", "time.process_time", "time.thread_time",
}
# pathlib's reads and writes, whatever the path object is called
FORBIDDEN_METHODS = {"read_text", "write_text", "read_bytes", "write_bytes", "unlink", "mkdir", "rmdir",
                     "iterdir", "touch"}


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
    """Everything under roles/cores imports no other roles module: no whitelist (the robot
    program's host is the runtime's, roles/runtime/program_host.py)."""
    loaded = _loaded_after_import("roles.cores")
    outside = sorted(m for m in loaded if m.startswith("roles.") and not m.startswith("roles.cores"))
    assert not outside, f"importing roles.cores pulled in {outside}"


def _dotted(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        owner = _dotted(node.value)
        return None if owner is None else f"{owner}.{node.attr}"
    return None


def _io_in(path: Path) -> list[str]:
    """``file:line what`` for each import of an I/O module and each forbidden call in ``path``."""
    found = []
    tree = ast.parse(path.read_text(), str(path))
    aliases: dict[str, str] = {}  # a name bound by ``from time import monotonic`` -> "time.monotonic"
    for node in ast.walk(tree):
        where = f"{path.name}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] in IO_MODULES:
                    found.append(f"{where} import {alias.name}")
                aliases[alias.asname or alias.name] = alias.name
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] in IO_MODULES:
                found.append(f"{where} from {node.module} import ...")
            for alias in node.names:
                aliases[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        where = f"{path.name}:{node.lineno}"
        name = _dotted(node.func)
        if name is not None:
            head, _, rest = name.partition(".")
            full = aliases.get(head, head) + (f".{rest}" if rest else "")
            if full in FORBIDDEN_CALLS or name in FORBIDDEN_CALLS:
                found.append(f"{where} {name}()")
                continue
        if isinstance(node.func, ast.Attribute) and node.func.attr in FORBIDDEN_METHODS:
            found.append(f"{where} .{node.func.attr}()")
    return found


def test_cores_do_no_io_and_read_no_clock():
    """The cores' own source: no socket, process or thread module, no file opened, read,
    written or listed, no code run from text, no clock read or slept on (``now`` is passed in)."""
    sources = sorted(CORES.glob("*.py"))
    assert len(sources) > 10  # the scan has something to read
    found = [hit for source in sources for hit in _io_in(source)]
    assert not found, "roles/cores does I/O or reads a clock:\n" + "\n".join(found)


def test_the_scan_sees_what_it_forbids(tmp_path):
    """The source scan is not blind: each kind of I/O it forbids is found in a sample."""
    sample = tmp_path / "sample.py"
    sample.write_text("import socket\nimport os, time\nfrom time import monotonic as clock\n"
                      "from pathlib import Path\n"
                      "def f(p):\n    open(p)\n    os.listdir(p)\n    exec('1')\n    time.sleep(1)\n"
                      "    clock()\n    Path(p).read_text()\n    time.perf_counter()\n")
    hits = {h.split(" ", 1)[1] for h in _io_in(sample)}
    assert hits == {"import socket", "open()", "os.listdir()", "exec()", "time.sleep()", "clock()", ".read_text()",
                    "time.perf_counter()"}


def test_every_core_keeps_the_one_contract():
    """The shell calls every core the same way (roles/cores/core.py Core): one datagram signature,
    arrivals included, and a shutdown on each, so it never probes a core for what it has."""
    import inspect

    from roles.cores.core import Core
    from roles.cores.ds import DriverStation
    from roles.cores.fms import FieldManagementSystem
    from roles.cores.rio import Rio

    wanted = {name: list(inspect.signature(getattr(Core, name)).parameters)
              for name in ("datagram", "stream_opened", "stream_data", "stream_closed", "poll", "next_deadline",
                           "view", "shutdown")}
    assert wanted["datagram"] == ["self", "channel", "data", "source", "now", "arrived", "superseded"]
    for core in (Rio, DriverStation, FieldManagementSystem):
        for name, parameters in wanted.items():
            assert list(inspect.signature(getattr(core, name)).parameters) == parameters, (core.__name__, name)
