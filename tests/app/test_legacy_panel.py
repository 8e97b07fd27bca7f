"""The Legacy 2010 panel, by Pilot: its keys and clicks change what the DS sends (checked on
the wire, SimEngine), and it shows the robot's LCD, BCD battery, outputs and NetConsole."""

from __future__ import annotations

from roles.runtime.field import LEGACY_FMS_NOTE, FieldConfig

from fieldbox.panels.legacy import AnalogSlider, LegacyPanel, control_text, lcd_text

from .helpers import Wire, make_app, step, text_of

ROBOT_PROGRAM = """
def robot_periodic(state, robot):
    robot.set_lcd(1, "Hello from 2010")
    robot.set_lcd(2, "enabled" if state.enabled else "disabled")
    robot.set_lcd(6, "A3 = " + str(robot.analog_in(3)))
    robot.set_digital_outputs(0x81)
    if state.enabled:
        print("driving")
"""


def config(tmp_path, **kw) -> FieldConfig:
    path = tmp_path / "robot.py"
    path.write_text(ROBOT_PROGRAM)
    kw.setdefault("roles", frozenset({"ds", "rio"}))
    return FieldConfig(team=294, legacy=True, program=str(path), **kw)


async def test_toggle_a_digital_input_and_see_the_bit_in_the_next_packet(tmp_path):
    app, engines = make_app(config(tmp_path), "legacy")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 1.0)
        assert all(p.ds_digital_in == 0 for p in wire.legacy_control())
        mark = wire.mark()
        await pilot.press("1")
        await step(pilot, 0.03)
        sent = wire.legacy_control(mark)
        assert sent and sent[0].ds_digital_in == 0x01  # the very next 1024-byte packet
        mark = wire.mark()
        await pilot.press("8", "3")
        await step(pilot, 0.03)
        assert wire.legacy_control(mark)[0].ds_digital_in == 0x85
        lamps = [app.query_one(f"#legacy-din-{n}").state for n in range(1, 9)]
        assert lamps == ["on", "idle", "on", "idle", "idle", "idle", "idle", "on"]
        # a click toggles too
        mark = wire.mark()
        await pilot.click("#legacy-din-3")
        await step(pilot, 0.03)
        assert wire.legacy_control(mark)[0].ds_digital_in == 0x81
        assert engine.field.stations[0].ds.legacy.digital_in == 0x81


async def test_the_lcd_battery_outputs_and_netconsole_are_shown(tmp_path):
    app, engines = make_app(config(tmp_path), "legacy")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        await step(pilot, 1.0)
        lcd = text_of(app, "#legacy-lcd")
        assert "│Hello from 2010      │" in lcd and "│disabled             │" in lcd
        assert "│A3 = 0               │" in lcd
        ds = engine.field.stations[0].ds
        b1, b2 = ds.view().legacy.battery_bytes
        status = text_of(app, "#legacy-status")
        assert f"battery 0x{b1:02x} 0x{b2:02x} BCD → {ds.link.battery:.2f} V" in status
        assert "size 1152 (LCD)" in status and "00:80:2f:10:01:26" in status
        lamps = [app.query_one(f"#legacy-dout-{n}").state for n in range(1, 9)]
        assert lamps == ["on"] + ["idle"] * 6 + ["on"]
        assert "0x40" in text_of(app, "#legacy-control") and "team 294" in text_of(app, "#legacy-control")
        assert "packets sent 5" in text_of(app, "#legacy-dashboard")  # 50 Hz: ~50 in the second
        await pilot.press("e", "e")
        await step(pilot, 0.2)
        assert "│enabled              │" in text_of(app, "#legacy-lcd")
        log = app.query_one("#legacy-netconsole")
        assert any("driving" in line for line in log.lines)
        assert "0x60" in text_of(app, "#legacy-control")


async def test_analog_sliders_by_keyboard_reach_the_robot(tmp_path):
    app, engines = make_app(config(tmp_path), "legacy")
    async with app.run_test(size=(120, 40)) as pilot:
        engine = engines[0]
        wire = Wire(engine)
        await step(pilot, 0.5)
        slider = app.query_one("#legacy-analog-3", AnalogSlider)
        slider.focus()
        await pilot.press("end", "left", "shift+left")
        await step(pilot, 0.1)
        assert slider.value == 1023 - 8 - 128
        assert wire.legacy_control()[-1].analog == (0, 0, 887, 0)
        assert "│A3 = 887             │" in text_of(app, "#legacy-lcd")  # the robot read it
        await pilot.press("home", "pageup")
        await step(pilot, 0.1)
        assert wire.legacy_control()[-1].analog[2] == 128
        # keys 1-8 still work while a slider has focus
        await pilot.press("2")
        await step(pilot, 0.05)
        assert wire.legacy_control()[-1].ds_digital_in == 0x02


async def test_without_legacy_mode_the_panel_says_how_to_get_it():
    app, _ = make_app(FieldConfig(team=294, roles=frozenset({"ds", "rio"})), "legacy")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.2)
        assert "2010 (cRIO) mode is off" in text_of(app, "#legacy-none")
        assert not app.query_one("#legacy-columns").display
        # no key is offered that would be refused: neither in the footer nor in the key hints
        await pilot.pause()
        footer = "\n".join(s.text for s in app.screen._compositor.render_strips()).split("\n")[-1]
        assert "DIn" not in footer and "Quit" in footer, footer
        assert not app.query_one("#legacy-keys").display
        await pilot.press("1")  # refused with a notification, nothing sent, nothing raised
        await pilot.pause()
        assert [n.message for n in app._notifications] == [
            "no 2010 Driver Station runs here: press F8 and tick 2010 legacy"]


async def test_the_fms_in_legacy_mode_is_said_plainly(tmp_path):
    app, engines = make_app(config(tmp_path, roles=frozenset({"ds", "rio", "fms"})), "legacy")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.2)
        assert engines[0].field.fms is None
        assert any(LEGACY_FMS_NOTE in n.message for n in app._notifications)
        app.action_show_tab("fms")
        await step(pilot, 0.1)
        assert "not documented" in text_of(app, "#fms-none")


def test_control_text_and_lcd_text():
    assert str(control_text(0x40)).startswith("control 0x40 ")
    assert "●not-e-stop" in str(control_text(0x40)) and "○enabled" in str(control_text(0x40))
    assert "○not-e-stop" in str(control_text(0x00))
    box = str(lcd_text(("x" * 30,))).splitlines()
    assert len(box) == 8 and box[1] == "│" + "x" * 21 + "│" and LegacyPanel.ID == "legacy"


async def test_the_role_picker_switches_2010_mode_on_and_off():
    app, engines = make_app(FieldConfig(team=294, roles=frozenset({"ds", "rio"})), "legacy")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.2)
        await pilot.press("f8")
        await pilot.click("#legacy")
        await pilot.click("#apply")
        await pilot.pause()
        assert len(engines) == 2 and engines[1].field.config.legacy
        wire = Wire(engines[1])
        await step(pilot, 0.5)
        assert len(wire.legacy_control()) >= 20  # 1024-byte 2010 packets every 20 ms
        assert all(len(d) == 1024 for r, direction, kind, d, t in wire.packets if kind == "legacy-ds-to-robot")
        assert app.query_one("#legacy-columns").display
        assert "size 1152 (LCD)" in text_of(app, "#legacy-status")
        await pilot.press("f8")
        await pilot.click("#legacy")
        await pilot.click("#apply")
        await step(pilot, 0.2)
        assert len(engines) == 3 and not engines[2].field.config.legacy
        assert "2010 (cRIO) mode is off" in text_of(app, "#legacy-none")
