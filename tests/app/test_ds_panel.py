"""The Driver Station panel, driven with keys and clicks through the app on a SimEngine.

Every test checks the DS core's state and what went on the wire: the control packets the
DS sent, decoded from a tap (enabled / e-stop / mode bits, restart and reboot requests,
the countdown tag of a practice run).
"""

from __future__ import annotations

import pytest

from protocol.ds_to_rio import Countdown
from protocol.enums import Mode
from roles.runtime.field import FieldConfig

from fieldbox.app import StatusLine
from fieldbox.panels.ds import DriverStationPanel
from fieldbox.linechart import LineChart, bucket
from fieldbox.widgets import StatusLight

from ..roles.test_ds import connected, refusal
from .helpers import SIZE, Harness, make_app, one_team


pytestmark = pytest.mark.usefixtures("no_real_joysticks")


async def test_e_twice_enables_and_enter_disables():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        ds = h.engine.field.stations[0].ds
        assert ds.link.robot_comms and ds.link.robot_code and not ds.enabled
        assert not h.wire.last_control().enabled

        await pilot.press("e")
        h.run()
        assert not ds.enabled  # one e only arms
        await pilot.press("e")
        h.run()
        assert ds.enabled and h.wire.last_control().enabled
        assert "ENABLED" in str(h.app.query_one("#ds-state").content)

        await pilot.press("enter")
        h.run()
        assert not ds.enabled and not h.wire.last_control().enabled
        assert str(h.app.query_one("#ds-state").content).startswith("DISABLED")


async def test_space_estops_and_restart_code_clears_it():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        ds = h.engine.field.stations[0].ds
        await pilot.press("space")
        h.run()
        assert ds.arbiter.estopped and h.wire.last_control().estop and not h.wire.last_control().enabled
        assert str(h.app.query_one("#ds-state").content) == "E-STOPPED"
        assert "E-stop latched" in str(h.app.query_one("#ds-note").content)

        mark = h.wire.mark()
        await pilot.press("R")  # restart robot code: the only way out of an e-stop
        h.run(0.3)
        sent = h.wire.ds_control(since=mark)
        assert sent[0].restart_code and not sent[0].estop
        assert not ds.arbiter.estopped
        assert ("Restart robot code requested", "information") in h.notes


async def test_mode_keys_and_buttons_set_the_mode_bits():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        ds = h.engine.field.stations[0].ds
        for key, mode in (("a", Mode.AUTONOMOUS), ("s", Mode.TEST), ("t", Mode.TELEOP)):
            await pilot.press(key)
            h.run()
            assert ds.mode is mode and h.wire.last_control().mode is mode
            assert h.app.query_one(f"#ds-mode-{mode.label}").has_class("-current")


async def test_buttons_click_and_a_refused_mode_says_why():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        ds = h.engine.field.stations[0].ds
        await pilot.click("#ds-mode-auto")
        h.run()
        assert ds.mode is Mode.AUTONOMOUS and h.wire.last_control().mode is Mode.AUTONOMOUS
        await pilot.click("#ds-enable-btn")  # a click is deliberate: enables at once
        h.run()
        assert ds.enabled and h.wire.last_control().enabled and h.wire.last_control().mode is Mode.AUTONOMOUS
        # enabled, a mode change is refused with the reason, and nothing changes on the wire
        await pilot.press("t")
        h.run()
        assert ds.mode is Mode.AUTONOMOUS and h.wire.last_control().mode is Mode.AUTONOMOUS
        assert ("disable the robot before changing mode", "warning") in h.notes
        h.app.query_one("#ds-disable-btn").press()  # the app's own disable, as Enter
        await pilot.pause()
        h.run()
        assert not ds.enabled and not h.wire.last_control().enabled
        h.app.query_one("#ds-estop-btn").press()
        await pilot.pause()
        h.run()
        assert ds.arbiter.estopped and h.wire.last_control().estop


async def test_reboot_key_sends_the_reboot_bit():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        mark = h.wire.mark()
        await pilot.press("B")
        h.run(0.1)
        sent = h.wire.ds_control(since=mark)
        assert sent[0].reboot_roborio and not sent[0].restart_code
        assert ("Reboot roboRIO requested", "information") in h.notes


async def test_practice_key_runs_a_practice_match():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        ds = h.engine.field.stations[0].ds
        await pilot.press("p")
        h.run(1.0)
        assert ds.arbiter.practice is not None
        pkt = h.wire.last_control()
        assert not pkt.enabled and pkt.mode is Mode.AUTONOMOUS
        countdown = [t for t in pkt.tags if isinstance(t, Countdown)]
        assert countdown and 1.5 < countdown[0].seconds <= 2.0  # 3 s countdown, 1 s in
        assert str(h.app.query_one("#ds-phase").content) == "Practice: countdown"
        assert h.app.query_one("#ds-countdown").value == "2"
        assert str(h.app.query_one("#ds-practice-btn").label) == "Stop practice p"

        h.run(2.5)  # into autonomous: the run enables the robot itself
        assert ds.enabled and h.wire.last_control().enabled and h.wire.last_control().mode is Mode.AUTONOMOUS
        assert str(h.app.query_one("#ds-phase").content) == "Practice: auto"

        await pilot.press("p")
        h.run()
        assert ds.arbiter.practice is None and not h.wire.last_control().enabled
        assert not [t for t in h.wire.last_control().tags if isinstance(t, Countdown)]
        assert str(h.app.query_one("#ds-phase").content) == "No match running"


async def test_lights_battery_and_link_figures():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(0.0)
        assert h.app.query_one("#ds-light-comms", StatusLight).state == "off"
        assert h.app.query_one("#ds-battery").value == "--.--"
        h.run(2.0)
        assert h.app.query_one("#ds-light-comms", StatusLight).state == "on"
        assert h.app.query_one("#ds-light-code", StatusLight).state == "on"
        joysticks = h.app.query_one("#ds-light-joysticks", StatusLight)
        assert joysticks.state == "on" and joysticks.label == "Joysticks: 1"  # the keyboard joystick
        assert h.app.query_one("#ds-light-fms", StatusLight).state == "idle"
        assert abs(float(h.app.query_one("#ds-battery").value) - 12.6) < 0.1
        assert "Robot program: disabled" in str(h.app.query_one("#ds-program").content)
        link = str(h.app.query_one("#ds-link").content)
        assert "Trip time" in link and "Lost packets  0" in link

        h.app.run_command("battery 10.2")  # the fake roboRIO's battery runs low
        h.run(0.5)
        battery = h.app.query_one("#ds-battery")
        assert battery.value == "10.20" and battery.has_class("-low")
        chart = h.app.query_one("#ds-chart", LineChart)
        filled = [v for v in chart.buckets if v is not None]
        assert filled and min(filled) == pytest.approx(10.2, abs=0.01) and max(filled) == pytest.approx(12.6, abs=0.1)


async def test_a_field_switches_teams_with_the_bracket_keys():
    h = Harness(FieldConfig(teams=[254, 1114, None, 118, None, None], roles=frozenset({"ds", "rio"})))
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        panel = h.app.query_one(DriverStationPanel)
        assert panel.station().team == 254 and h.app.selected_team is None
        await pilot.press("right_square_bracket")
        h.run()
        assert h.app.selected_team == 1114
        assert str(h.app.query_one("#ds-team").content).startswith("Team 1114")
        assert "team 1114" in str(h.app.query_one(StatusLine).content)
        await pilot.press("e", "e")  # the app's keys act on the selected team
        h.run()
        stations = {st.team: st.ds for st in h.engine.field.stations}
        assert stations[1114].enabled and not stations[254].enabled
        assert h.wire.last_control("ds 1114").enabled and not h.wire.last_control("ds 254").enabled
        await pilot.press("space")
        h.run()
        assert stations[1114].arbiter.estopped and not stations[254].arbiter.estopped
        assert h.wire.last_control("ds 1114").estop and not h.wire.last_control("ds 254").estop
        buttons = list(h.app.query("#ds-teams Button"))
        assert [str(b.label) for b in buttons] == ["R1 254", "R2 1114", "B1 118"]
        assert [b.has_class("-selected") for b in buttons] == [False, True, False]
        await pilot.press("left_square_bracket", "left_square_bracket")  # back round the field
        assert h.app.selected_team == 118
        buttons[0].press()  # as a click on "R1 254" does
        await pilot.pause()
        assert h.app.selected_team == 254
        assert h.app.run_command("mode auto")
        h.run()
        assert h.wire.last_control("ds 254").mode is Mode.AUTONOMOUS
        assert h.wire.last_control("ds 118").mode is Mode.TELEOP


async def test_without_a_driver_station_the_panel_says_so():
    h = Harness(FieldConfig(team=254, roles=frozenset({"rio"})))
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(0.5)
        text = str(h.app.query_one("#ds-none").content)
        assert "No Driver Station runs here" in text and "F8" in text
        assert h.app.query_one("#ds-none").display and not h.app.query_one("#ds-columns").display
        await pilot.press("t")  # a refusal, not a crash
        h.run()
        assert any("no Driver Station" in n for n, _ in h.notes)


async def test_under_an_fms_the_panel_shows_the_field_in_charge():
    h = Harness(FieldConfig(team=254))  # DS, fake roboRIO and FMS
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(2.0)
        ds = h.engine.field.stations[0].ds
        fms = h.app.query_one("#ds-light-fms", StatusLight)
        assert ds.fms.attached and (fms.state, fms.label) == ("on", "FMS: good")
        assert str(h.app.query_one("#ds-team").content).endswith("(FMS)")
        assert h.wire.last_control().fms_attached
        await pilot.press("t")
        h.run()
        assert ("an FMS is attached: it decides the mode", "warning") in h.notes
        assert h.app.run_command("match start")
        h.run(1.0)
        assert ds.enabled and h.wire.last_control().enabled and h.wire.last_control().mode is Mode.AUTONOMOUS
        assert str(h.app.query_one("#ds-phase").content) == "Match: auto, enabled"
        assert h.app.query_one("#ds-countdown").value.isdigit()
        await pilot.press("enter")  # the operator's disable holds under an FMS too
        h.run()
        assert not ds.enabled and not h.wire.last_control().enabled


def test_the_chart_keeps_each_columns_lowest_value_and_leaves_gaps():
    points = [(0.0, 12.0), (0.5, 11.0), (1.2, 12.5), (3.5, 7.0), (3.9, 9.0), (4.5, float("nan"))]
    assert bucket(points, 0.0, 4.0, 4, lowest=True) == ([11.0, 12.5, None, 7.0], 7.0, 12.5)
    assert bucket(points, 1.0, 4.0, 3, lowest=True) == ([12.5, None, 7.0], 7.0, 12.5)  # earlier points left out
    # the window's highest sample (12.5) is no column's lowest: a title's "high" says 12.5
    assert bucket(iter(points), 0.0, 4.0, 2, lowest=True) == ([11.0, 7.0], 7.0, 12.5)
    assert bucket(points, 0.0, 4.0, 2, lowest=False) == ([12.5, 9.0], 7.0, 12.5)  # a trip time keeps its worst
    assert bucket(points, 0.0, 0.0, 4, lowest=True) == ([None] * 4, None, None)
    assert bucket(points, 0.0, 4.0, 0, lowest=True) == ([], None, None)


def _sent(app) -> int:
    text = str(app.query_one("#ds-link").content)
    return int(text.split(" of ")[1].split()[0])


async def test_the_link_block_shows_a_loss_at_once_and_the_packets_sent_twice_a_second():
    # The packets sent and the trip time move with every packet: drawn ten times a second
    # they cost the app a repaint each tick and no one reads them; a loss shows at once.
    h = Harness(one_team(fault_seed=3))
    async with h.app.run_test(size=SIZE):
        h.run(2.0)
        seen = []
        for _ in range(10):  # one second, refreshed every 100 ms
            h.run(0.1)
            seen.append(_sent(h.app))
        assert 2 <= len(set(seen)) <= 3  # twice a second, not ten times
        assert seen[-1] >= 50 * 2.5  # and current: about 50 a second
        ds = h.engine.field.stations[0].ds
        lost = ds.link.echoes.lost_packets
        h.app.run_command("fault ds-rio:loss=30%")
        for _ in range(10):
            h.run(0.1)
            if ds.link.echoes.lost_packets > lost:
                break
        assert ds.link.echoes.lost_packets > lost  # the refresh that first saw a loss shows it
        assert f"Lost packets  {ds.link.echoes.lost_packets} " in str(h.app.query_one("#ds-link").content)


async def test_fms_control_from_an_address_it_refuses_is_shown_on_the_ds_and_faults_tabs():
    # Issue 29: a DS logged in to its FMS ("good") whose control comes from another address
    # (Cheesy Arena on one machine: 127.0.0.1 while the DS dialled 127.0.100.5) refuses it: its
    # screens said "FMS good" while the robot was never enabled. Here the field's own control
    # is cut, and control comes from 127.9.9.9 (this field's FMS is at 127.0.0.1).
    from protocol.fms_to_ds import FmsControlPacket

    from fieldbox.panels.faults import FaultsPanel

    h = Harness(FieldConfig(team=254))  # DS, fake roboRIO and FMS
    async with h.app.run_test(size=SIZE) as pilot:
        assert h.app.run_command("fault ds-fms:cut")
        h.run(2.0)
        st = h.engine.field.stations[0]
        ds = st.ds

        def foreign() -> None:
            pkt = FmsControlPacket(enabled=True, mode=Mode.TELEOP).encode()
            ds.datagram("fms", pkt, ("127.9.9.9", 50123), h.engine.now())

        for _ in range(4):
            h.engine.call(foreign, st.ds_name)
            h.run(0.5)
        shown = h.app.query_one("#ds-light-fms", StatusLight)
        assert ds.fms.status == "good" and not ds.fms.attached and not h.wire.last_control().enabled
        assert (shown.state, shown.label) == ("off", "FMS: CONTROL REFUSED")
        note = str(h.app.query_one("#ds-match-note").content)
        assert note.startswith("FMS control from 127.9.9.9 refused: this DS obeys only the FMS it logged in to")
        await pilot.press("f4")
        h.run(0.2)
        h.app.query_one(FaultsPanel)
        other = str(h.app.query_one("#faults-other").content)
        assert other.splitlines()[0].startswith("DS 254: FMS control from 127.9.9.9 refused: this DS obeys only")
        h.run(3.0)  # it stopped: the tabs stop saying so
        assert "refused" not in str(h.app.query_one("#faults-other").content).splitlines()[0]
        await pilot.press("f1")
        h.run(0.2)
        assert (shown.state, shown.label) == ("on", "FMS: good")


def test_the_chart_title_drops_whole_parts_and_never_leaves_a_low_without_its_high():
    """At 80 columns the battery chart's title was cut to "Battery 12.56 V low 12.56 V · hi…",
    which reads as a low-battery alarm: parts now go whole, the window first, then the span."""
    from rich.style import Style
    chart = LineChart("Battery", "V", 0.0, 14.0, aggregate="min", digits=2, window_text="10 s")
    chart.buckets, chart.latest, chart.range = [12.56, None, 10.2, 12.61], 12.56, (10.2, 12.61)
    styles = {name: Style() for name in ("line", "warn", "bad", "axis", "title")}
    whole = "Battery  12.56 V   low 10.20 V · high 12.61 V"
    for width in range(10, 81):
        line = chart._title_line(width, styles).plain
        assert len(line) <= width, (width, line)
        assert line.startswith("Bat"), (width, line)
        assert ("low" in line) == ("low 10.20 V · high 12.61 V" in line), (width, line)  # whole or not at all
        assert line.endswith(("Battery", "12.56 V", "12.61 V", "last 10 s")), (width, line)  # nothing cut
        if width >= 16:
            assert "12.56 V" in line, (width, line)  # the value before the rest of the title
    assert chart._title_line(80, styles).plain == whole.ljust(80 - len("last 10 s")) + "last 10 s"
    assert chart._title_line(30, styles).plain == "Battery  12.56 V     last 10 s"
    assert chart._title_line(14, styles).plain == "Batt…  12.56 V"


@pytest.mark.parametrize("teams", [[254], [254, 1114, None, 118, None, None]])
async def test_at_80_columns_the_keys_line_never_parts_a_key_from_what_it_does(teams):
    """At 80x24 the tab's key help was 80 cells in 78: "F1" ended one line and "more" began
    the next. One team: one line. A field's teams add "[ ] team": two lines, broken between keys."""
    h = Harness(FieldConfig(teams=teams, roles=frozenset({"ds", "rio"})))
    async with h.app.run_test(size=(80, 24)) as pilot:
        h.run(1.0)
        await pilot.pause()
        keys = h.app.query_one("#ds-keys")
        lines = keys.render().plain.split("\n")
        assert keys.region.height == len(lines) == (1 if len(teams) == 1 else 2)
        assert all(len(line) <= keys.region.width for line in lines), lines
        assert lines[-1].endswith(" F1  more" if len(teams) == 1 else " [ ]  team")
        assert "F1  more" in "\n".join(lines)


def test_the_ds_tab_note_shows_the_cores_blocker():
    """While a restart request goes out to a robot that still reports an e-stop, enable() is
    refused: the DS tab said "Ready: press e twice to enable" (its own copy of the rules)."""
    h = connected()
    h.robot.estop_latched = True
    h.run(0.1)
    h.ds.restart_code(h.t)
    h.run(0.021)
    assert refusal(h) == "the robot still reports an e-stop: restart its code"
    assert DriverStationPanel._note(h.ds.view(h.t)) == "The robot still reports an e-stop: restart its code (R)."
    h.robot.estop_latched = False
    h.run(0.5)
    assert DriverStationPanel._note(h.ds.view(h.t)) == "Ready: press e twice to enable."
