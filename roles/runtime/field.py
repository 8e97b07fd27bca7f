"""A field: any mix of Driver Stations, fake roboRIOs and an FMS, composed in one process.

:class:`FieldConfig` says what to run (roles, teams, stations, address plan); :class:`Field`
builds the cores and their :class:`~roles.runtime.shell.RoleSpec` and binds them either on real
sockets (:meth:`Field.start`, an asyncio :class:`~roles.runtime.shell.Runtime`) or on the in-memory
network of the tests (:meth:`Field.start_sim`). Both paths share every decision here: which
address each role binds, which peer each DS talks to, and how the ephemeral plan (OS-chosen
ports on 127.0.0.1) wires peers together once their ports are known.

:meth:`Field.execute` carries out one command (``roles.cores.commands``) against the right
core: the app's keys and panels, the headless stdin, a script and a classroom's seats all
come this one way.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, Sequence, TypeVar

from protocol.enums import AllianceStation

from ..cores import addresses as A
from ..cores.commands import FMS_COMMANDS, Command, Fault, SetBattery
from ..cores.core import Address, CommandError
from ..cores.ds import DriverStation
from ..cores.ds import KINDS as DS_KINDS
from ..cores.fms import FieldManagementSystem
from ..cores.legacy_ds import KINDS as LEGACY_DS_KINDS
from ..cores.legacy_rio import KINDS as LEGACY_RIO_KINDS
from ..cores.legacy_rio import LegacyBuiltinProgram
from ..cores.rio import Rio as FakeRoboRIO
from ..cores.rio import RioConfig
from ..sim.faults import Faults, FaultSpecError
from .ds_ip_server import DsIpServer, parse_port, robot_ip_of, serving_station
from .program_host import CodeHost
from .shell import RoleSpec

log = logging.getLogger("fieldbox.field")

ROLE_NAMES = ("ds", "rio", "fms")

RIO_KINDS = {("ds", "in"): "ds-to-rio", ("ds", "out"): "rio-to-ds",
             ("ds-fms", "in"): "ds-to-rio", ("ds-fms", "out"): "rio-to-ds",
             ("tcp", "in"): "ds-to-rio-tcp", ("tcp", "out"): "rio-to-ds-tcp"}
FMS_KINDS = {("udp", "in"): "ds-to-fms", ("udp", "out"): "fms-to-ds",
             ("tcp", "in"): "ds-to-fms-tcp", ("tcp", "out"): "fms-to-ds-tcp"}

#: Said (log, app notification, FMS panel, stderr in headless mode) when --legacy-2010 meets the FMS.
LEGACY_FMS_NOTE = ("the 2010 field protocol is not documented; the FMS role does not run in "
                   "--legacy-2010 mode")


def parse_dashboard(text: str | None, default_host: str) -> Address | None:
    """``--dashboard``: ``HOST``, ``HOST:PORT`` or ``off``; None/empty is ``default_host``:1165."""
    if text is None or not text.strip():
        return (default_host, A.LEGACY_DASHBOARD)
    text = text.strip()
    if text.lower() in ("off", "none", "no"):
        return None
    if text.count(":") > 1 and not text.startswith("["):  # a bare IPv6 address
        return (text, A.LEGACY_DASHBOARD)
    host, sep, port_text = text.rpartition(":")
    if not sep or not host:
        return (text, A.LEGACY_DASHBOARD)
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"bad --dashboard {text!r}: use HOST, HOST:PORT or off") from None
    if not 1 <= port <= 65535:
        raise ValueError(f"bad --dashboard port {port}: 1..65535")
    return (host.strip("[]"), port)


def parse_roles(text: str | None) -> frozenset[str]:
    if not text:
        return frozenset(ROLE_NAMES)
    roles = {r.strip().lower() for r in text.split(",") if r.strip()}
    aliases = {"roborio": "rio", "robot": "rio", "driverstation": "ds"}
    roles = {aliases.get(r, r) for r in roles}
    bad = sorted(roles - set(ROLE_NAMES))
    if bad or not roles:
        raise ValueError(f"unknown role(s) {', '.join(bad) or '(none)'}: use any of ds, rio, fms")
    return frozenset(roles)


def parse_teams(text: str) -> list[int | None]:
    """``254,1114,2056,118,148,1678`` -> six teams for R1, R2, R3, B1, B2, B3 (``-`` for none)."""
    items = [t.strip() for t in text.split(",")]
    if len(items) > 6:
        raise ValueError(f"a match has six stations; {len(items)} teams given")
    teams: list[int | None] = []
    for t in items:
        if t in ("", "-", "none"):
            teams.append(None)
            continue
        try:
            teams.append(A.check_team(int(t)))
        except ValueError:
            raise ValueError(f"bad team number {t!r} in --teams: 1..25599") from None
    present = [t for t in teams if t is not None]
    if len(set(present)) != len(present):
        raise ValueError("a team may play one station only")
    return teams + [None] * (6 - len(teams))


@dataclass
class FieldConfig:
    roles: frozenset[str] = frozenset(ROLE_NAMES)
    team: int = 1
    station: AllianceStation = AllianceStation.RED1
    teams: list[int | None] | None = None  # six stations, each with its DS and roboRIO: a full field
    fms_teams: list[int | None] | None = None  # the FMS's match when no full field runs
    plan: str = "loopback"
    robot: str | None = None  # a DS's robot address override
    fms: str | None = None  # a DS's FMS address override
    #: On the real plan a DS logs in to the field's FMS (10.0.100.5) unless told not to, as
    #: the NI DS does: on a real field the FMS is always there (``--no-fms`` for a bench).
    no_fms: bool = False
    #: How a DS logs in to its FMS: ``ni`` as the NI Driver Station, ``2027`` as the 2027 FIRST
    #: Driver Station (its hello, control to the port it names, game data in the control packet).
    ds_hello: str = "ni"
    legacy: bool = False
    program: str | None = None  # robot hook file for the fake roboRIOs
    dashboard: str | None = None  # 2010: where the DS sends dashboard packets (default: its own address)
    faults: tuple[str, ...] = ()  # fault specs to apply at start (--fault, roles/sim/faults.py)
    fault_seed: int | None = None  # seed of the faults' random numbers (None: unpredictable)
    log_dir: str | None = None  # where headless mode and the app write log files (None: the user's log dir)
    log_files: bool = True  # write console/event/match log files (roles/runtime/logfiles.py)
    dslog_version: int = 4  # the NI-format .dslog/.dsevents: 4 as the NI DS writes now, 3 for dslogparser
    single_ds: bool = True  # a fake roboRIO follows one DS at a time (False: whoever spoke last)
    #: Where the DS tells dashboards the robot's address (roles/runtime/ds_ip_server.py): a port
    #: on 127.0.0.1, ``off``; None is 1742 (in the ephemeral plan, a port the OS picks).
    ds_ip_server: str | None = None

    def stations(self) -> list[tuple[AllianceStation, int]]:
        """(station, team) of every station with a team, DS/roboRIO pairs to run."""
        if self.teams:
            return [(AllianceStation(i), t) for i, t in enumerate(self.teams) if t is not None]
        return [(self.station, self.team)]

    def match_teams(self) -> list[int | None]:
        if self.fms_teams:
            return list(self.fms_teams)
        if self.teams:
            return list(self.teams)
        teams: list[int | None] = [None] * 6
        teams[int(self.station)] = self.team
        return teams


class _Station(Protocol):
    @property
    def team(self) -> int: ...


_S = TypeVar("_S", bound=_Station)


def station_for(stations: Sequence[_S], team: int | None) -> _S:
    """The station of ``team`` (None: the first), of a live field or of its views; a
    command or step for a team not here is refused (CommandError)."""
    if team is None:
        if not stations:
            raise CommandError("no station runs here")
        return stations[0]
    for st in stations:
        if st.team == team:
            return st
    raise CommandError(f"team {team} is not on this field")


@dataclass
class StationRoles:
    station: AllianceStation
    team: int
    ds: DriverStation | None = None
    rio: FakeRoboRIO | None = None
    ds_name: str = ""
    rio_name: str = ""


@dataclass
class Field:
    config: FieldConfig
    stations: list[StationRoles] = field(default_factory=list)
    fms: FieldManagementSystem | None = None
    fms_name: str = "fms"
    bound: dict[str, dict[str, Address]] = field(default_factory=dict)
    clock: Callable[[], float] | None = None
    faults: Faults = field(default_factory=Faults)  # faults on purpose, shared by every link
    fms_note: str | None = None  # why an FMS asked for does not run (2010 mode)
    #: Robot program files run in processes of their own (roles/runtime/program_host.py): on real
    #: sockets; not on the fake clock of the tests, where they run in the core's thread.
    isolate_programs: bool = True
    #: The DS's robot-address service for dashboards (real sockets only), and why it does not
    #: run when it cannot (the port is another program's).
    ds_ip_server: DsIpServer | None = None
    ds_ip_note: str | None = None

    # -- construction ------------------------------------------------------------------------
    def _rio_spec(self, team: int) -> RoleSpec:
        cfg = self.config
        ip = A.robot_address(team, cfg.plan) if cfg.plan != "real" else "0.0.0.0"
        code = CodeHost()  # runs the robot program the core asks for (in a process of its own when isolated)
        rio = FakeRoboRIO(RioConfig(team=team, program=cfg.program or (LegacyBuiltinProgram if cfg.legacy else None),
                                    reply_port=None if cfg.plan == "ephemeral" else A.DS_UDP,
                                    wire="2010" if cfg.legacy else "2015", single_ds=cfg.single_ds,
                                    isolate=self.isolate_programs), code)
        code.deliver = rio.program_events
        if cfg.legacy:  # UDP 1110 only; NetConsole goes out of the same socket
            return RoleSpec(f"rio {team}", rio, udp={"ds": (ip, A.port(A.ROBOT_UDP, cfg.plan))},
                            kinds=dict(LEGACY_RIO_KINDS), aliases={"netconsole": "ds"}, code=code)
        return RoleSpec(f"rio {team}", rio,
                        udp={"ds": (ip, A.port(A.ROBOT_UDP, cfg.plan)),
                             "ds-fms": (ip, A.port(A.ROBOT_UDP_FMS, cfg.plan))},
                        tcp_servers={"tcp": (ip, A.port(A.ROBOT_TCP, cfg.plan))}, kinds=dict(RIO_KINDS), code=code)

    def _fms_spec(self) -> RoleSpec:
        cfg = self.config
        ip = A.fms_address(cfg.plan) if cfg.plan != "real" else "0.0.0.0"
        fms = FieldManagementSystem(cfg.match_teams(), ds_port=None if cfg.plan == "ephemeral" else A.DS_FMS_UDP)
        return RoleSpec(self.fms_name, fms, udp={"udp": (ip, A.port(A.FMS_UDP, cfg.plan))},
                        tcp_servers={"tcp": (ip, A.port(A.FMS_TCP, cfg.plan))}, kinds=dict(FMS_KINDS))

    def _ds_spec(self, station: AllianceStation, team: int) -> RoleSpec:
        cfg = self.config
        plan = cfg.plan
        rio_bound = self.bound.get(f"rio {team}")
        if rio_bound and not cfg.robot:
            robot_udp = rio_bound["ds"]
            robot_udp_fms, robot_tcp = rio_bound.get("ds-fms", robot_udp), rio_bound.get("tcp", robot_udp)
            if robot_udp[0] == "0.0.0.0":
                robot_udp, robot_udp_fms, robot_tcp = (("127.0.0.1", a[1]) for a in (robot_udp, robot_udp_fms,
                                                                                     robot_tcp))
        else:
            host = A.robot_address(team, plan, cfg.robot)
            robot_udp, robot_udp_fms, robot_tcp = (host, A.ROBOT_UDP), (host, A.ROBOT_UDP_FMS), (host, A.ROBOT_TCP)
        fms_udp = fms_tcp = None
        fms_bound = self.bound.get(self.fms_name)
        if cfg.legacy:
            if cfg.fms:
                self._note_fms()
            return self._legacy_ds_spec(station, team, robot_udp, robot_tcp)
        if fms_bound and not cfg.fms:
            fms_udp, fms_tcp = fms_bound["udp"], fms_bound["tcp"]
            if fms_udp[0] == "0.0.0.0":
                fms_udp, fms_tcp = ("127.0.0.1", fms_udp[1]), ("127.0.0.1", fms_tcp[1])
        elif cfg.fms or "fms" in cfg.roles or (plan == "real" and not cfg.no_fms):
            host = A.fms_address(plan, cfg.fms)
            fms_udp, fms_tcp = (host, A.FMS_UDP), (host, A.FMS_TCP)
        # A loopback --robot is most likely WPILib's simulator (roles/cores/ds.py: one POV per stick
        # until the robot's status says it is a roboRIO).
        simulator = bool(cfg.robot) and A.is_loopback(robot_udp[0])
        ds = DriverStation(team, robot_udp, robot_tcp, station=station, robot_udp_fms=robot_udp_fms,
                           fms_tcp=fms_tcp, fms_udp=fms_udp, legacy=cfg.legacy, simulator=simulator,
                           fms_hello=cfg.ds_hello)
        ip = A.ds_address(team, plan)
        udp = {"robot": (ip, A.port(A.DS_UDP, plan))}
        aliases = {}
        if fms_udp is not None:
            udp["fms"] = (ip, A.port(A.DS_FMS_UDP, plan))
            if plan == "ephemeral":
                # The FMS answers the port a status came from: send from the socket it answers to.
                aliases["fms-out"] = "fms"
            else:
                udp["fms-out"] = (ip, A.DS_FMS_SOURCE)
                # A real DS takes control on 1120 too: an FMS in "FMS Lite" mode (Cheesy
                # Arena's setting) sends there.
                udp["fms-lite"] = (ip, A.DS_FMS_UDP_LITE)
        return RoleSpec(f"ds {team}", ds, udp=udp, kinds=dict(DS_KINDS), aliases=aliases)

    def _legacy_ds_spec(self, station: AllianceStation, team: int, robot_udp: Address,
                        robot_tcp: Address) -> RoleSpec:
        """A 2010 DS: robot UDP 1150, NetConsole 6666, the dashboard out of the robot socket."""
        plan = self.config.plan
        ds = DriverStation(team, robot_udp, robot_tcp, station=station, legacy=True)
        ip = A.ds_address(team, plan)
        ds.legacy.dashboard = parse_dashboard(self.config.dashboard, "127.0.0.1" if ip == "0.0.0.0" else ip)
        udp = {"robot": (ip, A.port(A.DS_UDP, plan)), "netconsole": (ip, A.port(A.NETCONSOLE, plan))}
        return RoleSpec(f"ds {team}", ds, udp=udp, kinds=dict(LEGACY_DS_KINDS), aliases={"dashboard": "robot"})

    def _note_fms(self) -> None:
        if self.fms_note is None:
            self.fms_note = LEGACY_FMS_NOTE
            log.warning("%s", LEGACY_FMS_NOTE)

    def _after_bind(self) -> None:
        self._name_hello_ports()
        self._tell_netconsole()

    def _name_hello_ports(self) -> None:
        """A 2027 DS's hello names the port its FMS control must come to: the ``"fms"``
        channel's, which only binding tells in the ephemeral plan (1121 otherwise)."""
        for st in self.stations:
            fms = self.bound.get(st.ds_name, {}).get("fms")
            if st.ds is not None and fms is not None and fms[1]:
                st.ds.fms.hello_port = fms[1]

    def _tell_netconsole(self) -> None:
        """2010, ephemeral plan: each fake robot learns where its DS listens for NetConsole
        (an OS-chosen port the robot cannot guess). In the loopback and real plans the robot
        sends to the address its DS's packets come from, port 6666, as a cRIO's console did."""
        if not self.config.legacy or self.config.robot or self.config.plan != "ephemeral":
            return
        for st in self.stations:
            ds_bound = self.bound.get(st.ds_name, {})
            if st.rio is not None and "netconsole" in ds_bound:
                host, port = ds_bound["netconsole"]
                st.rio.send_netconsole_to(("127.0.0.1" if host == "0.0.0.0" else host, port))

    def _plan_order(self) -> list[tuple[str, Any]]:
        """What to bind, servers first, so a DS can be pointed at the ports they got."""
        cfg = self.config
        order: list[tuple[str, Any]] = []
        for station, team in cfg.stations():
            self.stations.append(StationRoles(station, team))
        if "rio" in cfg.roles:
            order += [("rio", s) for s in self.stations]
        if "fms" in cfg.roles:
            if cfg.legacy:
                self._note_fms()  # said plainly, never a silent failure
            else:
                order.append(("fms", None))
        if "ds" in cfg.roles:
            order += [("ds", s) for s in self.stations]
        return order

    def _make(self, what: str, st: StationRoles | None) -> RoleSpec:
        if what == "rio":
            assert st is not None  # a station's role: only the FMS has none
            spec = self._rio_spec(st.team)
            assert isinstance(spec.core, FakeRoboRIO)
            st.rio, st.rio_name = spec.core, spec.name
        elif what == "fms":
            spec = self._fms_spec()
            assert isinstance(spec.core, FieldManagementSystem)
            self.fms = spec.core
        else:
            assert st is not None  # as for the rio
            spec = self._ds_spec(st.station, st.team)
            assert isinstance(spec.core, DriverStation)
            st.ds, st.ds_name = spec.core, spec.name
        if st is not None:
            spec.group = ("station", st.station)  # a station's DS and robot beat together
        return spec

    async def start(self, runtime) -> None:
        """Bind every role on real sockets (call on the runtime's loop)."""
        self.clock = runtime.clock
        self._install_faults()
        runtime.faults = self.faults
        for what, st in self._plan_order():
            spec = self._make(what, st)
            try:
                host = await runtime.add(spec)
            except OSError as exc:
                raise OSError(f"{spec.name}: cannot bind {_describe(spec)}: {exc.strerror or exc}") from None
            self.bound[spec.name] = dict(host.bound)
        self._after_bind()
        await self._start_ds_ip_server(runtime)

    async def _start_ds_ip_server(self, runtime) -> None:
        """Dashboards in "Driver Station" mode ask the DS where the robot is: one service per
        field, as the NI DS is one per computer, for the DS of --team if it runs here, else the
        first station's (roles/runtime/ds_ip_server.py). The 2010 DS had none. A port another
        program has is said (:attr:`ds_ip_note`) and the field runs on without it."""
        cfg = self.config
        st = serving_station(self.stations, cfg.team)
        port = parse_port(cfg.ds_ip_server, cfg.plan)
        if cfg.legacy or st is None or port is None:
            return
        ds, name = st.ds, st.ds_name

        def resolved(host: str) -> str | None:
            role = runtime.hosts.get(name)
            return role.resolved(host) if role is not None else None

        server = DsIpServer(lambda: robot_ip_of(ds, resolved), port)
        if await server.start():
            self.ds_ip_server = server
            runtime.services.append(server)
        else:
            self.ds_ip_note = server.note

    def start_sim(self, net) -> None:
        """Bind every role on an in-memory :class:`~roles.sim.simnet.SimNetwork`."""
        self.clock = lambda: net.now
        self.isolate_programs = False
        self._install_faults()
        net.faults = self.faults
        for what, st in self._plan_order():
            spec = self._make(what, st)
            self.bound[spec.name] = dict(net.add(spec).bound)
        self._after_bind()

    def _install_faults(self) -> None:
        """The command line's faults (a bad spec raises ValueError saying what is wrong)."""
        if self.config.fault_seed is not None:
            self.faults.rng.seed(self.config.fault_seed)
        for spec in self.config.faults:
            self.faults.apply(spec)

    # -- lookups -----------------------------------------------------------------------------
    def station_for(self, team: int | None) -> StationRoles:
        return station_for(self.stations, team)

    def describe_bound(self) -> list[str]:
        lines = []
        for name, links in self.bound.items():
            parts = ", ".join(f"{link} {ip}:{port}" for link, (ip, port) in links.items())
            lines.append(f"{name}: {parts}")
        if self.ds_ip_server is not None and self.ds_ip_server.address is not None:
            ip, port = self.ds_ip_server.address
            lines.append(f"ds-ip-server: tcp {ip}:{port}")
        return lines

    # -- commands ----------------------------------------------------------------------------
    def host_for(self, command: Command) -> str | None:
        """The name of the role a command acts on (the shell polls it after the command)."""
        if isinstance(command, Fault):
            return None  # the shell's faults, no core: a cut's end releases held data by itself
        if isinstance(command, FMS_COMMANDS):
            return self.fms_name if self.fms else None
        st = self.station_for(command.team)
        if isinstance(command, SetBattery):
            return st.rio_name or None
        return st.ds_name or None

    def execute(self, command: Command, now: float) -> str | None:
        """Carry out one command on the core it acts on (its ``apply``); returns a line to
        print (``fault``), or raises CommandError."""
        if isinstance(command, Fault):
            return self._fault(command, now)
        if isinstance(command, FMS_COMMANDS):
            if self.fms is None:
                raise CommandError(self.fms_note or "no FMS runs here (add it with --roles ...,fms)")
            self.fms.apply(command, now)
            return None
        st = self.station_for(command.team)
        if isinstance(command, SetBattery):
            if st.rio is None:
                raise CommandError("no fake roboRIO runs here (add it with --roles ...,rio)")
            st.rio.apply(command, now)
        elif st.ds is None:
            raise CommandError("no Driver Station runs here (add it with --roles ds,...)")
        else:
            st.ds.apply(command, now)
        return None

    def _fault(self, command: Fault, now: float) -> str:
        """``fault SPEC`` changes the faults; ``fault`` alone lists them with their counters."""
        if command.team is not None:
            raise CommandError("faults act on a link for the whole field: drop the @TEAM")
        if command.spec is not None:
            try:
                self.faults.apply(command.spec)
            except FaultSpecError as exc:
                raise CommandError(str(exc)) from None
        return "\n".join(f"fault {line}" for line in self.faults.describe())

    # -- status ------------------------------------------------------------------------------
    def snapshot(self, now: float) -> dict[str, Any]:
        out: dict[str, Any] = {"stations": []}
        for st in self.stations:
            entry: dict[str, Any] = {"team": st.team, "station": st.station.label}
            if st.ds is not None:
                entry["ds"] = st.ds.snapshot()
                if st.ds.legacy is not None:
                    entry["legacy"] = st.ds.legacy.snapshot()
            if st.rio is not None:
                entry["rio"] = st.rio.snapshot()
            out["stations"].append(entry)
        if self.fms is not None:
            out["fms"] = self.fms.snapshot(now)
        if self.fms_note:
            out["fms_note"] = self.fms_note
        return out


def _describe(spec: RoleSpec) -> str:
    parts = [f"UDP {ip}:{port}" for ip, port in spec.udp.values()]
    parts += [f"TCP {ip}:{port}" for ip, port in spec.tcp_servers.values()]
    return ", ".join(parts)
