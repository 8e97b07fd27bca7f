"""A robot program for fieldbox's fake roboRIO that reports what its robot code sees, for
``fieldbox conform robot``: one line ``conform {json}`` when it changes, and once a second.

    fieldbox --roles rio --headless --robot-program fieldbox/conform/programs/fieldbox_robot.py

The fake roboRIO's program API has no joystick type or Xbox flag: those are reported as null.
"""

import json

SLOTS = 6
_last = None
_said_at = -1.0


def _stick(joy):
    return {"axes": [round(a, 4) for a in joy.axes], "buttons": list(joy.pressed),
            "button_count": joy.button_count, "povs": list(joy.povs), "name": joy.name,
            "type": None, "xbox": None}


def robot_periodic(state, robot):
    global _last, _said_at
    sticks = [_stick(state.joystick(slot)) for slot in range(SLOTS)]
    info = state.match_info
    match = None if info is None else {"event": info.competition, "type": int(info.match_type),
                                       "number": info.match_number, "replay": info.replay}
    seen = {"enabled": state.enabled, "mode": state.mode, "estop": state.estop, "ds": state.ds_attached,
            "fms": state.fms_attached, "sticks": sticks, "match": match, "game_data": state.game_data}
    if seen != _last or state.time - _said_at >= 1.0:
        _last, _said_at = seen, state.time
        print("conform " + json.dumps(seen, separators=(",", ":")))
