"""The FMS panel, driven by its keys, with the effect checked on the wire (SimEngine)."""

from __future__ import annotations

from protocol.enums import AllianceStation, Mode
from roles.cores.match import Phase
from roles.runtime.field import FieldConfig

from fieldbox.panels.fms import FmsPanel

from .helpers import Wire, make_app, one_team, step, text_of, until


def cell(app, station: str, column: str) -> str:
    table = app.query_one("#fms-stations")
    return str(table.get_cell(station, column))


async def test_start_enables_in_auto_and_x_estops_the_station():
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 2.0)
        fms = engine.field.fms
        ds = engine.field.stations[0].ds
        assert "Ready: s starts the match" in text_of(app, "#fms-start")
        assert cell(app, "R1", "team") == "254" and cell(app, "R1", "ds") == "●"
        assert app.query_one("#fms-stations").has_focus  # keys work on this tab at once

        t0 = wire.mark()
        await pilot.press("s")
        await step(pilot, 1.0)
        assert fms.phase is Phase.AUTO
        assert text_of(app, "#fms-phase") == "AUTO"
        assert app.query_one("#fms-clock").value == "0:19"
        # the wire: the FMS enables R1 in auto, and the DS passes it on to the robot
        control = wire.fms_control(since=t0)
        assert control and all(p.enabled and p.mode is Mode.AUTONOMOUS and not p.estop for p in control)
        assert control[-1].station is AllianceStation.RED1 and control[-1].remaining_seconds == 19
        assert ds.enabled and wire.ds_control(since=t0)[-1].enabled
        assert cell(app, "R1", "field") == "ENABLED"

        t1 = wire.mark()
        await pilot.press("1", "x")  # R1, e-stop (space would be the DS's own e-stop)
        await step(pilot, 0.1)
        assert fms.station("R1").commands.estop
        after = wire.fms_control(since=t1)
        assert after and after[0].estop and not after[0].enabled  # the very next packet
        assert ds.arbiter.estopped and not ds.enabled
        assert wire.ds_control(since=t1)[-1].estop  # and the robot hears it
        assert cell(app, "R1", "estop") == "E-STOP"
        assert cell(app, "R1", "field") == "disabled"

        await pilot.press("x")  # clearing an e-stop during the match is refused, and said why
        assert fms.station("R1").commands.estop
        assert any("latches until the match is over" in str(n.message) for n in app._notifications)

        t2 = wire.mark()
        await pilot.press("ctrl+a")  # abort
        await step(pilot, 0.1)
        assert fms.phase is Phase.POST_MATCH
        assert all(not p.enabled for p in wire.fms_control(since=t2))
        assert "aborted" in text_of(app, "#fms-start")


async def test_refused_start_lists_every_reason_and_bypass_clears_them():
    # R2 and B1 have teams whose DS never comes: the start is refused for each of them
    config = FieldConfig(team=254, fms_teams=[254, 1114, None, 118, None, None])
    app, engines = make_app(config, "fms")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 2.0)
        fms = engine.field.fms
        live = text_of(app, "#fms-start")
        assert "Cannot start yet" in live and "R2 (1114): not connected and not bypassed" in live

        await pilot.press("s")
        await step(pilot, 0.1)
        assert fms.phase is Phase.PRE_MATCH
        banner = text_of(app, "#fms-start")
        assert banner.startswith("START REFUSED")
        for reason in ("R2 (1114): not connected and not bypassed", "B1 (118): not connected and not bypassed"):
            assert reason in banner
        assert app.query_one("#fms-start").has_class("-refused")
        assert not any(p.enabled for p in wire.fms_control())

        await pilot.press("2", "b", "4", "b")  # bypass R2 and B1
        assert fms.station("R2").commands.bypass and fms.station("B1").commands.bypass
        assert cell(app, "R2", "bypass") == "BYPASS" and cell(app, "B1", "bypass") == "BYPASS"
        t0 = wire.mark()
        await pilot.press("s")
        await step(pilot, 0.6)
        assert fms.phase is Phase.AUTO
        assert wire.fms_control(since=t0)[-1].enabled
        assert cell(app, "R2", "field") == "disabled" and cell(app, "R1", "field") == "ENABLED"


async def test_astop_disables_for_the_rest_of_auto_only():
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 2.0)
        fms, ds = engine.field.fms, engine.field.stations[0].ds
        engine.call(lambda: fms.set_timing(engine.now(), auto=3, pause=1), engine.field.fms_name)  # a short match
        await pilot.press("a")  # not in auto yet: refused, with the reason
        assert not fms.station("R1").commands.astop
        assert any("only during auto" in str(n.message) for n in app._notifications)
        await pilot.press("s")
        await step(pilot, 1.0)
        t0 = wire.mark()
        await pilot.press("a")
        await step(pilot, 0.1)
        packets = wire.fms_control(since=t0)
        assert packets[0].astop and not packets[0].enabled
        assert not ds.enabled and not ds.arbiter.estopped
        assert cell(app, "R1", "astop") == "A-STOP"
        await step(pilot, 3.5)  # auto and the pause are over: teleop enables again
        assert fms.phase is Phase.TELEOP
        last = wire.fms_control()[-1]
        assert last.enabled and not last.astop and last.mode is Mode.TELEOP
        assert cell(app, "R1", "astop") == "·"


async def test_period_lengths_apply_and_a_refusal_is_shown():
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 2.0)
        fms = engine.field.fms
        await pilot.press("d")  # to the period lengths (the auto box, its text selected)
        assert app.focused.id == "fms-auto"
        await pilot.press("1", "5", "escape")  # Esc (or Tab) applies
        assert fms.match.timing.auto == 15
        assert app.query_one("#fms-stations").has_focus
        assert "auto period is now 15 s" in text_of(app, "#fms-timing-note")
        assert app.query_one("#fms-clock").value == "0:15"
        t0 = wire.mark()
        await pilot.press("s")
        await step(pilot, 0.1)
        assert wire.fms_control(since=t0)[0].remaining_seconds == 15

        await pilot.press("d", "tab", "tab")
        assert app.focused.id == "fms-teleop"
        await pilot.press("9", "tab")  # refused while the match runs
        assert fms.match.timing.teleop == 140
        note = app.query_one("#fms-timing-note")
        assert "cannot change period lengths while a match runs" in text_of(app, "#fms-timing-note")
        assert note.has_class("-error")
        assert app.query_one("#fms-teleop").value == "140"


async def test_next_match_and_match_type():
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 2.0)
        await pilot.press("t")  # practice -> qualification, same number
        await step(pilot, 0.1)
        assert text_of(app, "#fms-match").startswith("Qualification match 1")
        t0 = wire.mark()
        await pilot.press("n")
        await step(pilot, 0.6)
        assert text_of(app, "#fms-match").startswith("Qualification match 2")
        last = wire.fms_control(since=t0)[-1]
        assert int(last.tournament_level) == 2 and last.match_number == 2


async def test_without_an_fms_the_panel_says_how_to_add_it():
    app, _ = make_app(one_team(), "fms")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        panel = app.query_one(FmsPanel)
        assert panel.query_one("#fms-none").display and not panel.query_one("#fms-main").display
        text = text_of(app, "#fms-none")
        assert "No FMS runs here" in text and "--roles ds,rio,fms" in text and "F8" in text
        await pilot.press("s")
        assert any("no FMS runs here" in str(n.message) for n in app._notifications)


async def test_refusals_show_on_the_fms_panel_and_the_faults_panel():
    """Issue 17: a login while the station's DS is live and status from another address are
    refused; the FMS panel says so under the stations, the Faults panel counts them."""
    from protocol.ds_to_fms import DsStatusPacket, TeamNumber

    from fieldbox.panels.faults import FaultsPanel

    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(140, 44)) as pilot:
        engine = engines[0]
        await step(pilot, 2.0)
        fms = engine.field.fms
        assert not app.query_one("#fms-refused").display  # nothing refused: nothing shown

        def attack():
            now = engine.now()
            for i in range(3):
                fms.datagram("udp", DsStatusPacket(team=254, estop=True).encode(), ("127.9.9.9", 1145), now)
            fms.stream_opened("stranger", ("127.9.9.9", 40000), now)
            return fms.stream_data("stranger", TeamNumber(254).encode(), now)

        engine.call(attack, engine.field.fms_name)
        await step(pilot, 0.2)
        # (the app's fake clock runs the ephemeral plan: an address is named with its port)
        assert text_of(app, "#fms-refused") == ("R1 (254) refused 1 login while its DS was live and 3 status "
                                                "packets from another address, last from 127.9.9.9:40000")
        assert app.query_one("#fms-refused").display
        assert not fms.station("R1").commands.estop and fms.station("R1").login.peer[0] == "127.0.0.1"

        await pilot.press("f4")
        await step(pilot, 0.2)
        panel = app.query_one(FaultsPanel)
        assert panel.value("fms-R1", "foreign") == 3 and panel.value("fms-tcp", "foreign") == 1
        other = text_of(app, "#faults-other")
        assert "status from another address 3" in other and "logins refused 1" in other


async def test_a_rows_status_its_field_column_and_the_ready_line_agree():
    # issue 20: "Ready: s starts the match" beside "DS e-stopped", and ENABLED in the Field
    # column for a station its DS held
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(160, 50)) as pilot:
        await step(pilot, 2.0)
        assert "Ready: s starts the match" in text_of(app, "#fms-start")
        app.run_command("estop")  # the DS's own e-stop, before the match
        await step(pilot, 0.5)
        assert cell(app, "R1", "status") == "robot still e-stopped"
        start = text_of(app, "#fms-start")
        assert "Ready" not in start and "R1 (254): robot still e-stopped: restart its code" in start
        app.run_command("restart")  # the robot's code restarts: the DS's e-stop clears
        await step(pilot, 2.5)
        assert cell(app, "R1", "status") == "ready" and "Ready: s starts the match" in text_of(app, "#fms-start")
        await pilot.press("s")
        await step(pilot, 0.05)  # the DS has the FMS's enable, the FMS not yet its DS's report
        assert cell(app, "R1", "status") == "enabling" and cell(app, "R1", "field") == "enabling…"
        await step(pilot, 0.6)  # its DS's next status (every 500 ms)
        assert cell(app, "R1", "status") == "running" and cell(app, "R1", "field") == "ENABLED"
        app.run_command("disable")  # Enter on the DS: the operator holds the robot for the period
        await step(pilot, 0.6)
        fms = engines[0].field.fms
        assert fms.station("R1").commands.enabled  # the field still enables the station ...
        assert cell(app, "R1", "status") == "held by its DS"  # ... and the row says what the robot is
        assert cell(app, "R1", "field") == "HELD"


def log_tail(app, rows: int | None = None) -> list[str]:
    """The match log's lines a person sees now (those scrolled into its window)."""
    log = app.query_one("#fms-log")
    top = round(log.scroll_y)
    return [str(line) for line in log.lines[top:top + (rows or log.scrollable_content_region.height)]]


async def test_the_match_log_shows_its_newest_line_and_scrolls_from_the_keyboard():
    """Issue 31: on a six-team field the log stayed on its start-up lines ("Match 1 auto
    started" never appeared below 200x60), and it could not take the focus."""
    for size in ((80, 24), (160, 50), (200, 60)):
        app, _ = make_app(FieldConfig(teams=[254, 1114, 2056, 118, 148, 1678]), "fms")
        async with app.run_test(size=size) as pilot:
            await step(pilot, 2.0)  # some twenty lines of links coming up
            await pilot.press("s")
            await step(pilot, 1.0)
            assert any("Match 1 auto started" in line for line in log_tail(app)), size
            assert app.query_one("#fms-log").line_count > 20

            await pilot.press("l")  # the log takes the keys: up scrolls back
            log = app.query_one("#fms-log")
            assert log.has_focus
            await pilot.press("home")
            assert await until(pilot, lambda: log.scroll_y == 0), size  # (an animated scroll)
            overflows = size != (200, 60)  # at 200x60 every line fits
            assert overflows == ("Match 1 auto started" not in " ".join(log_tail(app))), size
            await pilot.press("b")  # R1 bypassed while a person reads: it does not yank the log
            await step(pilot, 0.5)
            assert log.scroll_y == 0 and any("R1" in line and "bypass" in line for line in log.lines[-3:])

            await pilot.press("escape")  # back to the stations: the newest line again
            await step(pilot, 0.3)
            assert app.query_one("#fms-stations").has_focus
            await pilot.press("2", "x")  # an e-stop: seen in the log at once
            await step(pilot, 0.3)
            tail = " ".join(log_tail(app))
            assert "R2" in tail and "e-stop" in tail.lower(), (size, tail)


async def test_space_under_an_fms_reads_e_stopped_not_fms_e_stop():
    # Space e-stops the DS; our FMS then e-stops the station too (it holds it for the match).
    # The DS tab and the status line say E-STOPPED, as the operator did it, not "FMS E-STOP".
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(160, 50)) as pilot:
        await step(pilot, 2.0)
        await pilot.press("s")
        await step(pilot, 1.0)
        await pilot.press("space")
        await step(pilot, 1.0)
        assert cell(app, "R1", "estop") == "E-STOP" and cell(app, "R1", "status") == "DS e-stop"
        await pilot.press("f1")
        await step(pilot, 0.3)
        assert text_of(app, "#ds-state") == "E-STOPPED"
        assert "E-STOPPED" in text_of(app, "#status-line") and "FMS E-STOP" not in text_of(app, "#status-line")
        assert text_of(app, "#ds-note").startswith("E-stop (operator): the FMS holds this station e-stopped")


async def test_an_fms_estop_reads_fms_estop_and_the_next_match_says_the_robot_is_still_estopped():
    # Issue 29: the field's e-stop (x) read "DS e-stopped"; and a robot e-stopped in one match
    # stays e-stopped into the next until its code restarts, which Cheesy Arena shows all green:
    # both tabs say so before the next match starts.
    app, engines = make_app(FieldConfig(team=254), "fms")
    async with app.run_test(size=(160, 50)) as pilot:
        await step(pilot, 2.0)
        await pilot.press("s")
        await step(pilot, 1.0)
        await pilot.press("1", "x")
        await step(pilot, 1.0)
        assert cell(app, "R1", "status") == "FMS e-stop" and cell(app, "R1", "estop") == "E-STOP"
        await pilot.press("f1")
        await step(pilot, 0.2)
        assert text_of(app, "#ds-state") == "FMS E-STOP"
        assert "FMS E-STOP" in text_of(app, "#status-line")
        assert text_of(app, "#ds-note").startswith("FMS e-stop: the FMS holds this station e-stopped for the "
                                                   "rest of the match.")
        await pilot.press("f5")
        await pilot.press("ctrl+a", "n")  # abort, and the next match: the field's e-stop is cleared
        await step(pilot, 1.0)
        fms, ds = engines[0].field.fms, engines[0].field.stations[0].ds
        assert not fms.station("R1").commands.estop and ds.arbiter.estopped  # the robot's latch is not the field's
        assert cell(app, "R1", "status") == "robot still e-stopped" and cell(app, "R1", "estop") == "·"
        start = text_of(app, "#fms-start")
        assert "Ready" not in start and "R1 (254): robot still e-stopped: restart its code" in start
        await pilot.press("f1")
        await step(pilot, 0.2)
        assert text_of(app, "#ds-state") == "E-STOPPED"
        assert text_of(app, "#ds-note").startswith("Robot still e-stopped: restart its code (R).")
        await pilot.press("R")  # its code restarts: the next match can enable it
        await step(pilot, 2.5)
        await pilot.press("f5")
        await step(pilot, 0.2)
        assert cell(app, "R1", "status") == "ready" and "Ready: s starts the match" in text_of(app, "#fms-start")
