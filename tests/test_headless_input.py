"""Headless mode's commands on stdin: input that cannot be read ends the run, saying why."""

import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_unreadable_commands_end_the_run_and_say_why():
    # Bytes that are not UTF-8, on a stdin decoded strictly: reading them fails. The pipe stays
    # open, so only the reader's own ending can end the run (it once raised a TypeError
    # instead, and the run went on without its commands).
    env = dict(os.environ, PYTHONIOENCODING="utf-8:strict")
    proc = subprocess.Popen([sys.executable, "-m", "fieldbox", "--headless", "--roles", "ds,rio", "--team", "254",
                             "--net", "ephemeral", "--no-log-files"],
                            cwd=ROOT, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        proc.stdin.write(b"status\n\xff\xfe\n")
        proc.stdin.flush()
        try:
            proc.wait(timeout=30)  # a hang guard: it ends at once
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            raise AssertionError("the run went on after its input failed; stderr:\n"
                                 + proc.stderr.read().decode()) from None
        text = proc.stderr.read().decode()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdin.close()
    assert "fieldbox: cannot read commands: 'utf-8' codec can't decode byte 0xff" in text, text
    assert "Traceback" not in text, text
    assert proc.returncode == 0
