"""Faults on purpose (roles/sim/faults.py): the spec language, the decisions on a seeded RNG,
and the same faults applied by the fake-clock network and by the asyncio shell on real
loopback sockets (ephemeral plan), end to end through a field."""

from __future__ import annotations

import asyncio
import socket
import time

import pytest

from protocol.ds_to_rio import ControlPacket
from protocol.enums import Mode
from roles.cores.core import CommandError
from roles.runtime.field import Field, FieldConfig
from roles.runtime.shell import Runtime
from roles.sim.faults import (LINKS, MAX_FLOWS, TCP_RTO, Faults, FaultSpecError, LinkFault,
                              link_for_kind, parse_fault)
from roles.sim.simnet import SimNetwork

from fieldbox.language import CommandSyntaxError, parse

# -- the spec language ------------------------------------------------------------------------
GOOD_SPECS = [
    ("ds-rio:loss=10%,delay=30ms~10ms,dup=1%,reorder=5%,corrupt=1%",
     LinkFault(loss=0.10, delay=0.030, jitter=0.010, dup=0.01, reorder=0.05, corrupt=0.01)),
    ("ds-rio:cut", LinkFault(cut=True)),
    ("ds-rio: loss = 2.5 %", LinkFault(loss=0.025)),       # spaces are ignored
    ("DS-RIO:LOSS=10", LinkFault(loss=0.10)),              # case too; a bare number is a percentage
    ("ds-rio:delay=0.5s", LinkFault(delay=0.5)),
    ("ds-rio:delay=250us", LinkFault(delay=0.00025)),
    ("ds-rio:delay=40", LinkFault(delay=0.040)),           # a bare time is milliseconds
    ("ds-rio:latency=5ms,jitter=2ms", LinkFault(delay=0.005, jitter=0.002)),
    ("ds-rio:cut=on,drop=1%", LinkFault(cut=True, loss=0.01)),
    ("ds-rio:duplicate=3%,corruption=4%", LinkFault(dup=0.03, corrupt=0.04)),
]

BAD_SPECS = [  # (spec, words the error must say)
    ("", "empty fault spec"),
    ("ds-rio", "says which link but not what fault"),
    ("loss=10%", "no ':'"),
    ("robot:cut", "unknown link 'robot'"),
    ("ds-rio:", "nothing after"),
    ("ds-rio:loss=150%", "loss must be 0..100%"),
    ("ds-rio:loss=-1%", "loss must be 0..100%"),
    ("ds-rio:loss=ten", "loss must be a percentage"),
    ("ds-rio:loss=nan", "loss must be 0..100%"),
    ("ds-rio:delay=fast", "delay must be a time"),
    ("ds-rio:delay=11s", "delay must be 0..10 s"),
    ("ds-rio:delay=30ms~", "jitter must be a time"),
    ("ds-rio:delay=30ms~1ms,jitter=2ms", "jitter given twice"),
    ("ds-rio:loss", "loss needs a value"),
    ("ds-rio:loss=1%,loss=2%", "loss given twice"),
    ("ds-rio:wobble=3", "unknown setting 'wobble'"),
    ("ds-rio:cut=maybe", "use cut, uncut"),
    ("ds-rio:,cut", "an empty setting"),
]


@pytest.mark.parametrize("spec,want", GOOD_SPECS)
def test_good_specs(spec, want):
    faults = Faults(seed=1)
    lines = faults.apply(spec)
    assert faults.links["ds-rio"] == want
    assert lines == [f"ds-rio: {want.describe()}"]
    # What describe() prints parses back to the same settings.
    again = Faults()
    again.apply(f"ds-rio:{want.describe()}")
    assert again.links["ds-rio"] == want


@pytest.mark.parametrize("spec,words", BAD_SPECS)
def test_bad_specs_say_what_is_wrong_and_change_nothing(spec, words):
    faults = Faults()
    faults.apply("ds-rio:loss=5%")
    with pytest.raises(FaultSpecError) as info:
        faults.apply(spec)
    assert words in str(info.value)
    assert faults.links["ds-rio"] == LinkFault(loss=0.05)


def test_several_links_all_clear_and_merging():
    assert parse_fault("all:cut").links == LINKS and parse_fault("clear").ops == (("clear", None),)
    assert parse_fault("ds-rio+ds-rio+ds-fms:cut").links == ("ds-rio", "ds-fms")
    f = Faults()
    f.apply("ds-rio+ds-fms-tcp:cut")
    assert [link for link in LINKS if f.is_cut(link)] == ["ds-rio", "ds-fms-tcp"]
    f.apply("all:loss=1%")
    assert all(f.links[link].loss == 0.01 for link in LINKS)
    f.apply("ds-rio:delay=30ms")  # sets what it names, keeps the rest
    assert f.links["ds-rio"] == LinkFault(loss=0.01, delay=0.03, cut=True)
    f.apply("ds-rio:uncut")
    assert f.links["ds-rio"] == LinkFault(loss=0.01, delay=0.03)
    f.apply("ds-rio:clear,dup=2%")  # in order: clear, then set
    assert f.links["ds-rio"] == LinkFault(dup=0.02)
    f.apply("ds-rio:loss=0,dup=0")
    assert not f.active("ds-rio")
    f.apply("clear")
    assert not f.any_active and all(f.links[link] == LinkFault() for link in LINKS)
    assert f.changes == 7


def test_link_of_every_kind():
    assert link_for_kind("ds-to-rio") == link_for_kind("rio-to-ds") == "ds-rio"
    assert link_for_kind("ds-to-rio-tcp") == link_for_kind("rio-to-ds-tcp") == "ds-rio-tcp"
    assert link_for_kind("ds-to-fms") == link_for_kind("fms-to-ds") == "ds-fms"
    assert link_for_kind("ds-to-fms-tcp") == link_for_kind("fms-to-ds-tcp") == "ds-fms-tcp"
    assert link_for_kind("legacy-ds-to-robot") == "ds-rio"
    assert link_for_kind("legacy-dashboard") is None and link_for_kind("") is None


def test_commands_parse_fault():
    cmd = parse("fault ds-rio:loss=10%, delay=30ms~10ms")
    assert cmd.verb == "fault" and cmd.spec == "ds-rio:loss=10%,delay=30ms~10ms"
    assert parse_fault(cmd.spec).ops == (("loss", 0.1), ("jitter", 0.01), ("delay", 0.03))
    assert parse("fault").spec is None and parse("faults").verb == "fault"
    with pytest.raises(CommandSyntaxError, match="unknown link"):
        parse("fault rio:cut")


# -- datagram decisions ------------------------------------------------------------------------
PACKET = bytes(range(40))


def run(f: Faults, n: int = 2000, link: str = "ds-rio", flow="a", period: float = 0.020):
    """Offer ``n`` packets (each its index) every ``period``; returns (send time, index,
    delivery time, bytes) of what is delivered."""
    out = []
    for i in range(n):
        now = 100.0 + i * period
        for delay, data in f.datagram(link, flow, i.to_bytes(4, "big") + PACKET, now):
            out.append((now, i, now + delay, data))
    return out


def test_no_fault_passes_untouched_and_counts_nothing():
    f = Faults(seed=1)
    assert f.datagram("ds-rio", "a", PACKET, 1.0) == [(0.0, PACKET)]
    assert f.datagram(None, "a", PACKET, 1.0) == [(0.0, PACKET)]
    assert f.counters["ds-rio"].seen == 0 and not f.any_active


def test_loss_drops_about_that_share_and_counts_it():
    f = Faults(seed=2)
    f.apply("ds-rio:loss=10%")
    got = run(f, 5000)
    c = f.counters["ds-rio"]
    assert c.seen == 5000 and c.dropped == 5000 - len(got)
    assert 400 < c.dropped < 600
    assert all(delay == now for now, _, delay, _ in got)  # no delay asked: sent at once


def test_same_seed_same_decisions():
    a, b = Faults(seed=42), Faults(seed=42)
    for f in (a, b):
        f.apply("ds-rio:loss=10%,delay=30ms~10ms,dup=5%,reorder=5%,corrupt=5%")
    assert run(a, 500) == run(b, 500)
    assert a.counters == b.counters


def test_delay_and_jitter_keep_the_order_of_a_flow():
    f = Faults(seed=3)
    f.apply("ds-rio:delay=30ms~10ms")
    got = run(f, 3000)
    assert len(got) == 3000 and f.counters["ds-rio"].delayed == 3000
    delays = [t - now for now, _, t, _ in got]
    assert 0.020 - 1e-9 <= min(delays) and max(delays) <= 0.040 + 1e-9
    assert sum(delays) / len(delays) == pytest.approx(0.030, abs=0.002)
    order = [i for *_, i in sorted((t, i) for _, i, t, _ in got)]
    assert order == sorted(order)  # jitter alone never reorders
    # ...at 2 ms spacing too, where jitter is bigger than the gap (deliveries bunch instead)
    got = run(f, 1000, flow="fast", period=0.002)
    assert [i for *_, i in sorted((t, i) for _, i, t, _ in got)] == list(range(1000))


def test_reorder_lets_the_next_packet_overtake():
    f = Faults(seed=4)
    f.apply("ds-rio:reorder=10%")
    got = run(f, 2000)
    c = f.counters["ds-rio"]
    assert 150 < c.reordered < 250
    arrival = [i for _, i in sorted((t, i) for _, i, t, _ in got)]
    held_back = {i for now, i, t, _ in got if t > now}
    overtaken = {i for pos, i in enumerate(arrival) if any(j > i for j in arrival[:pos])}
    assert len(held_back) == c.reordered
    # Every packet a later one overtook was held back; most held back were overtaken (two
    # held back in a row: the first may still arrive before anything sent after it).
    assert overtaken <= held_back and len(overtaken) > 0.8 * c.reordered
    held = [t - now for now, _, t, _ in got if t > now]
    assert all(0.020 < d < 0.040 for d in held)  # 1.5 x the 20 ms interval
    # on a 500 ms flow (FMS control) the hold-back scales with the interval
    f2 = Faults(seed=4)
    f2.apply("ds-fms:reorder=50%")
    slow = run(f2, 40, link="ds-fms", period=0.5)
    assert max(t - now for now, _, t, _ in slow) == pytest.approx(0.75, abs=0.01)


def test_duplicates_follow_their_original():
    f = Faults(seed=5)
    f.apply("ds-rio:dup=20%")
    got = run(f, 1000)
    c = f.counters["ds-rio"]
    assert len(got) == 1000 + c.duplicated and 150 < c.duplicated < 250
    by_index: dict[int, list] = {}
    for _, i, t, data in got:
        by_index.setdefault(i, []).append((t, data))
    for copies in by_index.values():
        assert len({d for _, d in copies}) == 1


def test_corruption_flips_one_to_three_bits():
    f = Faults(seed=6)
    f.apply("ds-rio:corrupt=50%")
    got = run(f, 1000)
    changed = 0
    for _, i, _, data in got:
        original = i.to_bytes(4, "big") + PACKET
        bits = sum(bin(a ^ b).count("1") for a, b in zip(original, data))
        assert len(data) == len(original) and bits <= 3
        changed += bits > 0
    assert changed == f.counters["ds-rio"].corrupted and 400 < changed < 600


def test_cut_drops_everything_both_ways_until_uncut():
    f = Faults(seed=7)
    f.apply("ds-rio:cut")
    assert run(f, 100) == [] and f.counters["ds-rio"].dropped == 100
    assert run(f, 10, flow="b") == []
    f.apply("ds-rio:uncut")
    assert len(run(f, 100)) == 100


def test_flows_are_bounded():
    f = Faults(seed=8)
    f.apply("ds-rio:delay=1ms")
    for i in range(MAX_FLOWS + 500):
        f.datagram("ds-rio", ("host", "ch", ("10.0.0.1", i)), PACKET, float(i))
    assert len(f._flows) == MAX_FLOWS
    f.apply("clear")
    assert not f._flows


# -- TCP lines ---------------------------------------------------------------------------------
def test_tcp_delay_keeps_order_and_loss_is_a_retransmission_delay():
    f = Faults(seed=9)
    f.apply("ds-rio-tcp:delay=30ms~20ms,loss=20%,dup=50%,reorder=50%")
    flow = ("rio", "c1", "out")
    for i in range(200):
        assert f.stream_involved("ds-rio-tcp", flow)
        f.stream_push("ds-rio-tcp", flow, bytes([i]), 10.0 + i * 0.001)
    got, now = [], 10.0
    while (deadline := f.stream_deadline(flow)) is not None:
        now = max(now, deadline)
        got += f.stream_take(flow, now)
    assert got == [bytes([i]) for i in range(200)]  # all of it, once, in order
    c = f.counters["ds-rio-tcp"]
    assert c.retransmitted > 10 and c.duplicated == 0 and c.reordered == 0 and c.dropped == 0
    assert now >= 10.0 + 0.2 + TCP_RTO  # the last write waited at least for one retransmission
    assert not f.stream_involved(None, flow)  # drained: the line is gone


def test_tcp_cut_holds_then_releases_in_order():
    f = Faults(seed=10)
    flow = ("ds", "robot-tcp", "out")
    f.stream_push("ds-rio-tcp", flow, b"before", 1.0)  # no fault: due at once
    f.apply("ds-rio-tcp:cut")
    f.stream_push("ds-rio-tcp", flow, b"during", 1.5)
    assert f.stream_take(flow, 2.0) == [] and f.stream_deadline(flow) is None
    assert f.stream_queued(flow) == len(b"beforeduring")
    assert f.counters["ds-rio-tcp"].held == 1
    assert not f.connect_allowed("ds-rio-tcp") and f.counters["ds-rio-tcp"].refused_connects == 1
    f.apply("ds-rio-tcp:uncut")
    assert f.connect_allowed("ds-rio-tcp")
    assert f.waiting_flows() == [flow]
    assert f.stream_take(flow, 30.0) == [b"before", b"during"]
    assert f.waiting_flows() == [] and not f.any_active


def test_tcp_line_forgotten_when_the_connection_closes():
    f = Faults()
    f.apply("ds-fms-tcp:cut")
    f.stream_push("ds-fms-tcp", "x", b"abc", 0.0)
    f.stream_closed("x")
    assert f.waiting_flows() == [] and f.stream_queued("x") == 0


def test_listeners_hear_every_change():
    f = Faults()
    heard = []
    f.listeners.append(lambda: heard.append(f.changes))
    f.apply("ds-rio:cut")
    f.cut("ds-rio", False)
    f.clear()
    f.reset_counters()
    assert heard == [1, 2, 3, 4]


# -- through a field on the fake clock ----------------------------------------------------------
def sim_field(*faults: str, roles=("ds", "rio"), seed: int = 1, **kw):
    net = SimNetwork()
    field = Field(FieldConfig(roles=frozenset(roles), team=254, plan="ephemeral", faults=faults,
                              fault_seed=seed, **kw))
    field.start_sim(net)
    return net, field


def test_sim_loss_counts_on_both_sides():
    net, field = sim_field("ds-rio:loss=10%")
    net.run_for(20.0)
    ds, rio = field.stations[0].ds, field.stations[0].rio
    c = field.faults.counters["ds-rio"]
    assert ds.link.robot_comms and ds.link.robot_code
    # Both directions are faulted: DS -> robot and robot -> DS packets are offered.
    assert c.seen == ds.link.echoes.sent_packets + rio.stats["rio->ds"].packets_out
    assert 0.08 < c.dropped / c.seen < 0.12
    # A control packet or its echo lost counts as one lost packet at the DS.
    assert ds.link.echoes.lost_packets == pytest.approx(ds.link.echoes.sent_packets - rio.stats["rio->ds"].packets_out + c.dropped
                                            - (ds.link.echoes.sent_packets - rio.stats["ds->rio"].packets_in), abs=60)
    assert 0.15 < ds.link.echoes.lost_packets / ds.link.echoes.sent_packets < 0.23  # 1 - 0.9 * 0.9


def test_sim_delay_shows_in_the_trip_time_both_ways():
    net, field = sim_field("ds-rio:delay=30ms")
    net.run_for(5.0)
    ds = field.stations[0].ds
    assert ds.link.robot_comms
    assert ds.trip_ms == pytest.approx(60.0, abs=1.0)  # 30 ms each way


def test_sim_tcp_cut_holds_console_lines_and_releases_them_in_order():
    net, field = sim_field()
    net.run_for(2.0)
    ds = field.stations[0].ds
    assert ds.tcp.state == "open"
    before = ds.tcp.console_total
    field.execute(parse("fault ds-rio-tcp:cut"), net.now)
    net.command(field.stations[0].ds_name, lambda: ds.enable(net.now))
    net.run_for(0.5)
    net.command(field.stations[0].ds_name, lambda: ds.disable(net.now))
    net.run_for(2.0)
    assert field.stations[0].rio.control.enabled is False and ds.tcp.console_total == before  # nothing came
    assert field.faults.counters["ds-rio-tcp"].held >= 2
    reply = field.execute(parse("fault ds-rio-tcp:uncut"), net.now)
    assert "ds-rio-tcp: none" in reply
    net.run_for(0.01)
    texts = [t for _, _, t in list(ds.tcp.console)[-(ds.tcp.console_total - before):]]
    assert texts == ["Robot enabled in teleop", "Robot disabled"]


def test_sim_connect_during_a_cut_times_out_and_works_after():
    net, field = sim_field("ds-rio-tcp:cut")
    ds = field.stations[0].ds
    net.run_for(5.0)
    assert ds.link.robot_comms and ds.tcp.state != "open"
    assert field.faults.counters["ds-rio-tcp"].refused_connects >= 2
    field.execute(parse("fault clear"), net.now)
    net.run_for(3.5)
    assert ds.tcp.state == "open"


def test_sim_fms_link_cut_detaches_the_ds():
    net, field = sim_field(roles=("ds", "rio", "fms"))
    net.run_for(3.0)
    ds, fms = field.stations[0].ds, field.fms
    assert ds.fms.attached and fms.stations[0].ds_link
    field.execute(parse("fault ds-fms:cut"), net.now)
    net.run_for(1.1)
    assert not ds.fms.attached and not fms.stations[0].report.udp_link
    assert fms.stations[0].tcp_connected  # TCP is quiet, not closed (yet)
    field.execute(parse("fault ds-fms:uncut"), net.now)
    net.run_for(2.0)
    assert ds.fms.attached and fms.stations[0].ds_link


def test_field_fault_command_refuses_a_team_and_lists():
    net, field = sim_field()
    with pytest.raises(CommandError, match="drop the @TEAM"):
        field.execute(parse("@254 fault ds-rio:cut"), net.now)
    assert field.host_for(parse("fault ds-rio:cut")) is None
    text = field.execute(parse("fault"), net.now)
    assert text.splitlines() == [f"fault {link}: none" for link in LINKS]


def test_a_bad_start_spec_is_a_value_error():
    with pytest.raises(ValueError, match="unknown link"):
        sim_field("robot:cut")


def test_cli_fault_option_is_checked_and_carried(tmp_path):
    from fieldbox.cli import build_parser
    from fieldbox.headless import config_from_args

    args = build_parser().parse_args(["--roles", "ds,rio,fms", "--fault", "ds-rio:loss=10%", "--fault", "ds-fms:cut",
                                      "--log-dir", str(tmp_path)])
    config = config_from_args(args)
    assert config.faults == ("ds-rio:loss=10%", "ds-fms:cut") and config.log_dir == str(tmp_path)
    with pytest.raises(ValueError, match=r"--fault 'ds-rio:loss=200%': loss must be 0..100%"):
        config_from_args(build_parser().parse_args(["--fault", "ds-rio:loss=200%"]))


# -- the same faults on real sockets (ephemeral plan, loopback only) ---------------------------
async def _until(check, timeout: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if check():
            return True
        await asyncio.sleep(0.01)
    return check()


async def _socket_field(*faults: str):
    runtime = Runtime()
    field = Field(FieldConfig(roles=frozenset({"ds", "rio"}), team=254, plan="ephemeral", faults=faults,
                              fault_seed=1))
    await field.start(runtime)
    runtime.start()
    return runtime, field


async def test_sockets_delay_both_ways():
    runtime, field = await _socket_field("ds-rio:delay=30ms")
    try:
        ds = field.stations[0].ds
        assert await _until(lambda: ds.link.robot_comms and len(ds.link.echoes.trip.samples) > 30)
        assert ds.trip_ms == pytest.approx(60.0, abs=15.0)
        assert field.faults.counters["ds-rio"].delayed > 60
    finally:
        await runtime.close()


async def test_sockets_tcp_cut_holds_and_releases_in_order():
    runtime, field = await _socket_field()
    try:
        ds = field.stations[0].ds
        host = runtime.hosts[field.stations[0].ds_name]
        assert await _until(lambda: ds.tcp.state == "open" and ds.link.robot_code)
        await asyncio.sleep(0.2)
        before = ds.tcp.console_total
        field.execute(parse("fault ds-rio-tcp:cut"), runtime.clock())
        ds.enable(runtime.clock())
        host.kick()
        await asyncio.sleep(0.3)
        ds.disable(runtime.clock())
        host.kick()
        await asyncio.sleep(0.5)
        assert ds.tcp.console_total == before and field.faults.counters["ds-rio-tcp"].held >= 2
        field.execute(parse("fault ds-rio-tcp:uncut"), runtime.clock())
        assert await _until(lambda: ds.tcp.console_total - before >= 2)
        texts = [t for _, _, t in list(ds.tcp.console)[-(ds.tcp.console_total - before):]]
        assert texts == ["Robot enabled in teleop", "Robot disabled"]
    finally:
        await runtime.close()


async def test_sockets_a_foreign_sender_is_faulted_on_arrival():
    """A peer outside this process (a raw socket here, a real DS in life): its packets meet
    the fault when they arrive, so a cut stops both directions."""
    runtime = Runtime()
    field = Field(FieldConfig(roles=frozenset({"rio"}), team=254, plan="ephemeral", faults=("ds-rio:cut",)))
    await field.start(runtime)
    runtime.start()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    try:
        rio = field.stations[0].rio
        dest = field.bound[field.stations[0].rio_name]["ds"]
        for seq in range(10):
            sock.sendto(ControlPacket(seq, mode=Mode.TELEOP).encode(), dest)
        await asyncio.sleep(0.2)
        assert rio.stats["ds->rio"].packets_in == 0
        assert field.faults.counters["ds-rio"].dropped == 10
        field.execute(parse("fault clear"), runtime.clock())
        sock.sendto(ControlPacket(11, mode=Mode.TELEOP).encode(), dest)
        assert await _until(lambda: rio.stats["ds->rio"].packets_in == 1)
    finally:
        sock.close()
        await runtime.close()
