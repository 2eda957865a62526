"""Stored batches as report rows: the warnings stored with a batch reach the HTML, Markdown and CSV
reports (on SQLite and PostgreSQL)."""

from __future__ import annotations

import pytest

from crossroads.evaluation.report import csv_rows, render_html
from crossroads.evaluation.report_markdown import render_markdown
from crossroads.store import Store, crud
from crossroads.evaluation.stored_batches import UnknownBatchError, report_rows

from store.test_store import make_batch, result

WARNING = "cross.net.xml (left from 1si): SUMO's internal lanes run up to <3.15 m> off the paths"


def test_report_rows_carry_the_warnings_stored_with_each_batch(store: Store) -> None:
    warned = make_batch(store, runs=2, seed=31, warnings=(WARNING,))
    quiet = make_batch(store, runs=2, seed=32)
    with store.session() as s:
        for batch_id in (warned, quiet):
            crud.record_episode(session=s, batch_id=batch_id, run_index=0, seed=1, result=result())
    rows = report_rows(store, [warned, quiet])
    assert [r.warnings for r in rows] == [[WARNING], []]

    page = render_html(rows)
    block = page[page.index("<h2>Warnings</h2>"):page.index("<h2>Results</h2>")]  # before the results
    assert f"<code>{warned}</code>" in block and "store-test" in block and "rule" in block
    assert "&lt;3.15 m&gt;" in block and "<3.15 m>" not in page  # the text, escaped
    assert f"<code>{quiet}</code>" not in block and block.count("<tr>") == 2  # head + one warning

    text = render_markdown(rows)
    assert text.index(f"- batch {warned} (store-test, rule): {WARNING}") < text.index("| case |")
    assert f"- batch {quiet} " not in text
    assert [line["warnings"] for line in csv_rows(rows)[1]] == [WARNING, ""]


def test_a_report_without_warnings_has_no_warnings_block(store: Store) -> None:
    rows = report_rows(store, [make_batch(store, runs=1, seed=33)])
    assert rows[0].warnings == []
    assert "Warnings" not in render_html(rows) and "Warnings" not in render_markdown(rows)
    with pytest.raises(UnknownBatchError):
        report_rows(store, [987654])
