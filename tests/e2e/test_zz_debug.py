from e2e.test_viewer_controls import *  # noqa
from e2e.test_viewer_controls import _episode, _open, _viewer_frame, _now

def test_dbg(studio_url, browser, artifacts):
    page, errs = _open(browser, studio_url)
    batch_id = _episode(page, studio_url)
    page.reload()
    page.wait_for_selector(f"#batches button[data-batch='{batch_id}']")
    page.click(f"#batches button[data-batch='{batch_id}']")
    page.locator("#episodes a.playback").first.click()
    viewer = _viewer_frame(page, studio_url, "playback")
    viewer.wait_for_function(f"({CHARTS_JS})().length === 4", timeout=START_TIMEOUT_MS)
    page.hover("#viewer-title")
    print("active", page.evaluate("document.activeElement.tagName + ' ' + document.activeElement.name"))
    print("buttons", viewer.evaluate("[...document.querySelectorAll('button')].map(b => b.textContent.trim())"))
    page.keyboard.press("ArrowRight")
    time.sleep(1)
    print("lastkey", page.get_attribute("#viewer-frame", "data-last-key"), _now(viewer), errs)
