"""The studio in headless chromium: upload an ONNX policy with a name and a card, see it offered with
its hash beside the shipped policies, see a bad one refused at its field, delete it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from evaluation.test_onnx_policy import linear_policy

pytestmark = pytest.mark.slow


def test_upload_choose_and_delete_an_onnx_policy(studio_url: str, browser: Any, tmp_path: Path,
                                                artifacts: Path) -> None:
    good, bad = tmp_path / "mine.onnx", tmp_path / "wrong.onnx"
    good.write_bytes(linear_policy())
    bad.write_bytes(linear_policy(width=100))
    page = browser.new_page(viewport={"width": 1400, "height": 1100})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(studio_url + "/")
    page.wait_for_selector("#policy-upload")

    page.set_input_files("#policy-file", str(bad))
    page.fill("#policy-name", "wrong-width")
    page.fill("#policy-card", "a state of the wrong size")
    page.click("#policy-upload-button")
    page.wait_for_selector("#policy-upload .field-error")
    assert "108 or 120" in page.inner_text("#policy-upload .field-error")

    page.set_input_files("#policy-file", str(good))
    page.fill("#policy-name", "mine")
    page.fill("#policy-card", "steers on the tracking error, brakes on Δv")
    page.click("#policy-upload-button")
    page.wait_for_selector("#policy-upload-status:has-text('mine: stored')")
    assert page.input_value("#policy") == "mine"
    options = page.locator("#policy option").all_inner_texts()
    assert any(o.startswith("mine (uploaded ONNX, sha256 ") for o in options), options
    assert any(o.startswith("mine+shield (uploaded ONNX + safety shield") for o in options), options
    assert "rule" in options
    page.screenshot(path=str(artifacts / "policy-upload.png"))

    page.click("button[data-delete-policy=mine]")
    page.wait_for_selector("#policy-upload-status:has-text('mine: deleted')")
    assert not any(o.startswith("mine") for o in page.locator("#policy option").all_inner_texts())
    assert errors == []
