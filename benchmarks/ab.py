"""One benchmark, run interleaved on several worktrees: A/B figures from one run of the machine.

    python benchmarks/ab.py [options] WORKTREE... -- SCRIPT [ARGS...]
    python benchmarks/ab.py --rounds 3 /work/wt/ab-base /work/wt/ab-timerfd -- outside.py --seconds 20
    python benchmarks/ab.py --dry-run /work/wt/ab-base /work/wt/ab-timerfd -- outside.py

This machine's speed moves by 1.4x with the hour, so a figure measured on one branch today
and on another tomorrow compares nothing. Here each round runs the benchmark once on every
worktree, the order reversed every other round (A B, B A, A B, ...: with three, A B C, C B A),
so each worktree has the same share of the machine's good and bad minutes. Each run is
``python benchmarks/SCRIPT ARGS --json`` with the worktree as its folder: the benchmark and
every process it starts (``python -m fieldbox``, the wire's process, the classroom's tabs)
import that worktree's code, not the editable install. ``--dry-run`` shows where each
worktree's runs import fieldbox, roles and protocol from, and runs no benchmark.

``--bench DIR`` runs one copy of the benchmarks (DIR, e.g. a newer benchmarks/ folder) on
every worktree: ``FIELDBOX_BENCH_ROOT`` names the worktree (benchmarks/_common.py and
codec.py read it; a worktree's own copy of them does not matter then).

Output: for each figure, each worktree's value in each round, their median, and the median
over the first worktree's (the baseline); the machine's own jitter probe (an idle process on
a 20 ms grid) the same way where the benchmark measures one. Every run's JSON is kept in
``--keep`` (a folder; a new one in /tmp by default), and ``--from FOLDER`` prints the tables
again from such a folder. Run it where the benchmarks can watch loopback (root: a packet
socket), e.g. in a network namespace of its own:

    unshare -n sh -c 'ip link set lo up && python benchmarks/ab.py ...'
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Any

PYTHON = "/work/main/.venv/bin/python"

#: The figures shown by default, per benchmark (dotted paths into its JSON, shell-style
#: patterns); ``--figure`` replaces them, ``--all`` shows every number.
FIGURES: dict[str, list[str]] = {
    "outside.py": ["app.beat_deviation_ms.median", "app.beat_deviation_ms.p99", "app.beat_deviation_ms.max",
                   "app.cpu_percent", "headless.beat_deviation_ms.p99", "headless.beat_deviation_ms.max",
                   "headless.cpu_percent", "first_frame.best_s", "first_frame.median_s"],
    "field.py": ["wire.interval_ms.median", "wire.interval_ms.p99", "wire.interval_ms.max", "wire.lost",
                 "trip_ms.median", "trip_ms.p99", "cpu.cpu_percent", "wire_process.cpu_percent",
                 "wire_process.app_cpu_percent"],
    "classroom.py": ["beat.p99", "beat.max", "field_cpu_pct", "tabs_cpu_pct", "tab_start_s.median",
                     "tab_start_s.last", "tabs_showing_their_seat", "observer_pss_mb.median",
                     "observer_pss_mb.max", "fork_server_pss_mb"],
    "codec.py": ["codecs.*.decode_us", "codecs.*.encode_us", "worst.*.flood_decode_us", "worst.*.worst_decode_us"],
    "startup.py": ["modes.bytecode cached.first_frame.best_s", "modes.bytecode cached.first_frame.median_s",
                   "modes.bytecode cached.help.*.best_s"],
}
#: Where each benchmark puts the machine's own jitter probe (ms late on a 20 ms grid).
JITTER = ["probe.median", "probe.p99", "machine_jitter.median", "machine_jitter.p99", "wake_probe_ms.median",
          "wake_probe_ms.p99"]
#: A list of objects is keyed by the first of these each object has (else by its index).
LIST_KEYS = ("packet", "kind", "command", "name")


# -- running ---------------------------------------------------------------------------------------
def label(worktree: str) -> str:
    return os.path.basename(os.path.normpath(worktree))


def order(worktrees: list[str], rounds: int) -> list[tuple[int, str]]:
    """(round, worktree) in the order they run: forwards, then backwards, and so on."""
    runs = []
    for r in range(rounds):
        runs += [(r, w) for w in (worktrees if r % 2 == 0 else worktrees[::-1])]
    return runs


def command(worktree: str, script: str, args: list[str], bench: str | None,
            python: str) -> tuple[list[str], dict[str, str]]:
    """The command line of one run (its folder is the worktree) and its environment."""
    env = dict(os.environ)
    if bench is not None:
        path = os.path.join(bench, script)
        env["FIELDBOX_BENCH_ROOT"] = os.path.abspath(worktree)
    else:
        path = os.path.join(os.path.abspath(worktree), "benchmarks", script)
        env.pop("FIELDBOX_BENCH_ROOT", None)
    env.pop("PYTHONPATH", None)  # nothing but the worktree decides what is imported
    return [python, path, *args, *([] if "--json" in args else ["--json"])], env


def last_json(stdout: str) -> dict[str, Any] | None:
    """The benchmark's JSON: the last JSON object of its output, on one line or printed over
    several (classroom.py indents its own), from a line that starts with ``{`` to the end."""
    lines = stdout.strip().splitlines()
    for i in range(len(lines) - 1, -1, -1):
        if lines[i].startswith("{"):  # an object's first line (an indented "{" is inside one)
            for text in (lines[i].strip(), "\n".join(lines[i:])):
                try:
                    value = json.loads(text)
                except ValueError:
                    continue
                if isinstance(value, dict):
                    return value
    return None


def run_all(worktrees: list[str], script: str, args: list[str], rounds: int, bench: str | None,
            python: str, keep: str, timeout: float) -> list[dict[str, Any]]:
    runs = []
    plan = order(worktrees, rounds)
    started = time.monotonic()
    for i, (r, worktree) in enumerate(plan, 1):
        cmd, env = command(worktree, script, args, bench, python)
        name = f"{label(worktree)}-round{r + 1}"
        print(f"[{i}/{len(plan)}] {time.strftime('%H:%M:%S')} {name}: {' '.join(cmd)}", file=sys.stderr, flush=True)
        t0 = time.monotonic()
        try:
            out = subprocess.run(cmd, cwd=worktree, env=env, capture_output=True, text=True, timeout=timeout)
            stdout, stderr, code = out.stdout, out.stderr, out.returncode
        except subprocess.TimeoutExpired as exc:
            stdout = exc.stdout.decode(errors="replace") if isinstance(exc.stdout, bytes) else (exc.stdout or "")
            stderr, code = f"timed out after {timeout:g} s", None
        took = time.monotonic() - t0
        result = last_json(stdout)
        with open(os.path.join(keep, f"{i:03d}-{name}.json"), "w") as f:  # in the order they ran
            json.dump({"worktree": os.path.abspath(worktree), "label": label(worktree), "round": r + 1,
                       "command": cmd, "exit_code": code, "seconds": round(took, 1), "result": result,
                       "stderr": stderr[-4000:]}, f)
        if result is None:
            print(f"    no JSON from {name} (exit code {code}): {stderr.strip()[-500:]}", file=sys.stderr)
        else:
            left = (time.monotonic() - started) / i * (len(plan) - i)
            print(f"    {took:.0f} s; about {left / 60:.1f} min left", file=sys.stderr, flush=True)
        runs.append({"label": label(worktree), "round": r + 1, "result": result})
    return runs


def load(folder: str) -> list[dict[str, Any]]:
    """The runs a ``--keep`` folder holds, in the order they ran (the baseline's first)."""
    runs = []
    for name in sorted(os.listdir(folder)):
        if name.endswith(".json"):
            with open(os.path.join(folder, name)) as f:
                saved = json.load(f)
            runs.append({"label": saved["label"], "round": saved["round"], "result": saved["result"]})
    return runs


# -- the dry run -------------------------------------------------------------------------------------
WHERE = ("import fieldbox, roles, protocol; "
         "print(fieldbox.__file__); print(roles.__file__); print(protocol.__file__)")


def where_imported(worktree: str, script: str, bench: str | None, python: str) -> list[tuple[str, list[str]]]:
    """Where a run's processes import the project from: the benchmark itself (its folder on
    sys.path, then benchmarks/_common.py), and a ``python -m fieldbox`` it starts (the
    worktree as its folder). Nothing is measured."""
    cmd, env = command(worktree, script, [], bench, python)
    bench_dir = os.path.dirname(cmd[1])
    # as a script: its own folder first on sys.path, not the current one
    as_benchmark = (f"import os, sys; sys.path[:] = [p for p in sys.path if p not in ('', os.getcwd())]; "
                    f"sys.path.insert(0, {bench_dir!r}); import _common; print(_common.ROOT); {WHERE}")
    found = []
    for what, code in (("the benchmark", as_benchmark), ("python -m fieldbox", WHERE)):
        out = subprocess.run([python, "-c", code], cwd=worktree, env=env, capture_output=True, text=True,
                             timeout=60)
        found.append((what, (out.stdout + out.stderr).strip().splitlines()))
    return found


def dry_run(worktrees: list[str], script: str, args: list[str], rounds: int, bench: str | None,
            python: str) -> int:
    wrong = 0
    for r, worktree in order(worktrees, rounds):
        cmd, _ = command(worktree, script, args, bench, python)
        print(f"round {r + 1}, {label(worktree)}: (cd {worktree} && {' '.join(cmd)})")
    for worktree in worktrees:
        root = os.path.abspath(worktree) + os.sep
        print(f"\n{label(worktree)}:")
        for what, lines in where_imported(worktree, script, bench, python):
            for line in lines:
                ok = line.startswith(root) or line == root.rstrip(os.sep)
                wrong += not ok
                print(f"  {what:20} {'ok   ' if ok else 'WRONG'} {line}")
    print(f"\n{'every import from its own worktree' if not wrong else f'{wrong} imports from elsewhere'}")
    return 1 if wrong else 0


# -- the tables -----------------------------------------------------------------------------------------
def flatten(value: Any, prefix: str = "") -> dict[str, float]:
    """Every number in a benchmark's JSON, by its dotted path (a list of objects keyed by
    their name: ``codecs.DS control, 6 joysticks.decode_us``)."""
    out: dict[str, float] = {}
    if isinstance(value, bool) or value is None:
        return out
    if isinstance(value, (int, float)):
        out[prefix] = float(value)
    elif isinstance(value, dict):
        for k, v in value.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(value, list) and all(isinstance(v, dict) for v in value):
        for i, v in enumerate(value):
            key = next((str(v[k]) for k in LIST_KEYS if k in v), str(i))
            out.update(flatten(v, f"{prefix}.{key}" if prefix else key))
    return out


def pick(keys: list[str], patterns: list[str]) -> list[str]:
    """The keys matching the patterns, in the patterns' order, then the keys' own."""
    chosen: list[str] = []
    for pattern in patterns:
        chosen += [k for k in keys if fnmatch.fnmatchcase(k, pattern) and k not in chosen]
    return chosen


def _number(x: float | None) -> str:
    if x is None or math.isnan(x):
        return "-"
    return f"{x:.4g}" if abs(x) < 1e5 else f"{x:.0f}"


def tables(runs: list[dict[str, Any]], patterns: list[str] | None, everything: bool) -> str:
    labels: list[str] = []
    for run in runs:
        if run["label"] not in labels:
            labels.append(run["label"])
    rounds = max((run["round"] for run in runs), default=0)
    values: dict[str, dict[str, dict[int, float]]] = {}  # figure -> label -> round -> value
    for run in runs:
        for key, v in flatten(run["result"] or {}).items():
            values.setdefault(key, {}).setdefault(run["label"], {})[run["round"]] = v
    keys = list(values)
    figures = keys if everything else pick(keys, patterns or [])
    jitter = [k for k in pick(keys, JITTER) if k not in figures]
    lines = []
    width = max([len(x) for x in labels] + [8])
    for title, group in (("", figures), ("the machine's own jitter probe (ms late on a 20 ms grid): ", jitter)):
        for key in group:
            lines.append(f"{title}{key}")
            head = f"  {'':{width}} " + " ".join(f"{'r' + str(r + 1):>9}" for r in range(rounds))
            lines.append(head + f" {'median':>9} {'/ base':>7}")
            base = None
            for name in labels:
                per_round = values[key].get(name, {})
                got = [per_round[r] for r in sorted(per_round) if not math.isnan(per_round[r])]
                median = statistics.median(got) if got else None
                if base is None:
                    base = median
                ratio = (f"{median / base:.2f}x" if median is not None and base not in (None, 0.0)
                         and name != labels[0] else "")
                cells = " ".join(f"{_number(per_round.get(r + 1)):>9}" for r in range(rounds))
                lines.append(f"  {name:{width}} {cells} {_number(median):>9} {ratio:>7}")
            lines.append("")
    missing = [run for run in runs if run["result"] is None]
    if missing:
        lines.append("runs that gave no figures: " + ", ".join(f"{r['label']} round {r['round']}" for r in missing))
    return "\n".join(lines)


# -- the command line -----------------------------------------------------------------------------------
def split_argv(argv: list[str]) -> tuple[list[str], list[str]]:
    """ab.py's own arguments, and the benchmark's (after the first ``--``)."""
    if "--" not in argv:
        return argv, []
    i = argv.index("--")
    return argv[:i], argv[i + 1:]


def main(argv: list[str] | None = None) -> int:
    ours, theirs = split_argv(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                                 usage="ab.py [options] WORKTREE... -- SCRIPT [ARGS...]")
    ap.add_argument("worktrees", nargs="*", help="worktree folders; the first is the baseline")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--bench", help="one benchmarks/ folder for every worktree (default: each its own)")
    ap.add_argument("--python", default=PYTHON)
    ap.add_argument("--figure", action="append", help="a figure to show (dotted path, * allowed); repeatable")
    ap.add_argument("--all", action="store_true", help="every number the benchmark gives")
    ap.add_argument("--keep", help="folder for each run's JSON (default: a new one in /tmp)")
    ap.add_argument("--from", dest="saved", help="print the tables from a --keep folder; run nothing")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds one run may take")
    ap.add_argument("--dry-run", action="store_true", help="show the runs and where they import from")
    args = ap.parse_args(ours)
    if not theirs and not args.saved:
        raise SystemExit("ab.py: which benchmark? (after --)")
    script, script_args = (theirs[0], theirs[1:]) if theirs else ("", [])
    script = os.path.basename(script)
    patterns = args.figure or FIGURES.get(script, ["*"])
    if args.saved:
        print(tables(load(args.saved), patterns, args.all))
        return 0
    if len(args.worktrees) < 1:
        raise SystemExit("ab.py: name the worktrees (the first is the baseline)")
    for w in args.worktrees:
        if not os.path.isdir(os.path.join(w, "fieldbox")):
            raise SystemExit(f"ab.py: {w} is not a fieldbox worktree")
    if args.dry_run:
        return dry_run(args.worktrees, script, script_args, args.rounds, args.bench, args.python)
    keep = args.keep or tempfile.mkdtemp(prefix=f"fieldbox-ab-{os.path.splitext(script)[0]}-")
    os.makedirs(keep, exist_ok=True)
    print(f"each run's JSON goes to {keep}", file=sys.stderr)
    runs = run_all(args.worktrees, script, script_args, args.rounds, args.bench, args.python, keep, args.timeout)
    print(f"{script} {' '.join(script_args)}: {args.rounds} rounds, interleaved "
          f"({' '.join(label(w) for _, w in order(args.worktrees, min(args.rounds, 2)))} ...); runs kept in {keep}\n")
    print(tables(runs, patterns, args.all))
    return 0


if __name__ == "__main__":
    sys.exit(main())
