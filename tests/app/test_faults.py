"""The Faults panel: counters move when faults happen on the wire (SimEngine)."""

from __future__ import annotations

from protocol import rio_to_ds
from roles.runtime.field import FieldConfig

from fieldbox.panels.faults import RECENT, FaultsPanel

from .helpers import Wire, make_app, one_team, step, text_of


def shown(app, row: str, column: str) -> str:
    return str(app.query_one("#faults-table").get_cell(row, column))


async def test_a_brownout_moves_the_12v_and_brownout_counters():
    app, engines = make_app(one_team(), "faults")
    async with app.run_test(size=(140, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 1.0)
        panel = app.query_one(FaultsPanel)
        assert panel.value("ds254-status", "brownouts") == 0
        assert panel.value("ds254-tcp", "12v") == 0
        builds = panel.builds
        rows = app.query_one("#faults-table").row_count

        assert app.run_command("battery 6.0")  # the headless command: the battery sags below 6.8 V
        await step(pilot, 0.5)
        # the wire: status packets carry the brownout bit, robot TCP a 0x04 frame with 12 V = 1
        assert any(s.brownout for s in wire.robot_status())
        faults = [m for m in wire.robot_tcp() if isinstance(m, rio_to_ds.DisableFaults)]
        assert faults and faults[-1].rail_12v == 1
        # the panel: the DS's counters and the roboRIO's own moved, and are highlighted
        assert panel.value("ds254-status", "brownouts") == 1
        assert panel.value("ds254-tcp", "12v") == 1
        assert panel.value("rio254-status", "12v") == 1
        assert panel.value("rio254-status", "brownouts") == 1
        assert panel.highlighted("ds254-tcp", "12v") and panel.highlighted("ds254-status", "brownouts")
        assert shown(app, "ds254-tcp", "12v") == "1"
        assert not panel.highlighted("ds254-tcp", "comms")  # nothing else went up
        # updated in place: the same rows, the table never rebuilt
        assert panel.builds == builds and app.query_one("#faults-table").row_count == rows

        await step(pilot, RECENT + 0.5)  # the highlight fades, the count stays
        assert not panel.highlighted("ds254-tcp", "12v")
        assert panel.value("ds254-tcp", "12v") == 1


async def test_garbage_on_a_link_counts_bad_packets_with_the_reason():
    app, engines = make_app(FieldConfig(team=254), "faults")
    async with app.run_test(size=(140, 40)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        panel = app.query_one(FaultsPanel)
        assert panel.value("ds254-status", "bad") == 0
        assert panel.value("fms-udp", "bad") == 0

        garbage = {"rio 254": b"\x00\x01garbage", "ds 254": b"\xff"}
        sent = []

        def corrupt_once(host, link, dest, data, now):
            # the next robot status (from port 1115: the DS is under the FMS) and the next
            # DS -> FMS status become garbage, once each
            if (host, link) in (("rio 254", "ds-fms"), ("rio 254", "ds"), ("ds 254", "fms-out")):
                if host not in sent:
                    sent.append(host)
                    return [(0.0, garbage[host])]
            return [(0.0, data)]

        engine.net.filters.append(corrupt_once)
        await step(pilot, 0.6)
        assert sorted(sent) == ["ds 254", "rio 254"]
        assert panel.value("ds254-status", "bad") == 1
        assert panel.highlighted("ds254-status", "bad")
        assert panel.value("fms-udp", "bad") == 1
        assert panel.value("fms-R1", "bad") == 0  # too short to read the team: the station is unknown
        # the decoder's reason is shown on the row
        assert "status" in shown(app, "ds254-status", "error").lower()
        assert panel.value("ds254-status", "error") == engine.field.stations[0].ds.stats["rio->ds"].last_error
        assert str(app.query_one("#faults-table").get_cell("fms-R1", "link")).startswith("FMS  R1 (254)")


async def test_a_full_field_has_a_row_per_link():
    teams = [254, 1114, 2056, 118, 148, 1678]
    app, _ = make_app(FieldConfig(teams=teams), "faults")
    async with app.run_test(size=(140, 40)) as pilot:
        await step(pilot, 0.5)
        table = app.query_one("#faults-table")
        # five DS links and three roboRIO links per team, then the FMS's two and its six stations
        assert table.row_count == 6 * (5 + 3) + 2 + 6
        assert panel_rows_of(app, 1678) == 8
        assert "FMS: refused connections 0" in text_of(app, "#faults-other")


def panel_rows_of(app, team: int) -> int:
    table = app.query_one("#faults-table")
    return sum(1 for key in table.rows if str(key.value).startswith((f"ds{team}-", f"rio{team}-")))


async def test_a_fault_while_the_tab_is_hidden_is_highlighted_when_shown():
    app, engines = make_app(one_team(), "ds")
    async with app.run_test(size=(140, 40)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        assert app.run_command("battery 6.0")
        await step(pilot, 0.5)
        await pilot.press("f4")
        panel = app.query_one(FaultsPanel)
        assert panel.value("ds254-tcp", "12v") == 1 and panel.highlighted("ds254-tcp", "12v")


async def test_the_fault_injector_pulls_the_robot_cable_and_the_robot_disables():
    """Faults on purpose from the app: a typed spec and the cable buttons go through the same
    `fault` command as stdin; the robot stops hearing its DS and disables; the counters show it."""
    app, engines = make_app(one_team(), "faults")
    async with app.run_test(size=(140, 60)) as pilot:
        engine = engines[0]
        st = engine.field.stations[0]
        await step(pilot, 1.0)
        await pilot.press("e", "e")
        await step(pilot, 0.5)
        assert st.rio.control.enabled
        spec = app.query_one("#fault-spec")
        spec.value = "ds-rio:loss=50%"
        await spec.action_submit()
        await step(pilot, 0.5)
        assert engine.field.faults.links["ds-rio"].loss == 0.5
        app.query_one("#fault-cut-robot").press()
        await pilot.pause()
        await step(pilot, 0.2)
        assert not st.rio.control.enabled  # the robot's watchdog: 100 ms without its DS
        await step(pilot, 1.2)
        assert not st.ds.link.robot_comms and not st.ds.enabled
        assert engine.field.faults.counters["ds-rio"].dropped > 0
        assert "ds-rio" in str(app.query_one("#fault-table").get_row_at(0)[0])
        spec.value = "ds-rio:bogus=1"
        await spec.action_submit()
        await pilot.pause()
        assert "refused" in text_of(app, "#fault-status")
        app.query_one("#fault-uncut-robot").press()
        app.query_one("#fault-clear").press()
        await pilot.pause()
        await step(pilot, 1.0)
        assert st.ds.link.robot_comms and not st.ds.enabled  # back, and it needs a fresh enable


async def test_stale_and_foreign_packets_are_counted_on_their_links():
    """A control packet that arrives twice is stale at the roboRIO (answered, not obeyed); a
    status packet from an address that is not the robot's is foreign at the DS (dropped). Each
    shows on its link's row and in the line under the table, with the roboRIO's evictions."""
    app, _ = make_app(one_team(), "faults")
    async with app.run_test(size=(140, 40)) as pilot:
        engine = app.engine
        st = engine.field.stations[0]
        wire = Wire(engine)
        await step(pilot, 1.0)
        panel = app.query_one(FaultsPanel)
        for row, column in (("rio254-control", "stale"), ("rio254-control", "foreign"),
                            ("ds254-status", "stale"), ("ds254-status", "foreign")):
            assert panel.value(row, column) == 0
        other = text_of(app, "#faults-other")
        assert "status from another address 0" in other
        assert "stale control packets 0" in other and "evicted TCP clients 0" in other

        doubled = []

        def duplicate_once(host, link, dest, data, now):  # the next DS control packet, twice
            if host == "ds 254" and link == "robot" and not doubled:
                doubled.append(bytes(data))
                return [(0.0, data), (0.001, data)]
            return [(0.0, data)]

        engine.net.filters.append(duplicate_once)
        await step(pilot, 0.1)
        assert doubled and sum(1 for p in wire.packets if p[1:4] == ("in", "ds-to-rio", doubled[0])) == 2
        assert st.rio.faults.stale_packets == 1 == st.rio.stats["ds->rio"].stale_packets
        assert panel.value("rio254-control", "stale") == 1 and panel.highlighted("rio254-control", "stale")

        status = next(d for r, direction, kind, d, _ in reversed(wire.packets)
                      if r == "ds 254" and direction == "in" and kind == "rio-to-ds")
        engine.call(lambda: st.ds.datagram("robot", status, ("10.99.99.2", 1150), engine.now()), st.ds_name)
        await step(pilot, 0.1)
        assert st.ds.link.foreign_packets == 1 == st.ds.stats["rio->ds"].foreign_packets
        assert panel.value("ds254-status", "foreign") == 1 and panel.highlighted("ds254-status", "foreign")
        assert not panel.highlighted("ds254-status", "bad")  # well-formed: not a bad packet
        other = text_of(app, "#faults-other")
        assert "status from another address 1" in other and "stale control packets 1" in other
        assert f"evicted TCP clients {st.rio.faults.evicted_clients}" in other


async def test_malformed_tags_are_counted_under_the_table():
    """A control packet with a malformed joystick tag (a size byte past the packet, as LibDS
    writes them) is obeyed for its header; the roboRIO counts the dropped tag."""
    app, _ = make_app(one_team(), "faults")
    async with app.run_test(size=(140, 40)) as pilot:
        engine = app.engine
        st = engine.field.stations[0]
        await step(pilot, 1.0)
        assert "malformed tags dropped (header applied) 0" in text_of(app, "#faults-other")
        changed = []

        def malform_once(host, link, dest, data, now):  # the next DS control packet gets a bad tag
            if host == "ds 254" and link == "robot" and not changed:
                changed.append(bytes(data))
                return [(0.0, bytes(data) + bytes.fromhex("0d 0c 04"))]
            return [(0.0, data)]

        engine.net.filters.append(malform_once)
        await step(pilot, 0.1)
        assert changed and st.rio.faults.malformed_tags == 1
        assert st.rio.stats["ds->rio"].bad_packets == 0
        assert "malformed tags dropped (header applied) 1" in text_of(app, "#faults-other")


async def test_f_on_the_faults_tab_puts_the_typing_in_the_injector_and_the_footer_says_so():
    """The injector was reached only by Tabs nobody knew about, and keys typed before that went
    to the app's shortcuts ("e" arms an enable). f takes you there; Esc back to the table."""
    from textual.widgets import Footer
    app, engines = make_app(one_team(), "faults")
    async with app.run_test(size=(80, 24)) as pilot:
        await step(pilot, 1.0)
        footer = [key.description for key in app.query_one(Footer).query("FooterKey") if key.display]
        assert "Type a fault" in footer
        await pilot.press("f")
        spec = app.query_one("#fault-spec")
        assert app.focused is spec
        await pilot.press(*"ds-rio:delay=30ms")
        assert spec.value == "ds-rio:delay=30ms"
        assert app._enable_armed_at is None  # its e went into the box, not to the enable key
        await pilot.press("escape")
        assert app.focused is app.query_one("#faults-table")
