"""benchmarks/ab.py: the interleaved order of the runs, and the tables it prints from what the
benchmarks print (saved output of outside.py, codec.py and classroom.py, shaped as their
``--json`` is; no benchmark runs here)."""

from __future__ import annotations

import importlib.util
import json
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_spec = importlib.util.spec_from_file_location("fieldbox_ab", os.path.join(ROOT, "benchmarks", "ab.py"))
assert _spec is not None and _spec.loader is not None
ab = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ab)

MACHINE = {"python": "3.12.3", "implementation": "CPython", "cpu": "x", "cpus": 2, "memory_mb": 3900,
           "platform": "Linux"}


def beat(median: float, p99: float, biggest: float) -> dict:
    return {"n": 5994, "min": 0.0, "median": median, "p99": p99, "p999": biggest - 0.1, "max": biggest,
            "mean": median}


def outside(app_p99: float, app_cpu: float, headless_cpu: float, probe_p99: float) -> str:
    """What ``outside.py --json`` prints: the packet socket's warning, then one JSON line."""
    result = {"machine": MACHINE,
              "app": {"beat_deviation_ms": beat(0.08, app_p99, 3.2), "cpu_percent": app_cpu, "processes": 3,
                      "terminal_kb_per_s": 41.5, "tab_switches": 20, "seconds": 20.0},
              "headless": {"beat_deviation_ms": beat(0.05, 0.4, 1.1), "cpu_percent": headless_cpu, "seconds": 20.0},
              "first_frame": {"best_s": 0.94, "median_s": 1.02},
              "probe": {"n": 150, "min": 0.05, "median": 0.07, "p99": probe_p99, "p999": 0.5, "max": 0.5,
                        "mean": 0.08},
              "load": [0.5, 0.4, 0.3]}
    return "a line the benchmark printed before its figures\n" + json.dumps(result) + "\n"


def _runs(outputs: dict[tuple[str, int], str]) -> list[dict]:
    return [{"label": name, "round": r, "result": ab.last_json(text)} for (name, r), text in outputs.items()]


def _rows(table: str, figure: str) -> dict[str, list[str]]:
    """The rows of one figure's table: label -> its cells."""
    lines = table.splitlines()
    i = lines.index(figure)
    rows = {}
    for line in lines[i + 2:]:
        if not line.strip():
            break
        cells = line.split()
        rows[cells[0]] = cells[1:]
    return rows


def test_the_runs_alternate_so_each_worktree_has_the_same_share_of_the_hour():
    assert [w for _, w in ab.order(["a", "b"], 3)] == ["a", "b", "b", "a", "a", "b"]
    assert [w for _, w in ab.order(["a", "b", "c"], 2)] == ["a", "b", "c", "c", "b", "a"]
    assert [r for r, _ in ab.order(["a", "b"], 2)] == [0, 0, 1, 1]


def test_each_run_is_the_worktrees_own_benchmark_in_json_with_nothing_else_on_the_path(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    monkeypatch.setenv("FIELDBOX_BENCH_ROOT", "/elsewhere")
    cmd, env = ab.command("/w/ab-gc", "outside.py", ["--seconds", "20"], None, "/py")
    assert cmd == ["/py", "/w/ab-gc/benchmarks/outside.py", "--seconds", "20", "--json"]
    assert "PYTHONPATH" not in env and "FIELDBOX_BENCH_ROOT" not in env
    cmd, env = ab.command("/w/ab-gc", "classroom.py", ["--json"], "/w/ab-script/benchmarks", "/py")
    assert cmd == ["/py", "/w/ab-script/benchmarks/classroom.py", "--json"]  # --json once
    assert env["FIELDBOX_BENCH_ROOT"] == "/w/ab-gc"


def test_outside_figures_per_round_with_their_median_the_ratio_and_the_jitter_probe():
    runs = _runs({("base", 1): outside(0.61, 50.0, 15.0, 0.31), ("timerfd", 1): outside(1.40, 47.0, 14.0, 0.29),
                  ("timerfd", 2): outside(1.20, 45.0, 13.0, 0.33), ("base", 2): outside(0.59, 52.0, 16.0, 0.30),
                  ("base", 3): outside(0.70, 54.0, 17.0, 0.35), ("timerfd", 3): outside(1.10, 49.0, 15.0, 0.30)})
    table = ab.tables(runs, ab.FIGURES["outside.py"], False)
    p99 = _rows(table, "app.beat_deviation_ms.p99")
    assert p99["base"] == ["0.61", "0.59", "0.7", "0.61"]  # rounds 1-3, then the median; the baseline has no ratio
    assert p99["timerfd"] == ["1.4", "1.2", "1.1", "1.2", "1.97x"]
    cpu = _rows(table, "app.cpu_percent")
    assert cpu["timerfd"] == ["47", "45", "49", "47", "0.90x"]
    assert _rows(table, "headless.cpu_percent")["base"][-1] == "16"
    assert _rows(table, "first_frame.best_s")["timerfd"][-1] == "1.00x"
    jitter = "the machine's own jitter probe (ms late on a 20 ms grid): probe.p99"
    assert _rows(table, jitter)["base"] == ["0.31", "0.3", "0.35", "0.31"]
    # a figure the benchmark did not ask for is not shown
    assert "app.terminal_kb_per_s" not in table and "machine.cpus" not in table


def test_a_run_that_gave_no_figures_is_named_and_the_others_still_count():
    runs = _runs({("base", 1): outside(0.6, 50.0, 15.0, 0.3), ("gc", 1): "Traceback (most recent call last):\n",
                  ("gc", 2): outside(0.8, 40.0, 12.0, 0.3), ("base", 2): outside(0.6, 52.0, 15.0, 0.3)})
    table = ab.tables(runs, ["app.cpu_percent"], False)
    assert _rows(table, "app.cpu_percent")["gc"] == ["-", "40", "40", "0.78x"]
    assert table.splitlines()[-1] == "runs that gave no figures: gc round 1"


def test_codec_rows_are_named_by_their_packet_and_kind():
    codec = {"machine": MACHINE,
             "codecs": [{"packet": "DS control, 6 joysticks", "bytes": 62, "encode_us": 6.1, "decode_us": 4.2},
                        {"packet": "roboRIO status, every tag", "bytes": 120, "encode_us": 9.0, "decode_us": 7.5}],
             "worst": [{"kind": "ds-to-rio", "bound": 1500, "flood_decode_us": 1.2, "flood_annotate_us": 2.0,
                        "worst_unit": "01 0c", "worst_decode_us": 210.5, "worst_annotate_us": 900.1}]}
    slower = json.loads(json.dumps(codec))
    slower["codecs"][0]["decode_us"] = 12.6
    runs = _runs({("base", 1): json.dumps(codec), ("fastdec", 1): json.dumps(slower)})
    table = ab.tables(runs, ab.FIGURES["codec.py"], False)
    assert _rows(table, "codecs.DS control, 6 joysticks.decode_us")["fastdec"] == ["12.6", "12.6", "3.00x"]
    assert "worst.ds-to-rio.worst_decode_us" in table.splitlines()
    assert "worst_unit" not in table  # text, not a figure


def test_classroom_tab_start_and_its_jitter_probe():
    def classroom(last: float) -> str:
        return json.dumps({"tabs": 30, "tabs_showing_their_seat": 30, "tab_start_s": {"median": last / 2, "last": last},
                           "beat": beat(0.1, 0.7, 2.0), "observer_pss_mb": {"max": 58.0, "median": 55.0, "count": 24},
                           "observer_pss_each_mb": [55.0] * 24, "field_cpu_pct": 20.0, "tabs_cpu_pct": 90.0,
                           "machine_jitter": {"n": 3000, "median": 0.1, "p99": 0.4, "max": 1.0},
                           "checks": [{"name": "field beat p99 |dev| ms", "value": 0.7, "met": True}]})
    runs = _runs({("base", 1): classroom(6.0), ("fork", 1): classroom(18.0)})
    table = ab.tables(runs, ab.FIGURES["classroom.py"], False)
    assert _rows(table, "tab_start_s.last")["fork"] == ["18", "18", "3.00x"]
    assert "the machine's own jitter probe (ms late on a 20 ms grid): machine_jitter.p99" in table


def test_saved_runs_print_the_same_tables_again(tmp_path, capsys):
    # named as ab.py keeps them: in the order they ran, the baseline ("zz") first whatever its name
    for i, ((name, r), text) in enumerate({("zz", 1): outside(0.6, 50.0, 15.0, 0.3),
                                           ("rr", 1): outside(0.9, 50.0, 15.0, 0.3)}.items(), 1):
        (tmp_path / f"{i:03d}-{name}-round{r}.json").write_text(json.dumps(
            {"label": name, "round": r, "result": ab.last_json(text), "command": [], "exit_code": 0}))
    assert ab.main(["--from", str(tmp_path), "--", "outside.py"]) == 0
    out = capsys.readouterr().out
    assert _rows(out, "app.beat_deviation_ms.p99")["rr"] == ["0.9", "0.9", "1.50x"]  # against zz


def test_a_benchmark_that_prints_its_json_indented_is_read_whole():
    # classroom.py prints json.dumps(result, indent=2): its figures are a list of objects, each
    # opening with an indented "{" of its own; the result is the whole object, never one of them
    text = 'fieldbox serve started\n' + json.dumps({"figures": [{"name": "tabs", "value": 4}], "at": 1}, indent=2)
    assert ab.last_json(text) == {"figures": [{"name": "tabs", "value": 4}], "at": 1}
