"""The Faults panel: counters move when faults happen on the wire (SimEngine)."""

from __future__ import annotations

from protocol import rio_to_ds
from roles.engine import SimEngine
from roles.field import FieldConfig

from fieldbox.app import FieldboxApp
from fieldbox.panels.faults import RECENT, FaultsPanel


def make_app(config: FieldConfig, panel: str = "faults"):
    engines: list[SimEngine] = []

    def factory(cfg: FieldConfig) -> SimEngine:
        e = SimEngine(cfg)
        engines.append(e)
        return e

    return FieldboxApp(factory, config, panel=panel, animate=False), engines


class Wire:
    def __init__(self) -> None:
        self.packets: list[tuple[str, str, str, bytes]] = []

    def __call__(self, role, link, direction, kind, data, peer, now) -> None:
        self.packets.append((role, direction, kind, bytes(data)))

    def robot_tcp(self, role: str = "ds 254") -> list:
        return [rio_to_ds.decode_tcp(d) for r, direction, kind, d in self.packets
                if r == role and direction == "in" and kind == "rio-to-ds-tcp"]

    def status(self, role: str = "ds 254") -> list:
        out = []
        for r, direction, kind, d in self.packets:
            if r == role and direction == "in" and kind == "rio-to-ds":
                try:
                    out.append(rio_to_ds.decode_status(d))
                except ValueError:
                    pass
        return out


async def step(app, pilot, engine, seconds: float) -> None:
    engine.advance(seconds)
    app.refresh_views()
    await pilot.pause()


def shown(app, row: str, column: str) -> str:
    return str(app.query_one("#faults-table").get_cell(row, column))


async def test_a_brownout_moves_the_12v_and_brownout_counters():
    app, engines = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    async with app.run_test(size=(140, 40)) as pilot:
        engine = engines[0]
        wire = Wire()
        engine.add_tap(wire)
        await step(app, pilot, engine, 1.0)
        panel = app.query_one(FaultsPanel)
        assert panel.value("ds254-status", "brownouts") == 0
        assert panel.value("ds254-tcp", "12v") == 0
        builds = panel.builds
        rows = app.query_one("#faults-table").row_count

        assert app.run_command("battery 6.0")  # the headless command: the battery sags below 6.8 V
        await step(app, pilot, engine, 0.5)
        # the wire: status packets carry the brownout bit, robot TCP a 0x04 frame with 12 V = 1
        assert any(s.brownout for s in wire.status())
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

        await step(app, pilot, engine, RECENT + 0.5)  # the highlight fades, the count stays
        assert not panel.highlighted("ds254-tcp", "12v")
        assert panel.value("ds254-tcp", "12v") == 1


async def test_garbage_on_a_link_counts_bad_packets_with_the_reason():
    app, engines = make_app(FieldConfig(team=254))
    async with app.run_test(size=(140, 40)) as pilot:
        engine = engines[0]
        await step(app, pilot, engine, 1.0)
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
        await step(app, pilot, engine, 0.6)
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
    app, engines = make_app(FieldConfig(teams=teams))
    async with app.run_test(size=(140, 40)) as pilot:
        await step(app, pilot, engines[0], 0.5)
        table = app.query_one("#faults-table")
        # five DS links and three roboRIO links per team, then the FMS's two and its six stations
        assert table.row_count == 6 * (5 + 3) + 2 + 6
        assert panel_rows_of(app, 1678) == 8
        assert "FMS: refused connections 0" in str(app.query_one("#faults-other").render())


def panel_rows_of(app, team: int) -> int:
    table = app.query_one("#faults-table")
    return sum(1 for key in table.rows if str(key.value).startswith((f"ds{team}-", f"rio{team}-")))


async def test_a_fault_while_the_tab_is_hidden_is_highlighted_when_shown():
    app, engines = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})), panel="ds")
    async with app.run_test(size=(140, 40)) as pilot:
        engine = engines[0]
        await step(app, pilot, engine, 1.0)
        assert app.run_command("battery 6.0")
        await step(app, pilot, engine, 0.5)
        await pilot.press("f4")
        panel = app.query_one(FaultsPanel)
        assert panel.value("ds254-tcp", "12v") == 1 and panel.highlighted("ds254-tcp", "12v")


async def test_the_fault_injector_pulls_the_robot_cable_and_the_robot_disables():
    """Faults on purpose from the app: a typed spec and the cable buttons go through the same
    `fault` command as stdin; the robot stops hearing its DS and disables; the counters show it."""
    app, engines = make_app(FieldConfig(team=254, roles=frozenset({"ds", "rio"})))
    async with app.run_test(size=(140, 60)) as pilot:
        engine = engines[0]
        st = engine.field.stations[0]
        await step(app, pilot, engine, 1.0)
        await pilot.press("e", "e")
        await step(app, pilot, engine, 0.5)
        assert st.rio.enabled
        spec = app.query_one("#fault-spec")
        spec.value = "ds-rio:loss=50%"
        await spec.action_submit()
        await step(app, pilot, engine, 0.5)
        assert engine.field.faults.links["ds-rio"].loss == 0.5
        app.query_one("#fault-cut-robot").press()
        await pilot.pause()
        await step(app, pilot, engine, 0.2)
        assert not st.rio.enabled  # the robot's watchdog: 100 ms without its DS
        await step(app, pilot, engine, 1.2)
        assert not st.ds.robot_comms and not st.ds.enabled
        assert engine.field.faults.counters["ds-rio"].dropped > 0
        assert "ds-rio" in str(app.query_one("#fault-table").get_row_at(0)[0])
        spec.value = "ds-rio:bogus=1"
        await spec.action_submit()
        await pilot.pause()
        assert "refused" in str(app.query_one("#fault-status").render())
        app.query_one("#fault-uncut-robot").press()
        app.query_one("#fault-clear").press()
        await pilot.pause()
        await step(app, pilot, engine, 1.0)
        assert st.ds.robot_comms and not st.ds.enabled  # back, and it needs a fresh enable
