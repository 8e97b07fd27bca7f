import os

from hypothesis import HealthCheck, settings

# CI runs thousands of examples per property (the protocol issue asks for it); a developer's
# run stays quick. FIELDBOX_HYPOTHESIS=ci forces the long profile locally.
settings.register_profile("dev", max_examples=300, deadline=None)
settings.register_profile("ci", max_examples=3000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("FIELDBOX_HYPOTHESIS") or ("ci" if os.environ.get("CI") else "dev"))


# -- a network of the suite's own ------------------------------------------------------------
# Many tests bind the real FRC ports on their loopback addresses (127.0.100.5:1750, 127.0.1.2:1110,
# 127.0.0.1:1742...). A fieldbox, an NI DS or a simulator already running on the machine holds
# them too. So the suite moves, before any test runs, into a network namespace of its own
# with only loopback up: its ports are its own, nothing it sends can leave the machine, and
# every child process (the wire, the classroom, WPILib's simulator, Chromium) is in it too.
# FIELDBOX_TEST_NETNS=0 keeps the machine's network; where no namespace can be made, a test
# that fails only because another program holds its port is skipped, saying so.

_NETNS_NOTE: list[str] = []


def _loopback_up() -> None:
    import fcntl
    import socket
    import struct

    siocgifflags, siocsifflags, iff_up = 0x8913, 0x8914, 0x1
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        request = struct.pack("16sH14s", b"lo", 0, b"")
        flags = struct.unpack("16sH", fcntl.ioctl(s, siocgifflags, request)[:18])[1]
        fcntl.ioctl(s, siocsifflags, struct.pack("16sH14s", b"lo", flags | iff_up, b""))


def _own_network() -> str | None:
    """Unshare the network (and, for a user that is not root, a user namespace that maps it to
    itself); None when done, else why not."""
    import ctypes
    import sys

    if os.environ.get("FIELDBOX_TEST_NETNS") == "0":
        return "FIELDBOX_TEST_NETNS=0"
    if not sys.platform.startswith("linux"):
        return "not Linux"
    clone_newnet, clone_newuser = 0x40000000, 0x10000000
    libc = ctypes.CDLL(None, use_errno=True)
    uid, gid = os.getuid(), os.getgid()
    if libc.unshare(clone_newnet) != 0:
        if libc.unshare(clone_newnet | clone_newuser) != 0:
            return os.strerror(ctypes.get_errno())
        with open("/proc/self/setgroups", "w") as f:
            f.write("deny")
        with open("/proc/self/uid_map", "w") as f:  # the same user inside: no root powers in tests
            f.write(f"{uid} {uid} 1")
        with open("/proc/self/gid_map", "w") as f:
            f.write(f"{gid} {gid} 1")
    _loopback_up()
    return None


def pytest_configure(config):
    why = _own_network()
    _NETNS_NOTE.append("tests run in a network namespace of their own (loopback only)" if why is None
                       else f"tests share this machine's network ({why}): a port another program holds "
                            "skips the test that needs it")
    config._fieldbox_own_network = why is None


def pytest_report_header(config):
    return _NETNS_NOTE


import pytest  # noqa: E402


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if report.failed and not getattr(item.config, "_fieldbox_own_network", True) and call.excinfo is not None:
        text = str(report.longrepr)
        if "Address already in use" in text or "EADDRINUSE" in text:
            report.outcome = "skipped"
            report.longrepr = (str(item.path), item.location[1] or 0,
                               "Skipped: a port this test needs is held by another program on this machine "
                               "(a fieldbox running?): run the tests where they can have their own network "
                               "namespace, or stop it")
    return report
