"""Where every role lives: the loopback, real and ephemeral address plans (docs/design.md#addresses).

| plan      | robot        | DS           | FMS          | ports         |
|-----------|--------------|--------------|--------------|---------------|
| loopback  | 127.TE.AM.2  | 127.TE.AM.5  | 127.0.100.5  | the real ones |
| real      | 10.TE.AM.2   | this machine | 10.0.100.5   | the real ones |
| ephemeral | 127.0.0.1    | 127.0.0.1    | 127.0.0.1    | OS-chosen     |

Nothing here opens a socket: it only computes addresses, so tests can check the choice
without sending anything anywhere.
"""

from __future__ import annotations

import ipaddress

# The real ports (docs/protocol.md#ports).
ROBOT_UDP = 1110          # DS -> roboRIO control packets
ROBOT_UDP_FMS = 1115      # ... while the DS is attached to an FMS
DS_UDP = 1150             # roboRIO -> DS status packets
ROBOT_TCP = 1740          # DS <-> roboRIO TCP
FMS_TCP = 1750            # DS <-> FMS TCP
FMS_UDP = 1160            # DS -> FMS status
DS_FMS_UDP = 1121         # FMS -> DS control
DS_FMS_UDP_LITE = 1120    # the older "lite" port
DS_FMS_SOURCE = 1145      # the port a DS sends its FMS status from, where it can
LEGACY_DASHBOARD = 1165   # 2010: DS -> dashboard
NETCONSOLE = 6666         # 2010: robot console text

USB_ROBOT = "172.22.11.2"
REAL_FMS = "10.0.100.5"
LOOPBACK_FMS = "127.0.100.5"

PLANS = ("loopback", "real", "ephemeral")


def check_team(team: int) -> int:
    if not isinstance(team, int) or isinstance(team, bool) or not 1 <= team <= 25599:
        # 10.TE.AM.x needs TE <= 255: team 25599 is the largest a real field can address.
        raise ValueError(f"team must be 1..25599, not {team!r}")
    return team


def te_am(team: int) -> tuple[int, int]:
    """Team 254 -> (2, 54); team 1114 -> (11, 14); team 9 -> (0, 9)."""
    check_team(team)
    return team // 100, team % 100


def team_address(team: int, host: int, plan: str) -> str:
    te, am = te_am(team)
    if plan == "loopback":
        return f"127.{te}.{am}.{host}"
    if plan == "real":
        return f"10.{te}.{am}.{host}"
    if plan == "ephemeral":
        return "127.0.0.1"
    raise ValueError(f"unknown network plan {plan!r}: one of {', '.join(PLANS)}")


def robot_address(team: int, plan: str = "loopback", robot: str | None = None) -> str:
    """The address a DS sends to: ``--robot`` if given (an IP, a host name, ``usb`` or
    ``mdns``), else the plan's 10.TE.AM.2 / 127.TE.AM.2 / 127.0.0.1."""
    if robot:
        key = robot.strip().lower()
        if key == "usb":
            return USB_ROBOT
        if key in ("mdns", "local"):
            return f"roboRIO-{check_team(team)}-FRC.local"
        if key in ("loopback", "lo"):
            return team_address(team, 2, "loopback")
        return robot.strip()
    return team_address(team, 2, plan)


def ds_address(team: int, plan: str = "loopback") -> str:
    """Where a DS binds: 127.TE.AM.5 on loopback; every address (``0.0.0.0``) in the real plan."""
    if plan == "real":
        return "0.0.0.0"
    return team_address(team, 5, plan)


def fms_address(plan: str = "loopback", fms: str | None = None) -> str:
    if fms:
        return fms.strip()
    return {"loopback": LOOPBACK_FMS, "real": REAL_FMS, "ephemeral": "127.0.0.1"}[plan]


def port(real_port: int, plan: str) -> int:
    """The real port, or 0 (OS-chosen) in the ephemeral plan."""
    return 0 if plan == "ephemeral" else real_port


def is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host in ("localhost",)
