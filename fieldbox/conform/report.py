"""A conformance run as text (the terminal), JSON (machines) and HTML (a page a person can
send to a project's maintainers: the cases, the verdicts, and each packet behind a verdict
explained byte by byte, as the packet inspector explains it).

Everything a peer wrote (names, console lines, bytes) is escaped: the report of a hostile
peer is still just a report.
"""

from __future__ import annotations

import html
import json
import time
from typing import Any

from fieldbox import __version__

from .model import Evidence, Result, Run, Verdict

ROLE_TITLES = {"robot": "a robot (fieldbox plays the Driver Station)",
               "ds": "a Driver Station (fieldbox plays the robot and the FMS)",
               "fms": "an FMS (fieldbox plays six Driver Stations)"}
MARK = {Verdict.PASS: "pass", Verdict.FAIL: "FAIL", Verdict.NA: "n/a "}
#: Fields of one packet, and characters of one line a robot printed, the text report shows.
TEXT_SPANS = 24
TEXT_LINE = 240
#: Bytes of one packet the text report shows in hex (a real one is shorter; a 64 KB one is not
#: printed whole on a terminal).
TEXT_BYTES = 256


def _figure(value: Any) -> str:
    if isinstance(value, bool):  # as a person reads it, not Python's True
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, dict):
        return ", ".join(f"{k} {_figure(v)}" for k, v in value.items()) or "none"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_figure(v) for v in value) + "]"
    return str(value)


def figures_text(figures: dict[str, Any]) -> str:
    return "; ".join(f"{k.replace('_', ' ')} {_figure(v)}" for k, v in figures.items())


def evidence_lines(e: Evidence, indent: str = "      ") -> list[str]:
    """A packet as the decode command shows it: its hex, then a line per field."""
    who = "fieldbox sent" if e.direction == "sent" else "the peer sent"
    if e.kind is None:
        text = e.text if len(e.text) <= TEXT_LINE else e.text[:TEXT_LINE] + " ..."
        return [f"{indent}{who} at {e.at:.3f} s ({e.note}):", f"{indent}  {text}"]
    shown = e.data.hex(" ") if len(e.data) <= TEXT_BYTES else \
        e.data[:TEXT_BYTES].hex(" ") + f" ... ({len(e.data)} bytes; every one in --html and --json)"
    out = [f"{indent}{who} at {e.at:.3f} s, {e.kind} ({e.note}): {shown}"]
    spans, error = e.spans()
    if len(spans) > TEXT_SPANS:  # the terminal gets the head; --html and --json have every field
        hidden = len(spans) - TEXT_SPANS
        spans = spans[:TEXT_SPANS]
    else:
        hidden = 0
    for s in spans:
        raw = e.data[s.offset:s.offset + s.length].hex(" ")
        if len(raw) > 35:
            raw = raw[:32] + "..."
        meaning = f"  {s.meaning}" if s.meaning else ""
        value = str(s.value)
        if len(value) > TEXT_LINE:  # the undecodable rest of a huge packet, say
            value = value[:TEXT_LINE] + " ..."
        out.append(f"{indent}  {s.offset:>4} {raw:<35} {s.field} = {value}{meaning}")
    if hidden:
        out.append(f"{indent}  ... {hidden} more fields (every one in --html and --json)")
    if error:
        out.append(f"{indent}  decode error: {error}")
    return out


def text_report(run: Run, verbose: bool = False) -> str:
    lines = [f"fieldbox conform {run.role} {run.address}: {ROLE_TITLES.get(run.role, run.role)}"]
    if run.peer:
        lines.append("peer: " + figures_text(run.peer))
    for note in run.notes:
        lines.append(f"note: {note}")
    lines.append("")
    for r in run.ordered():
        lines.append(f"{r.case.id} {MARK[r.verdict]}  {r.case.title}")
        detail = verbose or r.verdict is not Verdict.PASS
        lines.append(f"      {r.reason}")
        if detail:
            lines.append(f"      rule: {r.case.rule}")
            lines.append(f"      source: {'; '.join(r.case.sources)}")
        if r.figures:
            lines.append(f"      figures: {figures_text(r.figures)}")
        if r.verdict is Verdict.FAIL or verbose:
            for e in r.evidence:
                lines.extend(evidence_lines(e))
    c = run.counts()
    lines.append("")
    lines.append(f"{c['pass']} pass, {c['fail']} fail, {c['n/a']} not applicable ({run.duration:.1f} s)")
    return "\n".join(lines) + "\n"


def json_report(run: Run) -> str:
    return json.dumps(run.to_json(), indent=1)


# -- HTML -------------------------------------------------------------------------------------------
_CSS = """
body { font: 15px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 72em; color: #1d2430; padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: .2em; }
.meta { color: #555; margin: 0 0 1em; }
.summary span { display: inline-block; padding: .2em .7em; border-radius: 1em; margin-right: .4em; font-weight: 600; }
table.cases { border-collapse: collapse; width: 100%; margin: 1em 0 2em; }
table.cases th, table.cases td { text-align: left; padding: .35em .6em; border-bottom: 1px solid #dde; vertical-align: top; }
.v { font-weight: 700; text-transform: uppercase; font-size: .85em; padding: .15em .6em; border-radius: .3em; white-space: nowrap; }
.pass { background: #d9f2df; color: #155d27; } .fail { background: #fbd9d6; color: #8a1c12; } .na { background: #eceef3; color: #4a5160; }
section.case { border: 1px solid #dde; border-radius: .5em; padding: .8em 1.1em; margin: 1em 0; }
section.case.failed { border-color: #e7a39b; }
section.case h2 { font-size: 1.1em; margin: 0 0 .4em; }
.rule { margin: .3em 0; } .source { color: #555; font-size: .9em; margin: .3em 0; }
.reason { margin: .5em 0; font-weight: 500; }
.figures { font-size: .9em; color: #333; }
.packet { margin: .8em 0; } .packet .head { font-size: .9em; color: #333; }
.hex { font-family: ui-monospace, monospace; background: #f5f6f8; padding: .4em .6em; border-radius: .3em; overflow-wrap: anywhere; }
table.spans { border-collapse: collapse; font-size: .85em; margin-top: .3em; }
table.spans td { padding: .15em .6em; border-bottom: 1px solid #eee; vertical-align: top; }
table.spans td.b { font-family: ui-monospace, monospace; white-space: nowrap; }
tr.bad td { background: #fde8e6; }
.line { font-family: ui-monospace, monospace; background: #f5f6f8; padding: .4em .6em; border-radius: .3em; overflow-wrap: anywhere; }
footer { color: #666; font-size: .85em; margin-top: 2em; }
"""

_CLASS = {Verdict.PASS: "pass", Verdict.FAIL: "fail", Verdict.NA: "na"}


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _evidence_html(e: Evidence) -> str:
    who = "fieldbox sent" if e.direction == "sent" else "the peer sent"
    if e.kind is None:
        return (f'<div class="packet"><div class="head">{who} at {e.at:.3f} s &mdash; {_e(e.note)}</div>'
                f'<div class="line">{_e(e.text)}</div></div>')
    spans, error = e.spans()
    rows = []
    for s in spans:
        bad = ' class="bad"' if "malformed" in s.field or s.field == "(undecodable)" else ""
        raw = e.data[s.offset:s.offset + s.length].hex(" ")
        rows.append(f"<tr{bad}><td class=b>{s.offset}</td><td class=b>{_e(raw)}</td><td>{_e(s.field)}</td>"
                    f"<td>{_e(s.value)}</td><td>{_e(s.meaning)}</td></tr>")
    err = f'<div class="reason">decode error: {_e(error)}</div>' if error else ""
    return (f'<div class="packet"><div class="head">{who} at {e.at:.3f} s, <b>{_e(e.kind)}</b> &mdash; '
            f'{_e(e.note)} ({len(e.data)} bytes)</div><div class="hex">{_e(e.data.hex(" "))}</div>'
            f'<table class="spans"><tr><td>offset</td><td>bytes</td><td>field</td><td>value</td><td>meaning</td></tr>'
            f'{"".join(rows)}</table>{err}</div>')


def _case_html(r: Result) -> str:
    cls = _CLASS[r.verdict]
    figures = f'<div class="figures">figures: {_e(figures_text(r.figures))}</div>' if r.figures else ""
    sources = "".join(f"<li>{_e(s)}</li>" for s in r.case.sources)
    evidence = "".join(_evidence_html(e) for e in r.evidence)
    failed = " failed" if r.verdict is Verdict.FAIL else ""
    return (f'<section class="case{failed}" id="{_e(r.case.id)}"><h2><span class="v {cls}">{_e(r.verdict.value)}'
            f'</span> {_e(r.case.id)} {_e(r.case.title)}</h2><div class="reason">{_e(r.reason)}</div>'
            f'<div class="rule"><b>Rule:</b> {_e(r.case.rule)}</div><div class="source"><b>Source:</b>'
            f'<ul>{sources}</ul></div>{figures}{evidence}</section>')


def html_report(run: Run) -> str:
    c = run.counts()
    started = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(run.started))
    rows = "".join(
        f'<tr><td><a href="#{_e(r.case.id)}">{_e(r.case.id)}</a></td><td><span class="v {_CLASS[r.verdict]}">'
        f'{_e(r.verdict.value)}</span></td><td>{_e(r.case.title)}</td><td>{_e(r.reason)}</td></tr>'
        for r in run.ordered())
    peer = "".join(f"<li>{_e(k.replace('_', ' '))}: {_e(_figure(v))}</li>" for k, v in run.peer.items())
    notes = "".join(f"<li>{_e(n)}</li>" for n in run.notes)
    cases = "".join(_case_html(r) for r in run.ordered())
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>fieldbox conform {_e(run.role)} {_e(run.address)}</title><style>{_CSS}</style></head>
<body>
<h1>FRC conformance: {_e(ROLE_TITLES.get(run.role, run.role))}</h1>
<p class="meta">Peer at <b>{_e(run.address)}</b>, checked {started} in {run.duration:.1f} s by fieldbox
{_e(__version__)} (<code>fieldbox conform {_e(run.role)}</code>).</p>
<p class="summary"><span class="pass">{c['pass']} pass</span><span class="fail">{c['fail']} fail</span>
<span class="na">{c['n/a']} not applicable</span></p>
{f'<h3>The peer</h3><ul>{peer}</ul>' if peer else ''}
{f'<h3>How the run went</h3><ul>{notes}</ul>' if notes else ''}
<table class="cases"><tr><th>case</th><th>verdict</th><th>rule</th><th>what happened</th></tr>{rows}</table>
{cases}
<footer>Each case names the rule it checks and where that rule is written: a section of fieldbox's
docs/protocol.md, which restates it with its origin (a table of the seed documents ds_to_rio.rst, rio_to_ds.rst
and fms_to_ds.rst; what real peers do where those are silent or wrong; a capture of a real NI Driver Station and
roboRIO, 2021). Quoted words are the origin's. Packets are explained field by field as
fieldbox's packet inspector and <code>fieldbox decode</code> explain them.</footer>
</body></html>
"""
