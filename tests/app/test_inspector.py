"""The packet inspector, driven with keys on a SimEngine field."""

from __future__ import annotations

import struct

import pytest

from fieldbox.packet_text import UNDECODABLE, summarize
from fieldbox.packetview import SUMMARIES, FieldList, HexView, PacketList
from fieldbox.panels.inspector import ANNOTATIONS_KEPT, InspectorPanel
from protocol import ds_to_rio
from protocol.kinds import coverage_gaps
from roles.runtime.field import FieldConfig
from roles.runtime.shell import TapRecord

from .helpers import layouts_asked, make_app, one_team, step, text_of, ui_modules_after

DS_CONTROL = ("ds 254", "robot", "out", "ds-to-rio")


def panel(app) -> InspectorPanel:
    return app.query_one(InspectorPanel)


async def test_links_from_the_taps_and_the_newest_control_packet_explained():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 1.0)
        p = panel(app)
        keys = p.links.keys
        assert DS_CONTROL in keys
        assert ("rio 254", "ds", "out", "rio-to-ds") in keys
        assert any(k[0] == "ds 254" and k[1] == "robot-tcp" for k in keys)
        assert p.link == DS_CONTROL  # the packet everyone asks about first
        ring = p.ring.links[DS_CONTROL]
        packets = p.query_one(PacketList)
        assert packets.row_count == len(ring) >= 45
        assert packets.follow and packets.selected() is ring[-1]
        hexview = p.query_one(HexView)
        assert hexview.data == ring[-1].data
        spans = p.query_one(FieldList).annotation.spans
        assert coverage_gaps(spans, len(hexview.data)) == []  # every byte explained
        assert app.focused is packets
        assert text_of(app, "#inspector-meaning").startswith("bytes 0-1  sequence")


async def test_moving_over_bytes_and_fields_keeps_them_in_step():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        p = panel(app)
        await pilot.press("tab", "right", "right", "right")  # to the hex view, onto byte 3
        hexview, fields = p.query_one(HexView), p.query_one(FieldList)
        assert app.focused is hexview and hexview.cursor == 3
        assert fields.annotation.spans[fields.cursor].field == "control"
        meaning = text_of(app, "#inspector-meaning")
        assert meaning.startswith("byte 3  control = 0x00") and "disabled" in meaning
        await pilot.press("tab", "down", "down")  # the field list: control -> request -> station
        assert app.focused is fields
        assert fields.annotation.spans[fields.cursor].field == "station"
        assert hexview.cursor == 5
        await pilot.press("right_square_bracket")  # next field: the first tag's size byte
        assert hexview.cursor == 6 and fields.annotation.spans[fields.cursor].field == "tags[0].size"


async def test_enable_shows_on_the_wire_in_the_inspector():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 1.0)
        await pilot.press("e", "e")
        await step(pilot, 0.1)
        p = panel(app)
        newest = p.query_one(PacketList).selected()
        assert ds_to_rio.decode_control(newest.data).enabled
        assert "enabled" in summarize(newest.kind, newest.data)
        await pilot.press("tab", "right", "right", "right")
        assert "enabled" in text_of(app, "#inspector-meaning")


async def test_pause_freezes_the_view_and_counts_what_arrives():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        p = panel(app)
        packets = p.query_one(PacketList)
        await pilot.press("p")
        rows, shown = packets.row_count, packets.selected()
        await step(pilot, 1.0)
        assert p.paused
        assert packets.row_count == rows and packets.selected() is shown  # frozen
        on_link, total = p.new_since_pause()
        assert 45 <= on_link <= 55 and total > on_link  # the capture kept recording
        assert len(p.ring.links[DS_CONTROL]) == rows + on_link
        state = text_of(app, "#inspector-state")
        assert "PAUSED" in state and f"{on_link} new on this link" in state
        await pilot.press("p")
        assert not p.paused and packets.row_count == rows + on_link
        assert packets.selected() is p.ring.links[DS_CONTROL][-1]


async def test_only_new_rows_are_drawn():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        packets = panel(app).query_one(PacketList)
        source = packets.source
        calls = []
        original = packets.render_row
        packets.render_row = lambda row, width, base: calls.append(row) or original(row, width, base)
        await step(pilot, 2.0)  # 100 more control packets
        assert packets.source is source  # the live ring itself, not a rebuilt copy
        assert packets.row_count == len(source) > 120
        height = packets.scrollable_content_region.height
        assert 0 < len(calls) <= 3 * height  # only visible rows were drawn
        assert min(calls) >= packets.row_count - height


async def test_a_growing_list_scrolls_without_laying_the_screen_out():
    # A list that grew by setting virtual_size laid the whole screen out ten times a second
    # (19 ms each under benchmarks/field.py --app). Only a scrollbar appearing needs it.
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.1)
        packets = panel(app).query_one(PacketList)
        height = packets.scrollable_content_region.height
        assert packets.row_count < height and not packets.show_vertical_scrollbar
        await step(pilot, 2.0)  # past the bottom: the scrollbar appears
        assert packets.row_count > height and packets.show_vertical_scrollbar
        asked = layouts_asked(packets)
        for _ in range(10):
            await step(pilot, 0.1)
        assert asked and not any(asked)  # refreshed every step, never laid out
        rows = packets.row_count
        assert rows == len(panel(app).ring.links[DS_CONTROL]) > 140
        assert packets.virtual_size.height == rows and packets.max_scroll_y == rows - height
        assert packets.scroll_offset.y == rows - height  # following: the newest row is on screen
        assert packets.vertical_scrollbar.window_virtual_size == rows
        assert packets.selected() is panel(app).ring.links[DS_CONTROL][-1]


async def test_the_followed_packet_reaches_every_pane_in_the_same_refresh():
    # The hex view and field list used to wait for the list's CursorMoved message: a second
    # frame every 100 ms. Now the refresh that moves the list shows the packet too.
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        p = panel(app)
        app.engine.advance(0.1)
        app.refresh_views()  # no await: no message has been handled yet
        newest = p.ring.links[DS_CONTROL][-1]
        assert p.query_one(PacketList).selected() is newest
        assert p.query_one(HexView).data == newest.data
        assert p.query_one(FieldList).annotation is p.annotation_for(newest)


async def test_the_summaries_kept_are_bounded():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 12.0)  # 600 control packets on the link shown
        packets = panel(app).query_one(PacketList)
        ring = list(panel(app).ring.links[DS_CONTROL])
        assert len(ring) > SUMMARIES
        for p in ring:  # as if every row had been drawn
            assert packets.summary(p)[0].startswith("ControlPacket")
        assert len(packets._summaries) == SUMMARIES
        assert packets.summary(ring[0]) == (summarize(ring[0].kind, ring[0].data), False)  # made again


async def test_the_decodes_kept_are_bounded():
    # Each decode is about 20 kB: following the live link for a minute must not keep them all.
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 12.0)
        p = panel(app)
        ring = list(p.ring.links[DS_CONTROL])
        assert len(ring) > 2 * ANNOTATIONS_KEPT
        oldest, newest = ring[0], ring[-1]
        first = p.annotation_for(oldest)
        for packet in ring:  # as if the cursor had passed over every row
            assert p.annotation_for(packet).spans
        assert len(p._annotations) == ANNOTATIONS_KEPT
        assert p.annotation_for(newest) is p.annotation_for(newest)  # kept: not made again
        again = p.annotation_for(oldest)  # dropped long ago: made again, the same
        assert again is not first and again.spans == first.spans


async def test_holding_a_packet_stops_following():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        packets = panel(app).query_one(PacketList)
        await pilot.press("up", "up")
        held = packets.selected()
        assert not packets.follow
        await step(pilot, 0.5)
        assert packets.selected() is held
        await pilot.press("end")
        assert packets.follow and packets.selected() is packets.source[-1]


async def test_switching_links_with_keys():
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        p = panel(app)
        await pilot.press("shift+tab")
        assert app.focused is p.links
        start = p.links.highlighted
        await pilot.press("down")
        assert p.link == p.links.keys[start + 1] != DS_CONTROL
        packets = p.query_one(PacketList)
        assert packets.selected().key == p.link
        assert p.link[3] in packets.border_title


async def test_a_bad_packet_shows_its_undecodable_bytes_in_the_error_colour():
    app, engines = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.2)
        p = panel(app)
        # a control packet whose station byte (7) names no station: the header is bad
        bad = bytes.fromhex("0001 01 04 00 07 0c")
        p.ring.tap(TapRecord(*DS_CONTROL, bad, ("127.0.0.1", 1110), ("127.0.0.1", 1150), engines[0].now()))
        app.refresh_views()
        await pilot.pause()
        packets = p.query_one(PacketList)
        assert packets.selected().data == bad
        hexview = p.query_one(HexView)
        a = hexview.annotation
        assert a.error is not None and a.spans[-1].field == UNDECODABLE
        assert coverage_gaps(a.spans, len(bad)) == []
        assert "BAD" in summarize("ds-to-rio", bad)
        error_style = hexview.get_component_rich_style("hex--error")
        undecodable = a.spans[-1]
        assert (undecodable.offset, undecodable.length) == (6, 1)  # after the bad station byte
        cells = [seg for seg in hexview.render_line(0) if len(seg.text) == 2 and seg.text.isalnum()]
        assert [seg.text for seg in cells] == [f"{b:02x}" for b in bad]
        assert cells[6].style.color == error_style.color and cells[6].style.reverse
        assert all(seg.style.color != error_style.color for seg in cells[:6])
        await pilot.press("tab", "end")
        meaning = p.query_one("#inspector-meaning")
        assert meaning.has_class("-bad") and "alliance station" in str(meaning.render())


async def test_a_malformed_tag_is_marked_while_the_header_is_explained():
    # Issue 18: a robot applies the header of a packet with a malformed tag and drops the tag;
    # the inspector explains the header and marks the tag in the error colour.
    app, engines = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.2)
        p = panel(app)
        # a control packet whose only tag says 255 bytes follow, with one there
        data = bytes.fromhex("0001 01 04 00 00 ff0c")
        p.ring.tap(TapRecord(*DS_CONTROL, data, ("127.0.0.1", 1110), ("127.0.0.1", 1150), engines[0].now()))
        app.refresh_views()
        await pilot.pause()
        hexview = p.query_one(HexView)
        a = hexview.annotation
        assert a.error is None and a.bad
        assert (a.spans[-1].field, a.spans[-1].offset, a.spans[-1].length) == ("tags[0].malformed", 6, 2)
        assert coverage_gaps(a.spans, len(data)) == []
        line = summarize("ds-to-rio", data)
        assert "MALFORMED" in line and "enabled" in line and not line.startswith("BAD")
        error_style = hexview.get_component_rich_style("hex--error")
        cells = [seg for seg in hexview.render_line(0) if len(seg.text) == 2 and seg.text.isalnum()]
        assert all(seg.style.color == error_style.color for seg in cells[6:8])
        assert all(seg.style.color != error_style.color for seg in cells[:6])
        # changed since the link's previous packet too: underlined, still in the error colour
        assert 6 in hexview.changed and cells[6].style.underline
        await pilot.press("tab", "end")
        meaning = p.query_one("#inspector-meaning")
        assert meaning.has_class("-bad") and "MALFORMED" in str(meaning.render())


async def test_export_and_record_keys_write_pcaps(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.5)
        p = panel(app)
        await pilot.press("r")
        assert p.recorder is not None
        recording = p.recorder.path
        assert recording.parent == tmp_path / "fieldbox" / "captures"
        await step(pilot, 0.5)
        size = recording.stat().st_size
        assert size > 1000  # written and flushed as packets arrive
        await step(pilot, 0.5)
        assert recording.stat().st_size > size
        await pilot.press("r")
        assert p.recorder is None
        await pilot.press("x")
        exports = [f for f in (tmp_path / "fieldbox" / "captures").glob("fieldbox-2*.pcap")]
        assert len(exports) == 1
        for path in (recording, exports[0]):
            raw = path.read_bytes()
            assert struct.unpack("<I", raw[:4])[0] == 0xA1B2C3D4
        messages = " ".join(n.message for n in app._notifications)
        assert "recording every packet" in messages and "recorded" in messages and "wrote" in messages


async def test_quitting_while_recording_closes_the_recording(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.3)
        await pilot.press("r")
        recording = panel(app).recorder.path
        await step(pilot, 0.3)
    assert app.return_code in (None, 0) and app._exception is None  # unmounting raised nothing
    assert struct.unpack("<I", recording.read_bytes()[:4])[0] == 0xA1B2C3D4 and recording.stat().st_size > 1000


async def test_record_to_a_chosen_path(tmp_path):
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.3)
        p = panel(app)
        await pilot.press("R")
        prompt = app.screen
        assert type(prompt).__name__ == "PathPrompt"
        target = tmp_path / "lesson" / "wire.pcap"
        prompt.query_one("Input").value = str(target)
        await pilot.press("ctrl+s")
        assert p.recorder is not None and p.recorder.path == target
        await step(pilot, 0.3)
        await pilot.press("R")  # stops
        assert p.recorder is None and target.stat().st_size > 24
        await pilot.press("X", "escape")  # a prompt, cancelled: nothing written
        assert sorted(f.name for f in target.parent.iterdir()) == ["wire.pcap"]


async def test_switching_engine_starts_a_fresh_capture():
    app, engines = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 0.3)
        p = panel(app)
        assert p.ring.seq > 0
        app.start_engine(FieldConfig(team=1114, roles=frozenset({"ds", "rio"})))
        assert p.attached is engines[1] and len(p.ring) == 0 and not p.links.keys
        assert p.ring.tap not in engines[0].net.taps and p.ring.tap in engines[1].net.taps
        await step(pilot, 0.3)
        assert p.link == ("ds 1114", "robot", "out", "ds-to-rio")


@pytest.mark.parametrize("kind, hex_data, expect", [
    ("ds-to-rio", "0001 01 04 10 00", "ControlPacket #1: no e-stop, no FMS, enabled, teleop"),
    ("ds-to-fms-tcp", "0001 1c", "ds_ping"),
])
def test_summary_leads_with_what_matters(kind, hex_data, expect):
    assert summarize(kind, bytes.fromhex(hex_data)).startswith(expect)


def test_packet_text_imports_without_textual():
    """What a packet says is plain Python over the protocol package: usable without the app."""
    assert ui_modules_after("import fieldbox.packet_text") == []


async def test_the_bytes_that_changed_since_the_links_previous_packet_are_underlined():
    # issue 20: a teacher's "watch this byte": the enable shows as the changed control byte
    app, _ = make_app(one_team(), "inspector")
    async with app.run_test(size=(120, 40)) as pilot:
        await step(pilot, 1.0)
        p = panel(app)
        hexview = p.query_one(HexView)
        before = hexview.changed
        assert before is not None and 3 not in before  # a disabled packet after a disabled one
        assert {1} <= before <= {0, 1}  # only the sequence moved
        app.run_command("enable")
        await step(pilot, 0.021)  # the very next control packet
        newest = p.query_one(PacketList).selected()
        previous = p.ring.previous(newest)
        assert previous is not None and previous.index == newest.index - 1
        assert ds_to_rio.decode_control(newest.data).enabled and not ds_to_rio.decode_control(previous.data).enabled
        assert 3 in hexview.changed  # the control byte
        assert "changed (underlined)" in str(hexview.border_title)
        underline = [seg for seg in hexview.render_line(0) if seg.style and seg.style.underline]
        assert any(seg.text == f"{newest.data[3]:02x}" for seg in underline)


async def test_a_classroom_observer_captures_only_while_its_inspector_is_shown():
    """Thirty tabs on one field: a driver's or an observer's app asks the field for its packets
    only while its Inspector is shown (roles/runtime/classroom.py), and shows them once it is."""
    import asyncio

    from fieldbox.app import FieldboxApp
    from roles.runtime.classroom import ClassroomProcess, JoinedEngine

    host = ClassroomProcess(FieldConfig(teams=[254, 1114, 2056, 118, 148, 1678], plan="ephemeral",
                                        log_files=False))
    host.start()
    try:
        def joined(cfg):
            engine = JoinedEngine(host.path, "observer", cfg)
            engine.start()
            return engine

        app = FieldboxApp(joined, FieldConfig(plan="ephemeral", log_files=False), animate=False)
        async with app.run_test(size=(160, 50)) as pilot:
            inspector = panel(app)

            async def until(check, timeout: float = 30.0) -> bool:
                deadline = asyncio.get_running_loop().time() + timeout
                while not check() and asyncio.get_running_loop().time() < deadline:
                    await pilot.pause(0.1)
                return bool(check())

            assert await until(lambda: inspector.attached is not None
                               and all(st.ds.link.robot_comms for st in inspector.attached.field.stations))
            await pilot.pause(1.0)  # the field's packets flow; this tab's DS page is shown
            assert not inspector.tapping and not inspector.ring.links
            await pilot.press("f6")
            assert await until(lambda: len(inspector.ring.links) >= 6), inspector.ring.links.keys()
            assert inspector.tapping
            assert await until(lambda: any(key[0] == "rio 254" for key in inspector.links.keys))
            await pilot.press("f6")  # F6 again: the timeline, which shows the same capture
            assert await until(lambda: app.query_one("TabbedContent").active == "timeline")
            await pilot.pause(1.0)
            assert inspector.tapping and any(inspector.ring.links.values())
            await pilot.press("f1")
            assert await until(lambda: not inspector.tapping)
            # what it showed is let go, and a batch already on its way too: thirty tabs' memory
            assert await until(lambda: not any(inspector.ring.links.values()))
    finally:
        host.stop()
