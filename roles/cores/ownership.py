"""Who an alliance station listens to, and whether it trusts it: two small tables of
``(state, input) -> (action, new state)``, the shape of :mod:`roles.cores.match` (docs/style.md).

**Ownership.** A station belongs to the DS whose TCP login holds it. Its UDP status is taken
only from that login's host, and its control packets go there (roles/cores/fms.py). The DS is
*live* while its status arrives (the FMS's 1 s rule; a fresh login gets a second to start),
and its TCP connection is up (the 5 s rule closes it). While the holder is live, a second
login for the team is refused, from another host and from the holder's own host alike (a
second program on the DS's machine, or a stranger behind the same address, must not take a
station whose DS is working: the real DS would be disabled mid-match until it took it
back). It takes the station only once the holder is lost (a DS whose machine hung or whose
cable was pulled: a second without its status) or gone (its connection closed: a DS that
crashed or restarted), or when it comes from the team's own address (10.TE.AM.x /
127.TE.AM.x) and the holder's address does not name the team (on a real field, the
station's network gives a DS that address; a program elsewhere cannot take it). A DS that
restarts gets straight back in: its old connection closed when its process ended, or, where
the old connection still looks open (a crashed machine), its status stopped a second ago.

**Challenge.** Each login is asked the challenge question; the station is trusted (may be
enabled) only after the right answer, and only the first answer counts (23 names cannot be
tried one by one). No answer within :data:`CHALLENGE_TIMEOUT` counts as wrong.

Nothing here knows about sockets, addresses or time: :mod:`roles.cores.fms` decides which input
a login, a status packet or a deadline is, and carries out the action.
"""

from __future__ import annotations

import enum

# Owner and Challenge are str enums: a station's snapshot and the panels show their values,
# and ``station.challenge == "right"`` reads as it always did.

#: Seconds a DS has to answer the challenge question.
CHALLENGE_TIMEOUT = 5.0


# -- ownership -------------------------------------------------------------------------------
class Owner(str, enum.Enum):
    EMPTY = "empty"  # no DS logged in for the station's team
    LIVE = "live"    # its DS is logged in and its status arrives (or it logged in < 1 s ago)
    LOST = "lost"    # its DS is logged in, but no status from it for a second


class OwnerInput(enum.Enum):
    LOGIN_SAME_HOST = "login-same-host"  # a login from the holder's host on another connection
    LOGIN_HOME = "login-home"            # from the team's own address; the holder's is not
    LOGIN_OTHER = "login-other"          # from any other host
    STATUS_OWN = "status-own"            # UDP status from the holder's address
    STATUS_OTHER = "status-other"        # UDP status from anywhere else
    SILENCE = "silence"                  # a second without status from the holder
    LOGOUT = "logout"                    # the holder's TCP connection closed


class OwnerAction(enum.Enum):
    TAKE = "take"                    # the login holds the station now; an earlier holder is closed
    REFUSE_LOGIN = "refuse-login"    # the login is closed, counted and logged
    ACCEPT_STATUS = "accept-status"  # the status is the station's
    REFUSE_STATUS = "refuse-status"  # counted and logged, never obeyed
    MARK_LOST = "mark-lost"          # the station's DS is lost
    RELEASE = "release"              # the station has no DS now
    IGNORE = "ignore"


O, OI, OA = Owner, OwnerInput, OwnerAction

#: The whole ownership machine. Every (state, input) pair is here.
OWNER_TABLE: dict[tuple[Owner, OwnerInput], tuple[OwnerAction, Owner]] = {
    # Nobody holds the station: the first login takes it; status is nobody's.
    (O.EMPTY, OI.LOGIN_SAME_HOST): (OA.TAKE, O.LIVE),
    (O.EMPTY, OI.LOGIN_HOME): (OA.TAKE, O.LIVE),
    (O.EMPTY, OI.LOGIN_OTHER): (OA.TAKE, O.LIVE),
    (O.EMPTY, OI.STATUS_OWN): (OA.REFUSE_STATUS, O.EMPTY),
    (O.EMPTY, OI.STATUS_OTHER): (OA.REFUSE_STATUS, O.EMPTY),
    (O.EMPTY, OI.SILENCE): (OA.IGNORE, O.EMPTY),
    (O.EMPTY, OI.LOGOUT): (OA.IGNORE, O.EMPTY),

    # A live DS keeps its station against anyone but the team's own address: a second
    # connection from its own host too (another program there; the DS itself, restarted, is
    # not live any more: its connection closed, or its status stopped).
    (O.LIVE, OI.LOGIN_SAME_HOST): (OA.REFUSE_LOGIN, O.LIVE),
    (O.LIVE, OI.LOGIN_HOME): (OA.TAKE, O.LIVE),
    (O.LIVE, OI.LOGIN_OTHER): (OA.REFUSE_LOGIN, O.LIVE),
    (O.LIVE, OI.STATUS_OWN): (OA.ACCEPT_STATUS, O.LIVE),
    (O.LIVE, OI.STATUS_OTHER): (OA.REFUSE_STATUS, O.LIVE),
    (O.LIVE, OI.SILENCE): (OA.MARK_LOST, O.LOST),
    (O.LIVE, OI.LOGOUT): (OA.RELEASE, O.EMPTY),

    # A lost DS: the next login takes the station; its own status brings it back.
    (O.LOST, OI.LOGIN_SAME_HOST): (OA.TAKE, O.LIVE),
    (O.LOST, OI.LOGIN_HOME): (OA.TAKE, O.LIVE),
    (O.LOST, OI.LOGIN_OTHER): (OA.TAKE, O.LIVE),
    (O.LOST, OI.STATUS_OWN): (OA.ACCEPT_STATUS, O.LIVE),
    (O.LOST, OI.STATUS_OTHER): (OA.REFUSE_STATUS, O.LOST),
    (O.LOST, OI.SILENCE): (OA.IGNORE, O.LOST),
    (O.LOST, OI.LOGOUT): (OA.RELEASE, O.EMPTY),
}


def owner_transition(state: Owner, event: OwnerInput) -> tuple[OwnerAction, Owner]:
    """The ownership table's entry for ``(state, event)``."""
    return OWNER_TABLE[(state, event)]


# -- the challenge ----------------------------------------------------------------------------
class Challenge(str, enum.Enum):
    NONE = "none"    # no login: nothing asked
    SENT = "sent"    # asked, not answered yet
    RIGHT = "right"  # answered right: the station may be enabled
    WRONG = "wrong"  # answered wrong: never enabled until the DS logs in again
    LATE = "late"    # no answer within CHALLENGE_TIMEOUT: as wrong

    @property
    def trusted(self) -> bool:
        return self is Challenge.RIGHT


class ChallengeInput(enum.Enum):
    ASK = "ask"                    # a login placed in the station: a fresh question
    ANSWER_RIGHT = "answer-right"
    ANSWER_WRONG = "answer-wrong"
    DEADLINE = "deadline"          # CHALLENGE_TIMEOUT since the question
    FORGET = "forget"              # the login left the station


class ChallengeAction(enum.Enum):
    SEND_QUESTION = "send-question"
    TRUST = "trust"                  # logged: challenge answered
    DISTRUST = "distrust"            # counted and logged: a wrong answer
    EXPIRE = "expire"                # counted and logged: no answer in time
    REFUSE_ANSWER = "refuse-answer"  # counted and logged: an answer after the first, or unasked
    IGNORE = "ignore"


C, CI, CA = Challenge, ChallengeInput, ChallengeAction

#: The whole challenge machine. Every (state, input) pair is here.
CHALLENGE_TABLE: dict[tuple[Challenge, ChallengeInput], tuple[ChallengeAction, Challenge]] = {
    (C.NONE, CI.ASK): (CA.SEND_QUESTION, C.SENT),
    (C.NONE, CI.ANSWER_RIGHT): (CA.REFUSE_ANSWER, C.NONE),
    (C.NONE, CI.ANSWER_WRONG): (CA.REFUSE_ANSWER, C.NONE),
    (C.NONE, CI.DEADLINE): (CA.IGNORE, C.NONE),
    (C.NONE, CI.FORGET): (CA.IGNORE, C.NONE),

    (C.SENT, CI.ASK): (CA.SEND_QUESTION, C.SENT),
    (C.SENT, CI.ANSWER_RIGHT): (CA.TRUST, C.RIGHT),
    (C.SENT, CI.ANSWER_WRONG): (CA.DISTRUST, C.WRONG),
    (C.SENT, CI.DEADLINE): (CA.EXPIRE, C.LATE),
    (C.SENT, CI.FORGET): (CA.IGNORE, C.NONE),

    # Once answered (or too late), nothing but a new login asks again.
    (C.RIGHT, CI.ASK): (CA.SEND_QUESTION, C.SENT),
    (C.RIGHT, CI.ANSWER_RIGHT): (CA.REFUSE_ANSWER, C.RIGHT),
    (C.RIGHT, CI.ANSWER_WRONG): (CA.REFUSE_ANSWER, C.RIGHT),
    (C.RIGHT, CI.DEADLINE): (CA.IGNORE, C.RIGHT),
    (C.RIGHT, CI.FORGET): (CA.IGNORE, C.NONE),

    (C.WRONG, CI.ASK): (CA.SEND_QUESTION, C.SENT),
    (C.WRONG, CI.ANSWER_RIGHT): (CA.REFUSE_ANSWER, C.WRONG),
    (C.WRONG, CI.ANSWER_WRONG): (CA.REFUSE_ANSWER, C.WRONG),
    (C.WRONG, CI.DEADLINE): (CA.IGNORE, C.WRONG),
    (C.WRONG, CI.FORGET): (CA.IGNORE, C.NONE),

    (C.LATE, CI.ASK): (CA.SEND_QUESTION, C.SENT),
    (C.LATE, CI.ANSWER_RIGHT): (CA.REFUSE_ANSWER, C.LATE),
    (C.LATE, CI.ANSWER_WRONG): (CA.REFUSE_ANSWER, C.LATE),
    (C.LATE, CI.DEADLINE): (CA.IGNORE, C.LATE),
    (C.LATE, CI.FORGET): (CA.IGNORE, C.NONE),
}


def challenge_transition(state: Challenge, event: ChallengeInput) -> tuple[ChallengeAction, Challenge]:
    """The challenge table's entry for ``(state, event)``."""
    return CHALLENGE_TABLE[(state, event)]


__all__ = ["CHALLENGE_TABLE", "CHALLENGE_TIMEOUT", "Challenge", "ChallengeAction", "ChallengeInput", "OWNER_TABLE",
           "Owner", "OwnerAction", "OwnerInput", "challenge_transition", "owner_transition"]
