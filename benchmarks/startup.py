"""Start-up times: ``fieldbox --help`` and the app's first frame.

    python benchmarks/startup.py            # a table (best of 7 for --help, best of 5 for the frame)
    python benchmarks/startup.py --json

* ``fieldbox --help``: wall time of the whole subprocess (the installed ``fieldbox``
  script, and ``python -m fieldbox``), best of N. Target <= 0.3 s.
* first frame: ``fieldbox --net ephemeral`` (the app: DS, fake roboRIO and FMS) started on a
  pseudo-terminal of 160 x 50; the time from just before the process is spawned to the
  first output that holds a drawn screen (the header's "fieldbox" title after the switch
  to the alternate screen), best of N. Target <= 1.5 s. The app is then ended with SIGTERM.

Both are measured as an installed fieldbox runs, with its bytecode cached (compiled once by
an unmeasured first run into a temporary PYTHONPYCACHEPREFIX, so the source tree is not
touched), and again with no bytecode cache at all (PYTHONDONTWRITEBYTECODE=1, as in a
sandbox that forbids writing .pyc files: every start compiles every module).
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import pty
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import termios
import time
from typing import Any

import _common as C  # noqa: E402

ALT_SCREEN = b"\x1b[?1049h"
MARKER = b"fieldbox"
HELP_TARGET = 0.3
FRAME_TARGET = 1.5


def env_for(cached: bool, prefix: str) -> dict[str, str]:
    env = dict(os.environ)
    if cached:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = prefix
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env.pop("PYTHONPYCACHEPREFIX", None)
    return env


def time_help(cmd: list[str], runs: int, env: dict[str, str]) -> list[float]:
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, timeout=30,
                   env=env)  # unmeasured: fills the bytecode cache (when there is one)
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, timeout=30,
                       env=env)
        times.append(time.perf_counter() - t0)
    return times


def time_first_frame(cmd: list[str], env: dict[str, str], size=(160, 50), timeout: float = 20.0) -> dict[str, Any]:
    """Spawn ``cmd`` on a pseudo-terminal; seconds until its first drawn frame."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", size[1], size[0], 0, 0))
    env = dict(env, TERM="xterm-256color", COLUMNS=str(size[0]), LINES=str(size[1]))
    env.pop("TEXTUAL", None)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdin=slave, stdout=slave, stderr=slave, env=env, close_fds=True,
                            start_new_session=True, cwd=C.ROOT)
    os.close(slave)
    seen = bytearray()
    first_output = alt_screen = frame = None
    try:
        deadline = t0 + timeout
        while time.perf_counter() < deadline:
            ready, _, _ = select.select([master], [], [], 0.05)
            if not ready:
                if proc.poll() is not None:
                    break
                continue
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the child closed the terminal
                break
            if not chunk:
                break
            now = time.perf_counter() - t0
            if first_output is None:
                first_output = now
            seen += chunk
            if alt_screen is None and ALT_SCREEN in seen:
                alt_screen = now
            if alt_screen is not None and MARKER in seen[seen.find(ALT_SCREEN):]:
                frame = now
                break
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        # drain so the child is never blocked on a full terminal while it exits
        try:
            while select.select([master], [], [], 0)[0] and os.read(master, 65536):
                pass
        except OSError:
            pass
        os.close(master)
    return {"first_output_s": first_output, "alt_screen_s": alt_screen, "first_frame_s": frame,
            "exit_code": proc.returncode}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--help-runs", type=int, default=7)
    ap.add_argument("--frame-runs", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    py = sys.executable
    script = shutil.which("fieldbox", path=os.path.dirname(py)) or shutil.which("fieldbox")
    help_cmds = [(f"{os.path.relpath(script, C.ROOT) if script else 'fieldbox'} --help", [script, "--help"]),
                 ("python -m fieldbox --help", [py, "-m", "fieldbox", "--help"]),
                 ("python -c pass (the interpreter alone)", [py, "-c", "pass"])]
    if not script:
        help_cmds = help_cmds[1:]
    modes = {}
    with tempfile.TemporaryDirectory(prefix="fieldbox-bench-") as tmp:
        for cached in (True, False):
            env = env_for(cached, os.path.join(tmp, "pycache"))
            help_rows = []
            for label, cmd in help_cmds:
                times = time_help(cmd, args.help_runs, env)
                help_rows.append({"command": label, "best_s": round(min(times), 4),
                                  "median_s": round(sorted(times)[len(times) // 2], 4)})
            cmd = [py, "-m", "fieldbox", "--net", "ephemeral", "--log-dir", os.path.join(tmp, "logs")]
            if cached:
                time_first_frame(cmd, env)  # unmeasured: compiles what the app imports
            frames = [time_first_frame(cmd, env) for _ in range(args.frame_runs)]
            good = [f["first_frame_s"] for f in frames if f["first_frame_s"] is not None]
            first = [f["first_output_s"] for f in frames if f["first_output_s"] is not None]
            modes["bytecode cached" if cached else "no bytecode cache"] = {
                "help": help_rows,
                "first_frame": {"runs": [{k: (round(v, 4) if isinstance(v, float) else v) for k, v in f.items()}
                                         for f in frames],
                                "best_s": round(min(good), 4) if good else None,
                                "median_s": round(sorted(good)[len(good) // 2], 4) if good else None,
                                "first_byte_best_s": round(min(first), 4) if first else None}}
    main_mode = modes["bytecode cached"]
    best_help = main_mode["help"][0]["best_s"]
    best_frame = main_mode["first_frame"]["best_s"]
    result = {
        "machine": C.machine(),
        "modes": modes,
        "first_frame_command": "python -m fieldbox --net ephemeral --log-dir TMP (pty 160 x 50)",
        "checks": [C.check("fieldbox --help s (best)", best_help, best_help <= HELP_TARGET, f"<= {HELP_TARGET}"),
                   C.check("first frame s (best)", best_frame if best_frame is not None else float("nan"),
                           best_frame is not None and best_frame <= FRAME_TARGET, f"<= {FRAME_TARGET}")],
        "load_average": os.getloadavg()[0],
        "command": ("python benchmarks/startup.py " + " ".join(argv if argv is not None else sys.argv[1:])).strip(),
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"start-up times (machine: {C.machine_line(result['machine'])}; "
              f"load average {result['load_average']:.2f})")
        for mode, figures in modes.items():
            print(f"\n{mode}:")
            print(f"{'command':45} {'best s':>8} {'median s':>9}")
            for r in figures["help"]:
                print(f"{r['command']:45} {r['best_s']:>8.3f} {r['median_s']:>9.3f}")
            ff = figures["first_frame"]
            nan = float("nan")
            print(f"{'app first frame, 160 x 50 (' + str(args.frame_runs) + ' runs)':45} "
                  f"{ff['best_s'] if ff['best_s'] is not None else nan:>8.3f} "
                  f"{ff['median_s'] if ff['median_s'] is not None else nan:>9.3f}")
            if ff["first_byte_best_s"] is not None:
                print(f"{'  (its first byte on the terminal)':45} {ff['first_byte_best_s']:>8.3f}")
        print("\ntargets (bytecode cached, as installed):")
        C.print_checks(result["checks"])
    return 0 if all(c["met"] for c in result["checks"]) else 1


if __name__ == "__main__":
    sys.exit(main())
