"""The NI Driver Station's places in fieldbox (issue 20, item 5): Setup, Diagnostics, Charts,
and the elapsed time and the PC's figures in the status line. On SimEngines (a fake clock),
with a :class:`~tests.app.helpers.Wire` to see what crosses it."""

from __future__ import annotations

import pytest

from protocol.ds_to_rio import GameData, decode_tcp
from roles.runtime.field import FieldConfig

from fieldbox.history import DsHistory, cpu_percent
from fieldbox.linechart import LineChart, nice_ceiling
from fieldbox.pcstatus import PcStatus

from .helpers import Harness, layouts_asked, one_team, text_of

pytestmark = pytest.mark.usefixtures("no_real_joysticks")

SIZE = (120, 40)


# -- Setup ----------------------------------------------------------------------------------------
async def test_game_data_typed_on_setup_reaches_the_robot():
    h = Harness(one_team(), "setup")
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        await pilot.press("g")  # into the game data box
        assert h.app.focused.id == "setup-game-data"
        await pilot.press("L", "R", "L", "enter")  # Enter applies it (and disables, as everywhere)
        h.run(0.5)
        sent = [decode_tcp(d) for r, direction, kind, d, _ in h.wire.packets
                if r == "ds 254" and direction == "out" and kind == "ds-to-rio-tcp"]
        assert any(isinstance(m, GameData) and m.text == "LRL" for m in sent)
        assert h.engine.field.stations[0].rio.inputs.game_data == "LRL"  # the robot program sees it
        assert "'LRL'" in text_of(h.app, "#setup-game-note")


async def test_practice_timing_edited_on_setup_times_the_next_practice_run():
    h = Harness(one_team(), "setup")
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        await pilot.press("p")  # the countdown box
        await pilot.press("tab", "5", "tab")  # auto (what a box holds is selected as it is entered): 5 s
        h.run(0.1)
        ds = h.engine.field.stations[0].ds
        assert ds.arbiter.practice_timing.auto == 5.0 and ds.arbiter.practice_timing.teleop == 135.0
        assert "auto is now 5 s" in text_of(h.app, "#setup-practice-note")
        await pilot.press("escape", "f3", "f1")  # the Driver Station tab (F1 from Setup would go on to Charts)
        await pilot.press("p")
        h.run(3.0 + 5.0 + 0.1)  # countdown, then the 5 s of auto are over
        assert ds.arbiter.practice_phase.value == "pause"
        await pilot.press("f1", "f1")  # Diagnostics, Setup
        await pilot.press("p", "tab", *"9999", "tab")  # refused: over an hour
        h.run(0.1)
        assert ds.arbiter.practice_timing.auto == 5.0
        assert "0..3600" in text_of(h.app, "#setup-practice-note")


async def test_a_new_team_on_setup_restarts_the_field_with_it_and_a_bad_station_is_refused():
    h = Harness(one_team(), "setup")
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        await pilot.press("t")
        await pilot.press(*"1114", "tab", "b", "2", "enter")
        h.run(1.0)
        assert len(h.engines) == 2
        st = h.engine.field.stations[0]
        assert (st.team, st.station.label) == (1114, "B2") and st.ds.link.robot_comms
        assert "team 1114 B2" in text_of(h.app, "#status-line")
        await pilot.press("t", "tab", "r", "enter")  # "R": no position
        assert len(h.engines) == 2 and "not applied" in text_of(h.app, "#setup-team-note")


async def test_on_a_field_of_six_setup_shows_the_teams_and_does_not_change_them():
    h = Harness(FieldConfig(teams=[254, 1114, None, None, None, None], roles=frozenset({"ds", "rio"})), "setup")
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        assert h.app.query_one("#setup-team").disabled
        assert "--teams" in text_of(h.app, "#setup-team-note")
        await pilot.press("t")
        assert h.app.focused is h.app.query_one("#panel-setup")


# -- Diagnostics ----------------------------------------------------------------------------------
async def test_diagnostics_shows_the_robots_versions_round_trips_and_its_keys_restart_the_code():
    h = Harness(FieldConfig(team=254), "diagnostics")  # with the FMS
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(2.0)
        versions = text_of(h.app, "#diag-versions")
        assert "roboRIO Image" in versions and "FRC_roboRIO" in versions  # from its TCP frames
        links = text_of(h.app, "#diag-links")
        ds = h.engine.field.stations[0].ds
        assert f"round trip {ds.trip_ms:.2f} ms" in links
        assert links.count("round trip") == 2  # the robot's, and the FMS's (both ends here)
        rio = text_of(h.app, "#diag-rio")
        assert "CPU" in rio and "%" in rio and "RAM free" in rio
        assert "CPU         12 %" in text_of(h.app, "#diag-pc")  # the tests' PC reading
        await pilot.press("R")
        h.run(0.5)
        assert any("restart robot code requested" in text for _, text in ds.events.items)
        assert "restart robot code requested" in "\n".join(h.app.query_one("#diag-events").lines)


async def test_diagnostics_says_the_fms_round_trip_cannot_be_timed_without_the_fms_here():
    h = Harness(one_team(), "diagnostics")  # no FMS: local control
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        links = text_of(h.app, "#diag-links")
        assert "none (local control)" in links and links.count("round trip") == 1


# -- Charts ------------------------------------------------------------------------------------------
def flat_points(volts: float, seconds: float) -> list[tuple[float, float]]:
    return [(t * 0.5, volts) for t in range(int(seconds * 2))]


async def test_a_flat_battery_is_a_line_not_a_block():
    # issue 20: at a steady 12.4 V the old chart filled every column to four fifths: a block
    from textual.app import App

    class OneChart(App):
        def compose(self):
            yield LineChart("Battery", "V", 6.0, 14.0, aggregate="min", below=True, digits=2, id="chart")

    app = OneChart()
    async with app.run_test(size=(60, 12)) as pilot:
        chart = app.query_one(LineChart)
        chart.plot(flat_points(12.4, 60.0), 0.0, 60.0)
        await pilot.pause()
        rows = str(chart.render()).splitlines()[1:-1]  # the plot, without title and time axis
        drawn = [r for r in rows if any("\u2801" <= c <= "\u28ff" for c in r)]
        assert len(drawn) == 1  # one row holds the line...
        assert sum(1 for c in drawn[0] if "\u2801" <= c <= "\u28ff") >= 50  # ...all the way along
        assert "12.40 V" in str(chart.render()).splitlines()[0]


async def test_charts_draw_the_last_minutes_with_the_dip_and_the_lost_packets():
    h = Harness(FieldConfig(team=254, fault_seed=3), "charts")
    async with h.app.run_test(size=SIZE) as pilot:
        for volts, seconds in (("12.5", 5.0), ("10.2", 3.0), ("12.4", 3.0)):
            h.app.run_command(f"battery {volts}")
            for _ in range(int(seconds * 10)):  # the app's 10 Hz refresh samples the field
                h.run(0.1)
        h.app.run_command("fault ds-rio:loss=50%")
        for _ in range(20):
            h.run(0.1)
        battery = h.app.query_one("#chart-battery", LineChart)
        assert min(v for v in battery.buckets if v is not None) == pytest.approx(10.2, abs=0.01)
        lost = h.app.query_one("#chart-lost", LineChart)
        assert max(v for v in lost.buckets if v is not None) > 5  # packets a second
        assert "last 1 min" in str(battery.render()).splitlines()[0]
        await pilot.press("w")
        assert "last 5 min" in str(battery.render()).splitlines()[0]


def test_the_history_samples_twice_a_second_and_the_cpu_tag_is_one_figure():
    from roles.runtime.engine import SimEngine

    engine = SimEngine(one_team())
    history = DsHistory()
    for _ in range(30):
        engine.advance(0.1)
        history.sample(engine, engine.now())
    h = history.get(254)
    assert len(h.battery) == 7  # the first at once, then one every 0.5 s of the 3 s
    assert [round(t - 1000.0, 3) for t, _ in h.battery][1:] == [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]  # on a grid
    assert all(v == pytest.approx(12.6, abs=0.1) for _, v in h.battery)
    ds = engine.field.stations[0].ds
    assert cpu_percent(ds.telemetry.cpu) == pytest.approx(sum(sum((c.time_critical, c.above_normal, c.normal, c.low))
                                                    for c in ds.telemetry.cpu.cpus) / len(ds.telemetry.cpu.cpus))
    assert list(h.mode)[-1][1] == "disabled"
    assert nice_ceiling(24.4) == 50 and nice_ceiling(3) == 5 and nice_ceiling(0.3) == pytest.approx(0.5)


# -- the status line -----------------------------------------------------------------------------------
async def test_elapsed_time_counts_while_enabled_and_holds_while_disabled():
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        assert "elapsed 0:00" in text_of(h.app, "#status-line")
        await pilot.press("e", "e")
        for _ in range(65):
            h.run(1.0)
        assert "elapsed 1:05" in text_of(h.app, "#status-line")
        await pilot.press("enter")
        h.run(10.0)
        assert "elapsed 1:05" in text_of(h.app, "#status-line")  # held
        await pilot.press("e", "e")
        h.run(3.0)
        assert "elapsed 0:03" in text_of(h.app, "#status-line")  # from zero at the next enable
        assert "PC cpu 12% battery 80%" in text_of(h.app, "#status-line")


async def test_the_status_line_changes_without_laying_the_screen_out():
    # Its text changes every second (elapsed time, the PC's CPU); a layout of the whole
    # screen each time cost the app more than the line itself (benchmarks/outside.py).
    h = Harness(one_team())
    async with h.app.run_test(size=SIZE) as pilot:
        h.run(1.0)
        line = h.app.query_one("#status-line")
        asked = layouts_asked(line)
        await pilot.press("e", "e")
        h.run(3.0)
        assert "ENABLED" in text_of(h.app, "#status-line") and "elapsed 0:03" in text_of(h.app, "#status-line")
        assert asked and not any(asked)


async def test_a_narrow_status_line_drops_the_pc_first_and_never_the_robot_state():
    h = Harness(FieldConfig(team=254))
    async with h.app.run_test(size=(80, 24)) as pilot:
        h.run(1.0)
        line = text_of(h.app, "#status-line")
        assert "PC" not in line and "team 254 R1" in line and "disabled" in line and "comms" in line
        assert len(line) <= 78


def test_the_pc_status_reads_linux_cpu_time_and_the_battery(tmp_path):
    stat = tmp_path / "stat"
    supply = tmp_path / "power_supply"
    (supply / "AC").mkdir(parents=True)
    (supply / "AC" / "type").write_text("Mains\n")
    (supply / "BAT0").mkdir()
    (supply / "BAT0" / "type").write_text("Battery\n")
    (supply / "BAT0" / "capacity").write_text("57\n")
    (supply / "BAT0" / "status").write_text("Discharging\n")
    clock = [0.0]
    pc = PcStatus(str(stat), str(supply), clock=lambda: clock[0])
    stat.write_text("cpu  100 0 100 800 0 0 0 0 0 0\n")
    first = pc.read()
    assert first.cpu is None and first.battery == 57.0 and first.charging is False  # one reading: no rate yet
    stat.write_text("cpu  200 0 200 1400 0 0 0 0 0 0\n")  # 200 busy of 800 ticks since
    clock[0] = 1.0
    assert pc.read().cpu == pytest.approx(25.0)
    assert pc.read().text() == "PC cpu 25% battery 57%"
    gone = PcStatus(str(tmp_path / "none"), str(tmp_path / "none"))
    assert gone.read().text() == ""  # not Linux, no battery: nothing said
