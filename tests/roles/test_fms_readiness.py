"""What each station's row says (roles/cores/fms_station.py readiness), computed by the FMS
core on the fake clock and carried in its frozen view: one test per state, with the words the
FMS panel shows for it. The panel only gives each state a colour (fieldbox/panels/fms.py)."""

from __future__ import annotations

import ast
import dataclasses
import pathlib

import pytest

from protocol.ds_to_fms import ChallengeResponse
from roles.cores.fms_station import Readiness
from roles.cores.views import FmsView, StationView

from .test_fms import PING_1C, Field, ds_address


def row(f: Field, label: str = "R1") -> StationView:
    view = f.fms.view(f.now)
    return next(st for st in view.stations if st.label == label)


def logged_in(**status) -> Field:
    """254 at R1: logged in, challenge answered, its status arriving."""
    f = Field()
    f.login(254)
    f.status(254, **status)
    return f


def started() -> Field:
    """A full field, a match started a moment after the last status of every DS."""
    f = Field()
    f.connect_all()
    f.now += 0.01
    f.fms.start_match(f.now)
    f.poll()
    return f


def empty() -> Field:
    return Field(teams=[254])  # R2..B3 empty


def bypassed() -> Field:
    f = Field()
    f.fms.set_bypass("R1", True, f.now)
    return f


def wrong_station() -> Field:
    f = Field()
    f.login(254, peer=(ds_address(118), 50000))  # 118's address: B1's
    return f


def no_ds() -> Field:
    return Field()


def wrong_answer() -> Field:
    f = Field()
    f.login(254, answer=False)
    f.tcp(("fms-tcp", 254), ChallengeResponse("Not A Robot").encode())
    return f


def no_answer() -> Field:
    f = Field()
    f.login(254, answer=False)
    f.now += 4.0
    f.tcp(("fms-tcp", 254), PING_1C)  # its DS is there (TCP keep-alive), its answer is not
    f.poll(f.now + 1.1)  # past the challenge's 5 s
    return f


def asked() -> Field:
    f = Field()
    f.login(254, answer=False)  # asked the challenge a moment ago; no answer yet
    f.status(254)  # its status arrives: still not ready until it answers (the start box agrees)
    return f


def no_status() -> Field:
    f = Field()
    f.login(254)
    return f


def estopped() -> Field:
    f = logged_in()
    f.fms.estop("R1", f.now)
    return f


def no_robot() -> Field:
    return logged_in(robot_comms=False)


def ready() -> Field:
    f = Field()
    f.connect_all()
    return f


def held() -> Field:
    f = started()
    f.fms.astop("R1", f.now)  # disabled for the rest of auto
    return f


def running() -> Field:
    f = started()
    f.now += 0.1
    f.status(254, enabled=True)  # its DS's first report since the period began: enabled
    return f


def enabling() -> Field:
    return started()  # the field enables it; its DS has not reported since


def held_by_ds() -> Field:
    f = started()
    f.now += 0.1
    f.status(254, enabled=False)  # its DS reports since the period began, still disabled: Enter on it
    return f


CASES = {
    Readiness.EMPTY: (empty, "R2", "empty"),
    Readiness.BYPASSED: (bypassed, "R1", "bypassed"),
    Readiness.WRONG_STATION: (wrong_station, "R1", "WRONG STATION (B1)"),
    Readiness.NO_DS: (no_ds, "R1", "no DS"),
    Readiness.WRONG_ANSWER: (wrong_answer, "R1", "WRONG CHALLENGE ANSWER"),
    Readiness.NO_ANSWER: (no_answer, "R1", "NO CHALLENGE ANSWER"),
    Readiness.ASKED: (asked, "R1", "challenge asked"),
    Readiness.NO_STATUS: (no_status, "R1", "DS logged in, no status"),
    Readiness.ESTOPPED: (estopped, "R1", "FMS e-stop"),
    Readiness.NO_ROBOT: (no_robot, "R1", "no robot"),
    Readiness.READY: (ready, "R1", "ready"),
    Readiness.HELD: (held, "R1", "held"),
    Readiness.RUNNING: (running, "R1", "running"),
    Readiness.ENABLING: (enabling, "R1", "enabling"),
    Readiness.HELD_BY_DS: (held_by_ds, "R1", "held by its DS"),
}


@pytest.mark.parametrize("state", list(Readiness), ids=[s.value for s in Readiness])
def test_each_readiness_of_a_station_and_its_words(state):
    make, label, words = CASES[state]
    st = row(make(), label)
    assert (st.readiness, st.reason) == (state.value, words)


def test_a_station_estopped_by_its_ds_or_still_estopped_from_before_says_which():
    f = started()
    f.status(1114, estop=True)  # R2's operator e-stops mid-match: the field latches it
    assert (row(f, "R2").readiness, row(f, "R2").reason) == ("estopped", "DS e-stop")
    g = logged_in(estop=True)  # e-stopped before this match: its robot's own latch
    assert (row(g).readiness, row(g).reason) == ("estopped", "robot still e-stopped")


def test_the_rows_words_follow_the_match_and_the_ds_on_the_clock():
    """One station through a match: ready, enabling, running, then held by its DS."""
    f = Field()
    f.connect_all()
    assert row(f).reason == "ready"
    f.now += 0.01
    f.fms.start_match(f.now)
    assert row(f).reason == "enabling"
    f.run_until(f.now + 0.3)  # every DS reports every 250 ms, disabled (their operators hold them)
    assert row(f).reason == "held by its DS"
    f.now += 0.1
    f.status(254, enabled=True)
    assert row(f).reason == "running"


def test_a_view_once_its_wire_ended_says_no_ds_for_every_station_past_that_rung():
    f = running()
    view = f.fms.view(f.now)
    ended = view.wire_ended()
    r1 = ended.stations[0]
    assert (r1.readiness, r1.reason) == ("no-ds", "no DS")
    assert not (r1.enabled or r1.ds_link or r1.report.udp_link or r1.report.robot_link or r1.tcp_connected)
    assert view.stations[0].reason == "running" and view.stations[0].enabled  # the view itself is frozen
    g = wrong_station()
    assert g.fms.view(g.now).wire_ended().stations[0].reason == "WRONG STATION (B1)"


def test_the_fms_view_is_frozen_all_the_way_down():
    view = ready().fms.view(1000.0)

    def check(value, path):
        if dataclasses.is_dataclass(value):
            assert type(value).__dataclass_params__.frozen, f"{path} is not frozen"  # type: ignore[attr-defined]
            for fld in dataclasses.fields(value):
                check(getattr(value, fld.name), f"{path}.{fld.name}")
        elif isinstance(value, (list, dict, set, bytearray)):
            raise AssertionError(f"{path} is a mutable {type(value).__name__}")
        elif isinstance(value, tuple):
            for i, item in enumerate(value):
                check(item, f"{path}[{i}]")

    assert isinstance(view, FmsView)
    check(view, "view")
    with pytest.raises(dataclasses.FrozenInstanceError):
        view.stations[0].enabled = True  # type: ignore[misc]


def test_views_imports_nothing_from_the_cores_at_its_top():
    """views.py is what crosses to the app and a classroom seat: its types are its own or the
    protocol's, never a core's."""
    tree = ast.parse(pathlib.Path(__file__).parents[2].joinpath("roles/cores/views.py").read_text())
    imported = [node.module or "" for node in tree.body if isinstance(node, ast.ImportFrom)
                and (node.level > 0 or (node.module or "").startswith("roles"))]
    assert imported == []


@pytest.mark.parametrize("state", list(Readiness), ids=[s.value for s in Readiness])
def test_the_start_box_and_the_row_never_disagree(state):
    """The start box lists a station exactly when its row says something a person must fix
    before a start (or the field holds it e-stopped): one ladder, fms_station.readiness."""
    from roles.cores.fms_station import START_REFUSALS

    make, label, _ = CASES[state]
    f = make()
    named = [r for r in f.fms.start_refusals() if r.split(":")[0].split(" ")[0] == label]
    blocks = state in START_REFUSALS or row(f, label).estop
    assert bool(named) == blocks, (state, named)
