"""Evaluation reports: the paper's numbers as data, the HTML report and the CSV."""

from __future__ import annotations

import base64
import csv
import random
import re
import sys
from pathlib import Path

import pytest

from crossroads.evaluation.metrics import summarize
from crossroads.evaluation.paper import PAPER_CASE_TITLES, PAPER_CASES, PAPER_TABLE
from crossroads.evaluation.report import (
    BatchRow,
    FailedEpisode,
    case_label,
    csv_rows,
    figure_png,
    paired_comparisons,
    pass_rate_figure,
    paper_policy,
    render_html,
    travel_time_figure,
    write_csv,
)
from support import REPO_ROOT

SPEC = REPO_ROOT.parent / "shared" / "SPEC.md"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def synthetic_suite(seed: int = 3, runs: int = 120) -> list[BatchRow]:
    """2 policies × the paper's 6 cases; outcomes drawn around the paper's rates, same seeds."""
    rng = random.Random(seed)
    rows = []
    for case in PAPER_CASES:
        for policy, col in (("models/apg.pt", "APG"), ("models/dpg.pt", "DPG")):
            cell = PAPER_TABLE[case][col]
            results = []
            for s in range(runs):
                u = rng.random()
                if u < 0.02:
                    results.append({"id": 1000 + s, "seed": s, "outcome": "timeout", "error": "SUMO closed"})
                elif u < cell.pass_rate:
                    results.append({"id": 1000 + s, "seed": s, "outcome": "passed",
                                    "travel_time_s": max(2.0, rng.gauss(cell.travel_mean_s, cell.travel_std_s))})
                else:
                    results.append({"id": 1000 + s, "seed": s, "outcome": rng.choice(["collision", "off_road"]),
                                    "detail": "hit vehicle <v7>", "trace_path": f"traces/{case}/{s}.json"})
            rows.append(BatchRow.from_results(case, policy, f"{case}:{col}", results))
    return rows


def img_pngs(page: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'<img[^>]*src="data:image/png;base64,([^"]+)"', page)]


# --- the paper's numbers ----------------------------------------------------------------------------


def test_paper_table_cells() -> None:
    assert tuple(PAPER_TABLE) == PAPER_CASES
    assert PAPER_TABLE["overspeed-10"]["APG"].pass_rate == 1.0
    assert PAPER_TABLE["rounding-50"]["DPG"] == type(PAPER_TABLE["rounding-50"]["DPG"])(0.34, 10.50, 4.94)
    assert PAPER_TABLE["overspeed-50"]["APG"].travel_mean_s == 16.18
    assert PAPER_TABLE["rounding-20"]["DPG"].passes == 144


@pytest.mark.skipif(not SPEC.is_file(), reason="SPEC.md is not beside the checkout")
def test_paper_table_matches_spec() -> None:
    text = SPEC.read_text(encoding="utf-8")
    found = 0
    for case, title in PAPER_CASE_TITLES.items():
        m = re.search(rf"\| {re.escape(title)} \| (\d+) %, ([\d.]+)±([\d.]+) \| (\d+) %, ([\d.]+)±([\d.]+) \|", text)
        assert m, title
        apg, dpg = PAPER_TABLE[case]["APG"], PAPER_TABLE[case]["DPG"]
        assert (round(apg.pass_rate * 100), apg.travel_mean_s, apg.travel_std_s) == \
            (int(m[1]), float(m[2]), float(m[3]))
        assert (round(dpg.pass_rate * 100), dpg.travel_mean_s, dpg.travel_std_s) == \
            (int(m[4]), float(m[5]), float(m[6]))
        found += 1
    assert found == 6


def test_case_and_policy_names() -> None:
    assert case_label("overspeed-10") == "overspeed-10"
    assert case_label("paper_Rounding_+50") == "rounding-50"
    assert case_label("left-turn-busy") is None
    assert paper_policy("models/apg.pt") == "APG"
    assert paper_policy("DPG_seed3") == "DPG"
    assert paper_policy("rule") is None and paper_policy("dapg.pt") is None


# --- HTML -------------------------------------------------------------------------------------------


def test_paper_suite_report() -> None:
    rows = synthetic_suite()
    pyplot = sys.modules.get("matplotlib.pyplot")
    figs_before = pyplot.get_fignums() if pyplot else None
    page = render_html(rows, title="Paper suite", trace_link=lambda b, e: f"/batches/{b}/episodes/{e}/trace")
    if pyplot is not None:
        assert pyplot.get_fignums() == figs_before  # no pyplot figures left behind

    # the paper's numbers, beside ours
    for case in PAPER_CASES:
        for col in ("APG", "DPG"):
            cell = PAPER_TABLE[case][col]
            assert f"{cell.travel_mean_s:.2f} ± {cell.travel_std_s:.2f}" in page
            assert f">{round(cell.pass_rate * 100)} %<" in page
        assert PAPER_CASE_TITLES[case] in page
    assert "(paper: APG)" in page and "(paper: DPG)" in page
    # the measured ones
    for row in rows:
        s = row.summary
        assert f"{100 * s.pass_rate:.1f} %" in page
        assert f"[{100 * s.wilson_low:.1f} %, {100 * s.wilson_high:.1f} %]" in page
        assert f"{s.travel_mean_s:.2f} ± {s.travel_std_s:.2f}" in page
    # two plots, real PNGs
    pngs = img_pngs(page)
    assert len(pngs) == 2 and all(p.startswith(PNG_MAGIC) for p in pngs)
    # paired comparisons: one per case
    assert "McNemar" in page and len(paired_comparisons(rows)) == 6
    # failed episodes link to their traces; their detail is escaped
    traced = [(r.batch_id, f.episode_id) for r in rows for f in r.failed if f.trace is not None]
    assert len(traced) > 20
    for batch_id, episode_id in traced:
        assert f'href="/batches/{batch_id}/episodes/{episode_id}/trace"' in page
    assert "hit vehicle &lt;v7&gt;" in page and "<v7>" not in page
    assert "SUMO closed" in page  # errored episodes are listed with their message
    assert "<script" not in page.lower()


def test_generic_single_batch() -> None:
    results = [{"seed": i, "outcome": "passed" if i % 3 else "red_light", "travel_time_s": 8.0 + i % 5,
                "detail": "" if i % 3 else "ran the red", "trace_path": None if i % 3 else f"t/{i}.json"}
               for i in range(30)]
    row = BatchRow.from_results("my-junction", "rule", "42", results)
    assert row.case is None and row.summary.passed == 20 and len(row.failed) == 10
    page = render_html([row], title="One batch")
    assert "my-junction" in page and "66.7 %" in page
    assert 'class="paper"' not in page and "The paper's numbers" not in page
    assert "Paired comparisons" not in page
    assert pass_rate_figure([row]) is None  # no injection level to plot against
    assert len(img_pngs(page)) == 1  # the travel-time plot
    assert 'href="t/0.json"' in page  # without trace_link, the path is the link


def test_escapes_user_text_and_unsafe_links() -> None:
    evil = '<script>alert("x")</script>'
    results = [{"seed": 0, "outcome": "collision", "detail": evil, "trace_path": "javascript:alert(1)"},
               {"seed": 1, "outcome": "passed", "travel_time_s": 9.0}]
    row = BatchRow.from_results(f"overspeed-10{evil}", f"apg & {evil}", f'b"{evil}', results)
    page = render_html([row], title=evil)
    assert "<script>" not in page
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in page
    assert "javascript:" not in page
    assert row.case == "overspeed-10"  # still matched to the paper's row
    csv_text = csv_rows([row])[1][0]
    assert csv_text["scenario"] == f"overspeed-10{evil}"


def test_warnings_come_first_with_their_batch_escaped_and_only_when_there_are_some() -> None:
    results = [{"seed": i, "outcome": "passed", "travel_time_s": 9.0} for i in range(4)]
    evil = '<script>alert("lanes")</script>'
    warned = BatchRow.from_results("cross-left", "rule", "7", results,
                                   warnings=[f"internal lanes 3.15 m off {evil}", "second"])
    quiet = BatchRow.from_results("cross-left", "models/apg.pt", "8", results)
    assert quiet.warnings == []
    page = render_html([quiet, warned])
    start, end = page.index("<h2>Warnings</h2>"), page.index("<h2>Results</h2>")
    assert start < end  # near the top: read before the numbers
    block = page[start:end]
    assert block.count('<td class="l"><code>7</code></td><td class="l">cross-left</td><td class="l">rule</td>') == 2
    assert "internal lanes 3.15 m off &lt;script&gt;alert(&quot;lanes&quot;)&lt;/script&gt;" in block
    assert "second" in block and "<code>8</code>" not in block and "<script>" not in page
    assert "Warnings" not in render_html([quiet])
    # the CSV: one column, the batch's warnings joined
    assert [line["warnings"] for line in csv_rows([warned, quiet])[1]] == [
        f"internal lanes 3.15 m off {evil}; second", ""]
    # and through mappings (JSON): kept, or none when absent
    as_dict = {"scenario": "cross-left", "policy": "rule", "batch_id": 7, "summary": warned.summary.to_json(),
               "warnings": warned.warnings}
    assert BatchRow.coerce(as_dict).warnings == warned.warnings
    assert BatchRow.coerce({**as_dict, "warnings": None}).warnings == []


def test_rows_from_mappings_and_duplicate_batches() -> None:
    rows = synthetic_suite(runs=40)[:2]
    again = BatchRow.from_results("overspeed-10", "models/apg.pt", "rerun", [
        {"seed": i, "outcome": "passed", "travel_time_s": 12.0} for i in range(40)])
    as_dicts = [{"scenario": r.scenario, "policy": r.policy, "batch_id": r.batch_id,
                 "summary": r.summary.to_json(), "travel_times": r.travel_times,
                 "outcomes": {str(k): v for k, v in r.outcomes.items()},
                 "failed": [vars(f) for f in r.failed]} for r in [*rows, again]]
    page = render_html(as_dicts)
    assert "models/apg.pt [rerun]" in page  # a second batch of the same scenario and policy
    assert len(paired_comparisons(as_dicts)) == 2  # apg vs dpg, apg rerun vs dpg; not apg vs its rerun
    assert BatchRow.coerce(as_dicts[0]) == rows[0]
    assert "No batches." in render_html([])


def test_row_with_no_valid_runs() -> None:
    row = BatchRow.from_results("rounding-20", "models/dpg.pt", "x",
                                [{"seed": i, "outcome": "error", "error": "boom"} for i in range(3)])
    page = render_html([row])
    assert "no valid runs" in page and "3 errored" in page
    assert row.failed == [FailedEpisode(i, i, "error", "boom") for i in range(3)]


def test_plots_render(tmp_path: Path) -> None:
    rows = synthetic_suite(runs=60)
    for fig in (pass_rate_figure(rows), travel_time_figure(rows)):
        assert fig is not None
        png = figure_png(fig)
        assert png.startswith(PNG_MAGIC) and len(png) > 10_000
    assert travel_time_figure([BatchRow("a", "p", "1", summarize([]))]) is None


# --- CSV --------------------------------------------------------------------------------------------


def test_csv_round_trip(tmp_path: Path) -> None:
    rows = synthetic_suite(runs=50)
    rows.append(BatchRow.from_results("my-junction", "rule", "g1", [{"seed": 0, "outcome": "passed",
                                                                      "travel_time_s": 7.5}]))
    path = write_csv(rows, tmp_path / "out.csv")
    with path.open(newline="", encoding="utf-8") as fh:
        lines = list(csv.DictReader(fh))
    assert len(lines) == len(rows)
    for row, line in zip(rows, lines):
        s = row.summary
        assert line["batch_id"] == row.batch_id and line["scenario"] == row.scenario
        assert line["policy"] == row.policy and line["case"] == (row.case or "")
        assert (int(line["runs"]), int(line["errors"]), int(line["valid"]), int(line["passed"])) == \
            (s.runs, s.errors, s.valid, s.passed)
        assert float(line["pass_rate"]) == s.pass_rate
        assert (float(line["wilson_low"]), float(line["wilson_high"])) == (s.wilson_low, s.wilson_high)
        assert float(line["travel_mean_s"]) == s.travel_mean_s
        assert int(line["travel_n"]) == s.travel_n
        assert line["travel_std_s"] == ("" if s.travel_std_s is None else repr(s.travel_std_s))
        for k, v in s.outcomes.items():
            assert int(line[f"outcome_{k}"]) == v
        cell = row.paper()
        if cell is None:
            assert line["paper_pass_rate"] == "" and line["paper_policy"] == ""
        else:
            assert float(line["paper_pass_rate"]) == cell.pass_rate
            assert float(line["paper_travel_mean_s"]) == cell.travel_mean_s
            assert line["paper_policy"] == row.paper_policy
