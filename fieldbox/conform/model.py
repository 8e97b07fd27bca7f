"""What a conformance run produces: cases, verdicts and the packets behind them.

A :class:`Case` is one numbered rule with the documents that state it. A :class:`Result` is
its verdict on one peer: ``pass``, ``fail`` (with the packets that broke the rule, each
explained byte by byte as the packet inspector explains it) or ``n/a`` (the case could not
be judged here, and why). Figures are what was measured (a period, a jitter, a count), so a
reader can see how close a pass was.
"""

from __future__ import annotations

import enum
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Awaitable, Callable, TextIO

from protocol.kinds import get as kind_of
from protocol.wire import jsonable

#: Evidence packets kept per case: enough to show what broke, never a capture of the run.
MAX_EVIDENCE = 6
#: Characters kept of a text a peer wrote (a console line, a reason built from its bytes).
MAX_TEXT = 2000


class SetupError(Exception):
    """The run could not begin (a port taken, a launch that failed): said, exit code 2."""


class Verdict(str, enum.Enum):
    PASS = "pass"
    FAIL = "fail"
    NA = "n/a"


@dataclass(frozen=True)
class Case:
    """One rule a peer is checked against. ``sources`` name where the rule is written:
    a section of docs/protocol.md (with the seed table it restates), the real capture."""

    id: str
    title: str
    rule: str
    sources: tuple[str, ...]
    needs: str = ""  # what the case needs besides the peer (a robot program, a hook)


@dataclass(frozen=True)
class Evidence:
    """A packet (or a line a robot program printed) that a verdict rests on."""

    direction: str  # "sent" (by fieldbox) or "received" (from the peer)
    at: float  # seconds since the run began
    note: str
    kind: str | None = None  # the protocol kind (``ds-to-rio``), None for a text line
    data: bytes = b""
    text: str = ""

    def spans(self) -> tuple[list[Any], str | None]:
        """The packet's byte-by-byte explanation, and the decode error if any (the good
        part explained, the rest one span naming the error, every byte covered)."""
        if self.kind is None:
            return [], None
        spans, error = kind_of(self.kind).annotate_lenient(self.data)
        return spans, None if error is None else str(error)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"direction": self.direction, "at": round(self.at, 4), "note": self.note}
        if self.kind is None:
            out["text"] = self.text
            return out
        spans, error = self.spans()
        out.update(kind=self.kind, hex=self.data.hex(), spans=[s.to_json() for s in spans], error=error)
        return out


@dataclass
class Result:
    case: Case
    verdict: Verdict
    reason: str
    figures: dict[str, Any] = field(default_factory=dict)
    evidence: list[Evidence] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"id": self.case.id, "title": self.case.title, "rule": self.case.rule,
                "sources": list(self.case.sources), "verdict": self.verdict.value, "reason": self.reason,
                "figures": jsonable(self.figures), "evidence": [e.to_json() for e in self.evidence]}


@dataclass
class Run:
    """One run of one role's cases against one peer."""

    role: str  # "robot", "ds" or "fms": the role of the peer under test
    address: str
    cases: list[Case]
    results: dict[str, Result] = field(default_factory=dict)
    peer: dict[str, Any] = field(default_factory=dict)  # what the peer said about itself
    notes: list[str] = field(default_factory=list)  # how the run went (launch, binds, hooks)
    started: float = field(default_factory=time.time)
    duration: float = 0.0
    selected: frozenset[str] | None = None  # --cases: only these run

    def __post_init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Seconds since the run began (what evidence times count from)."""
        return time.monotonic() - self._t0

    def since(self, monotonic: float) -> float:
        return monotonic - self._t0

    def case(self, cid: str) -> Case:
        for c in self.cases:
            if c.id == cid:
                return c
        raise KeyError(cid)

    def wanted(self, cid: str) -> bool:
        return self.selected is None or cid in self.selected

    def record(self, cid: str, verdict: Verdict, reason: str, figures: dict[str, Any] | None = None,
               evidence: list[Evidence] | None = None) -> Result:
        """The verdict of ``cid``; the first one recorded stands."""
        if cid in self.results:
            return self.results[cid]
        result = Result(self.case(cid), verdict, clip(reason), dict(figures or {}),
                        list(evidence or [])[:MAX_EVIDENCE])
        self.results[cid] = result
        return result

    def passed(self, cid: str, reason: str, figures: dict[str, Any] | None = None,
               evidence: list[Evidence] | None = None) -> Result:
        return self.record(cid, Verdict.PASS, reason, figures, evidence)

    def failed(self, cid: str, reason: str, figures: dict[str, Any] | None = None,
               evidence: list[Evidence] | None = None) -> Result:
        return self.record(cid, Verdict.FAIL, reason, figures, evidence)

    def not_applicable(self, cid: str, reason: str, figures: dict[str, Any] | None = None) -> Result:
        return self.record(cid, Verdict.NA, reason, figures)

    def finish(self, reason: str = "not run") -> None:
        """Every selected case without a verdict gets one: n/a, saying why."""
        for c in self.cases:
            if self.wanted(c.id) and c.id not in self.results:
                self.not_applicable(c.id, reason)
        self.duration = self.now()

    def ordered(self) -> list[Result]:
        return [self.results[c.id] for c in self.cases if c.id in self.results]

    def counts(self) -> dict[str, int]:
        out = {v.value: 0 for v in Verdict}
        for r in self.results.values():
            out[r.verdict.value] += 1
        return out

    @property
    def any_failed(self) -> bool:
        return any(r.verdict is Verdict.FAIL for r in self.results.values())

    def to_json(self) -> dict[str, Any]:
        from fieldbox import __version__

        return {"tool": "fieldbox conform", "version": __version__, "role": self.role, "address": self.address,
                "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(self.started)),
                "duration": round(self.duration, 2), "peer": jsonable(self.peer), "notes": list(self.notes),
                "summary": self.counts(), "cases": [r.to_json() for r in self.ordered()]}


def clip(text: str, limit: int = MAX_TEXT) -> str:
    """A text a peer had a hand in, cut to a length a report can hold."""
    text = str(text)
    return text if len(text) <= limit else text[:limit] + f"... ({len(text) - limit} more characters)"


async def judge(run: Run, cid: str, step: Callable[[], Awaitable[Any]], err: TextIO, retries: int = 0) -> None:
    """Run one case's step, if it was selected. A bug of ours is said (a traceback on ``err``,
    the case n/a), never a traceback instead of a report. A case that measures time gets
    ``retries``: a busy host can stall the peer (or fieldbox) for a second or two, so a
    timing case that fails is run again, and the last verdict stands, with the first
    failure in its figures (a peer that is wrong fails every time). A retry that cannot judge
    (n/a: the state the first try left, say an enable that toggles, is not the one it needs)
    never undoes a finding: the first try's FAIL stands, the retry's reason in its figures."""
    if not run.wanted(cid):
        return
    first: Result | None = None
    for attempt in range(retries + 1):
        try:
            await step()
        except Exception as exc:
            traceback.print_exc(file=err)
            run.not_applicable(cid, f"fieldbox conform could not judge this case: {type(exc).__name__}: {exc}")
            return
        result = run.results.get(cid)
        if result is None or result.verdict is not Verdict.FAIL or attempt == retries:
            break
        first = run.results.pop(cid)
    result = run.results.get(cid)
    if first is not None and result is not None:
        if result.verdict is Verdict.NA:
            first.figures["retry"] = f"n/a: {result.reason}"
            run.results[cid] = first
        else:
            result.figures["first_try"] = f"fail: {first.reason}"
