"""The roboRIO's view (roles/cores/views.py RioView): a frozen value, made of its parts."""

from __future__ import annotations

import ast
import json
from pathlib import Path

from protocol.ds_to_rio import Joystick

from roles.cores.views import StreamView

from .test_rio import Bench


def test_a_view_stays_as_it_was_while_the_robot_goes_on():
    """A panel may hold a view a while (the app shows the last one that came): what it shows
    is the robot at that moment, not the robot now."""
    b = Bench(program=_chatty)
    b.connect()
    b.drive(0.5, enabled=True, tags=[Joystick((10, -20), 0b101, 3, (90,))])
    view = b.rio.view(b.now)
    before = json.dumps(view.snapshot())
    b.rio.inject_rail_fault("5v", b.now)
    b.rio.set_battery(6.0, b.now)  # a brownout
    b.drive(0.5, enabled=False)  # more console lines, packets, a disable
    assert json.dumps(view.snapshot()) == before
    after = b.rio.view(b.now)
    assert after.faults.rail_5v == 1 and after.battery.brownout and not after.enabled
    assert view.console.end < after.console.end


def test_the_console_is_a_numbered_stream_a_reader_takes_the_new_lines_of():
    b = Bench(program=_chatty, console_size=5)
    b.drive(0.2, enabled=True)
    first = b.rio.view(b.now).console
    b.drive(0.2, enabled=True)
    second = b.rio.view(b.now).console
    assert isinstance(second, StreamView) and len(second) == 5 and second.first_seq > first.first_seq
    new = second.since(first.end)
    assert new and [line.text for line in new] == [line.text for line in second][-len(new):]
    assert [line.sequence for line in second] == list(range(second.first_seq, second.end))


def test_the_views_module_reaches_into_no_core():
    """A view is a value the app and a classroom seat read: views.py imports no core module
    (roles.cores), so nothing of a core's state can come with it."""
    source = Path(__file__).parents[2] / "roles" / "cores" / "views.py"
    imported = []
    for node in ast.walk(ast.parse(source.read_text())):
        if isinstance(node, ast.ImportFrom):
            imported.append("." * node.level + (node.module or ""))
        elif isinstance(node, ast.Import):
            imported += [alias.name for alias in node.names]
    FMS_STATION_INDEX = ".fms"  # FmsView.station (until the FMS's view is its own: issue 28)
    assert [m for m in imported if (m.startswith(".") or m.startswith("roles.cores")) and m != FMS_STATION_INDEX] == []


def _chatty(state, robot) -> None:
    """A robot program that writes a console line every beat."""
    robot.print(f"at {state.time:.2f} s")
